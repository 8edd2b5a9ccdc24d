"""core.identification: segments, sensitivities, recovery of known vehicles, checks."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from scipy import optimize
from tracked_kinematics.core.identify import _identification as ident
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import AdaptiveIcr, ConstantIcr, EffectiveWheelBase

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


@pytest.fixture(scope='module')
def clean():
    """Four minutes of the Auriga-alpha (Martinez sec. 5.3), ground truth off the encoder grid."""
    return simulate(TRUTH, P_TRUE, duration=240.0, seed=3, gt_phase=0.0137)


@pytest.fixture(scope='module')
def clean_segments(clean):
    segments = ident.build_segments([clean], 1.0)
    return segments.select(segments.travel >= 0.01)


def with_ground_truth(rec, x, y, yaw):
    return ident.Recording(rec.enc_t, rec.left, rec.right, rec.gt_t, x, y, yaw, rec.name)


SAMPLE_P = {
    'effective_wheel_base': [0.6], 'icr': [0.35, -0.42, 0.03], 'icr_scales': list(AURIGA),
    'general_slip': [-0.0022, 0.0355, -0.0386, 0.0409, -0.0173, -0.0602, -0.0549, -0.2785,
                     0.0605],
    'adaptive_icr': [0.05, 0.07, 0.09, 0.08, 0.02, 0.03],
}


@pytest.mark.parametrize('name', ident.FIT_MODELS)
def test_jacobian_matches_finite_differences(name, clean_segments):
    # Fink & Stump eq. (4) per segment, against central differences of the residuals.
    segments = clean_segments.select(np.arange(len(clean_segments)) < 60)
    problem = ident.SegmentProblem(ident.build_model(name, B), segments, heading_weight=0.7)
    p = np.array(SAMPLE_P[name], float)
    h = 1e-6
    numeric = np.stack([(problem.residuals(p + h * e) - problem.residuals(p - h * e)) / (2 * h)
                        for e in np.eye(len(p))], axis=1)
    np.testing.assert_allclose(problem.jacobian(p), numeric, atol=2e-7)


def test_chord_coefficients_and_their_series():
    # Derivatives of S = sin t / t and C = (1 - cos t) / t, series below 1e-3 and closed form
    # above, against central differences.
    t = np.array([-0.3, -2e-3, -0.9e-3, 1e-5, 0.5e-3, 0.999e-3, 1.001e-3, 0.02, 1.5])
    h = 1e-7
    s, c, ds, dc = ident._chord_coefficients(t)
    s_p, c_p, _, _ = ident._chord_coefficients(t + h)
    s_m, c_m, _, _ = ident._chord_coefficients(t - h)
    np.testing.assert_allclose(ds, (s_p - s_m) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(dc, (c_p - c_m) / (2 * h), atol=1e-8)
    assert ident._chord_coefficients(np.array([0.0]))[3][0] == 0.5


def test_prediction_equals_integrating_each_segment(clean_segments):
    # One integration of the whole log, relative poses between boundaries: exact.
    model = TRUTH
    problem = ident.SegmentProblem(model, clean_segments)
    predicted = problem.predict(P_TRUE)
    stop = clean_segments.stop
    for i in (0, 17, len(clean_segments) - 1):
        steps = slice(clean_segments.start[i], stop[i])
        x, y, th = model.integrate(P_TRUE, clean_segments.d_left[steps],
                                   clean_segments.d_right[steps], clean_segments.dt[steps])
        np.testing.assert_allclose(predicted[i], [x[-1], y[-1], th[-1]], atol=1e-12)
    # ... and it matches the measured increments of the true vehicle.
    np.testing.assert_allclose(predicted[:, :2], clean_segments.truth[:, :2], atol=1e-9)


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


def test_segment_length_zero_uses_every_ground_truth_sample(clean):
    every = ident.build_segments([clean], None)
    assert len(every) == len(clean.gt_t) - 1
    np.testing.assert_allclose(every.t1 - every.t0, 0.1, atol=1e-9)
    grouped = ident.build_segments([clean], 1.0)
    assert np.all(np.abs(grouped.t1 - grouped.t0 - 1.0) < 0.1 + 1e-9)
    # Segments tile time and their steps are positive.
    assert np.all(every.dt > 0) and np.all(np.diff(every.start) > 0)


def test_gaps_are_skipped(clean):
    # Drop 2 s of encoder samples and 2 s of ground truth elsewhere.
    enc_keep = (clean.enc_t < 50.0) | (clean.enc_t > 52.0)
    gt_keep = (clean.gt_t < 100.0) | (clean.gt_t > 102.0)
    rec = ident.Recording(clean.enc_t[enc_keep], clean.left[enc_keep], clean.right[enc_keep],
                          clean.gt_t[gt_keep], clean.gt_x[gt_keep], clean.gt_y[gt_keep],
                          clean.gt_yaw[gt_keep])
    segments = ident.build_segments([rec], 1.0)
    for lo, hi in ((50.0, 52.0), (100.0, 102.0)):
        assert not np.any((segments.t0 < hi) & (segments.t1 > lo))
    full = ident.build_segments([clean], 1.0)
    assert len(full) - len(segments) <= 7
    # Still exact: no segment straddles a hole.
    problem = ident.SegmentProblem(TRUTH, segments)
    np.testing.assert_allclose(problem.residuals(P_TRUE), 0.0, atol=1e-9)


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


def test_noise_and_quantisation_stated_tolerance():
    # Ground truth 3 mm / 0.2 deg noise, joint angles quantised to 4096 counts per turn,
    # ten minutes of driving: ICRs within 5 mm, scales within 0.3 %.
    rec = simulate(TRUTH, P_TRUE, duration=600.0, seed=8, gt_phase=0.004)
    rng = np.random.default_rng(2)
    quantum = 2 * np.pi / 4096 * 0.1
    noisy = ident.Recording(
        rec.enc_t, np.round(rec.left / quantum) * quantum,
        np.round(rec.right / quantum) * quantum, rec.gt_t,
        rec.gt_x + rng.normal(0, 0.003, len(rec.gt_t)),
        rec.gt_y + rng.normal(0, 0.003, len(rec.gt_t)),
        rec.gt_yaw + rng.normal(0, np.radians(0.2), len(rec.gt_t)))
    result = ident.identify([noisy], 'icr_scales', B, holdout=0.0)
    np.testing.assert_allclose(result.fit.p[:3], P_TRUE[:3], atol=5e-3)
    np.testing.assert_allclose(result.fit.p[3:], P_TRUE[3:], rtol=3e-3)
    assert np.all(result.fit.std[:3] < 5e-3)


def test_robust_cost_is_scipys_cost():
    rng = np.random.default_rng(1)
    target = rng.normal(size=40)
    target[:3] += 10
    for loss in ident.LOSSES:
        res = optimize.least_squares(lambda p: target - p[0], [0.0], loss=loss, f_scale=0.7)
        assert ident.robust_cost(target - res.x[0], loss, 0.7) == pytest.approx(res.cost)


def test_auto_heading_weight_balances_noise():
    rng = np.random.default_rng(5)
    r = np.column_stack([rng.normal(0, 0.004, (5000, 2)), rng.normal(0, 0.002, 5000)])
    assert ident.auto_heading_weight(r.ravel()) == pytest.approx(2.0, rel=0.1)
    assert ident.auto_heading_weight(np.zeros(30)) == 1.0


def test_bounds_keep_the_model_valid():
    model = ident.build_model('icr_scales', B)
    lo, hi = ident.bounds(model)
    for p in (lo, hi, np.clip([0.0, 0.0, 9.0, 0.0, 9.0], lo, hi)):
        icr = model.as_icr(p)
        assert 0 < icr.chi <= 1 and icr.scale_left > 0 and icr.scale_right > 0


def test_straight_driving_cannot_identify_the_icrs():
    rec = simulate(TRUTH, P_TRUE, duration=60.0, seed=1, legs=('straight',))
    segments = ident.build_segments([rec], 1.0)
    with pytest.raises(ident.ExcitationError,
                       match='too little turning to identify icr.y_left, icr.y_right, icr.x'):
        ident.check_excitation(TRUTH, ident.Excitation.of(segments, 0.01))
    with pytest.raises(ident.ExcitationError, match='too little turning'):
        ident.identify([rec], 'icr_scales', B)


def test_spinning_cannot_identify_the_scales():
    rec = simulate(TRUTH, P_TRUE, duration=60.0, seed=1, legs=('spin',))
    with pytest.raises(ident.ExcitationError,
                       match='too little straight driving to identify scale.left, scale.right'):
        ident.identify([rec], 'icr_scales', B)
    # The ICRs alone are identified by the same data.
    result = ident.identify([rec], 'icr', B, base=IcrParams(B, 0.3, -0.3, 0, *AURIGA[3:]),
                            holdout=0.0)
    np.testing.assert_allclose(result.fit.p, P_TRUE[:3], atol=1e-6)


def test_standing_still_is_too_little_motion():
    rec = simulate(TRUTH, P_TRUE, duration=30.0, seed=1)
    still = ident.Recording(rec.enc_t, np.zeros_like(rec.left), np.zeros_like(rec.right),
                            rec.gt_t, np.zeros_like(rec.gt_x), np.zeros_like(rec.gt_y),
                            np.zeros_like(rec.gt_yaw))
    with pytest.raises(ident.ExcitationError, match='too little motion: 0 of'):
        ident.identify([still], 'icr_scales', B)


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
    std = ident._standard_errors(jac, np.full(10, 0.01), np.ones(10, bool))
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


def test_spin_in_place_gives_martinez_eq16():
    # Symmetric vehicle of chi = 0.526 spinning both ways: eq. (16) gives it back.
    rec = simulate(EffectiveWheelBase(B), [0.526], duration=60.0, seed=2, legs=('spin',))
    spin = ident.spin_in_place([rec], B)
    assert spin.chi == pytest.approx(0.526, abs=1e-9)
    assert len(spin.runs) >= 5
    assert spin.icr(B).y_left == pytest.approx(0.399, abs=5e-4)
    straight = simulate(TRUTH, P_TRUE, duration=30.0, seed=1, legs=('straight',))
    with pytest.raises(ident.ExcitationError, match='no spin-in-place run'):
        ident.spin_in_place([straight], B)
    with pytest.raises(ident.IdentificationError, match='outside'):
        ident.spin_in_place([rec], B * 2.5)


def test_holdout_blocks_are_time_blocks(clean_segments):
    held = ident.HoldOut.choose(clean_segments, 0.25, 30.0)
    assert held.total_blocks == 8 and len(held.blocks) == 2
    inside, outside = held.inside(clean_segments), held.outside(clean_segments)
    assert not np.any(inside & outside)
    assert inside.sum() > 0.2 * len(clean_segments)
    assert ident.HoldOut.choose(clean_segments, 0.2, 100.0) is None


def test_identify_compares_models_on_held_out_blocks(clean):
    truth = AdaptiveIcr(B)
    rec = simulate(truth, SAMPLE_P['adaptive_icr'], duration=240.0, seed=6)
    result = ident.identify([rec], 'adaptive_icr', B, holdout_block=20.0)
    names = [e.name for e in result.evaluations]
    assert names == list(ident.COMPARE_MODELS)
    ideal, adaptive = result.evaluation('ideal'), result.evaluation('adaptive_icr')
    assert adaptive.segments.position_mean < 1e-6
    assert adaptive.windows.improvement_over(ideal.windows)['position'] > 99.0
    assert result.evaluation('icr_scales').windows.improvement_over(
        ideal.windows)['heading'] > 25.0
    # adaptive_icr has no constant ICRs: the ICR keys come from the icr_scales fit.
    assert result.icr_source == 'icr_scales'
    assert 0 < result.icr.chi < 1
