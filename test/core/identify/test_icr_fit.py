"""core.identify.fitting: recovery of known vehicles, robustness, standard errors, checks."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.identify.fitting import _standard_errors
from tracked_kinematics.core.models import ConstantIcr, EffectiveWheelBase

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


def with_ground_truth(rec, x, y, yaw):
    return ident.Recording(rec.enc_t, rec.left, rec.right, rec.gt_t, x, y, yaw, name=rec.name)


def test_clean_data_recovers_auriga_alpha(clean_segments):
    # Martinez sec. 5.3/6 values as the truth: recovered to far better than 2 mm / 0.2 %.
    result = ident.fit(TRUTH, clean_segments)
    np.testing.assert_allclose(result.p[:3], P_TRUE[:3], atol=2e-3)
    np.testing.assert_allclose(result.p[3:], P_TRUE[3:], rtol=2e-3)
    np.testing.assert_allclose(result.p, P_TRUE, atol=1e-7)
    assert result.icr.chi == pytest.approx(0.5398, abs=1e-4)
    assert result.icr.eccentricity == pytest.approx(0.0925, abs=1e-4)


def test_symmetric_model_recovers_spin_test_chi():
    # Martinez sec. 5.3: the spin experiments gave chi = 0.526, ICRs at +-0.399 m.
    truth = EffectiveWheelBase(B)
    rec = simulate(truth, [0.526], duration=120.0, seed=4)
    segments = ident.build_segments([rec], 1.0)
    result = ident.fit(truth, segments.select(segments.travel >= 0.01))
    assert result.p[0] == pytest.approx(0.526, abs=1e-8)
    assert result.icr.y_left == pytest.approx(0.399, abs=5e-4)


def test_ground_truth_outliers_do_not_pull_the_robust_fit(clean):
    rng = np.random.default_rng(0)
    x, y = clean.gt_x.copy(), clean.gt_y.copy()
    bad = rng.choice(len(x), size=len(x) // 50, replace=False)
    x[bad] += rng.choice([-0.5, 0.5], size=len(bad))
    y[bad] += rng.choice([-0.5, 0.5], size=len(bad))
    rec = with_ground_truth(clean, x, y, clean.gt_yaw)
    segments = ident.build_segments([rec], 1.0)
    segments = segments.select(segments.travel >= 0.01)
    robust = ident.fit(TRUTH, segments)
    np.testing.assert_allclose(robust.p[:3], P_TRUE[:3], atol=2e-3)
    np.testing.assert_allclose(robust.p[3:], P_TRUE[3:], rtol=2e-3)
    assert robust.inliers < robust.segments
    plain = ident.fit(TRUTH, segments, loss='linear', check=False)
    assert np.max(np.abs(plain.p[:3] - P_TRUE[:3])) > 5e-3   # what the robust loss avoids


def test_auto_heading_weight_balances_noise():
    rng = np.random.default_rng(5)
    r = np.column_stack([rng.normal(0, 0.004, (5000, 2)), rng.normal(0, 0.002, 5000)])
    assert ident.auto_heading_weight(r.ravel()) == pytest.approx(2.0, rel=0.1)
    assert ident.auto_heading_weight(np.zeros(30)) == 1.0


def test_unidentified_parameter_is_named():
    # Only gentle left arcs at one speed ratio: y_left and y_right cannot be told apart.
    result = ident.FitResult(TRUTH, P_TRUE, std=np.array([0.2, 0.001, 0.001, 0.001, 0.001]))
    with pytest.raises(ident.ExcitationError, match='too little turning to identify '
                       'icr.y_left: its standard error is 0.2'):
        ident.check_identified(result)
    result.std = np.array([0.001, 0.001, 0.001, np.inf, 0.001])
    with pytest.raises(ident.ExcitationError, match='straight driving to identify scale.left'):
        ident.check_identified(result)


def test_rank_deficient_jacobian_gives_infinite_standard_errors():
    jac = np.column_stack([np.ones(10), np.ones(10), np.arange(10.0)])
    std = _standard_errors(jac, np.full(10, 0.01), np.ones(10, bool))
    assert np.isinf(std[0]) and np.isinf(std[1]) and np.isfinite(std[2])


def test_fit_that_does_not_converge_raises(clean_segments):
    with pytest.raises(ident.FitError, match='the icr_scales fit did not converge'):
        ident.fit(TRUTH, clean_segments, max_nfev=1)


def test_differential_evolution_finds_the_same_minimum(clean_segments):
    segments = clean_segments.select(np.arange(len(clean_segments)) < 40)
    model = ident.build_model('icr', B, scales=AURIGA[3:])
    result = ident.fit(model, segments, method='de', heading_weight=1.0, f_scale=0.01,
                       rounds=1)
    np.testing.assert_allclose(result.p, P_TRUE[:3], atol=3e-3)


@pytest.mark.parametrize('sigma, cause, says, never', [
    (0.06, 'noise', 'because the ground truth is noisy', 'drive more'),
    (0.003, 'excitation', 'drive more, and more varied, straight lines', 'is noisy'),
])
def test_uncertain_parameters_name_their_cause(sigma, cause, says, never):
    # scale.left 0.03 against its 0.02 limit: with 60 mm residuals the same driving would
    # give 0.005 on 10 mm ground truth (noise); with 3 mm residuals it is the driving.
    result = ident.FitResult(TRUTH, P_TRUE, std=np.array([0.001, 0.001, 0.001, 0.03, 0.001]),
                             sigma=sigma, rms_position=sigma, rms_heading=sigma)
    with pytest.raises(ident.UncertainError) as refused:
        ident.check_identified(result)
    assert says in str(refused.value) and never not in str(refused.value)
    assert 'scale.left' in str(refused.value) and '--accept-uncertain' in str(refused.value)
    accepted = ident.check_identified(result, accept_uncertain=True)
    assert [(u.name, u.cause) for u in accepted] == [('scale.left', cause)]
    assert accepted[0].reference_std == pytest.approx(0.03 * min(1.0, 0.01 / sigma))
    # Not determined at all: refused even when uncertain fits are accepted.
    result.std = np.array([0.001, np.inf, 0.001, 0.001, 0.001])
    with pytest.raises(ident.ExcitationError, match='icr.y_right: the data do not determine'):
        ident.check_identified(result, accept_uncertain=True)
