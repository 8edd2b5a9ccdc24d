"""core.identify.problem: the residuals of Martinez eq. (17), their Jacobian, the cost."""

import inspect
import math

from helpers.vehicle_sim import AURIGA, B
import numpy as np
import pytest
from scipy import optimize
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import IdentificationError, TrackedKinematicsError
from tracked_kinematics.core.identify.problem import _chord_coefficients
from tracked_kinematics.core.identify.procedure import IdentifyOptions
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.offline.cli import identify_icr

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)

SAMPLE_P = {
    'effective_wheel_base': [0.6], 'icr': [0.35, -0.42, 0.03], 'icr_scales': list(AURIGA),
    'general_slip': [-0.0022, 0.0355, -0.0386, 0.0409, -0.0173, -0.0602, -0.0549, -0.2785,
                     0.0605],
    'adaptive_icr': [0.05, 0.07, 0.09, 0.08, 0.02, 0.03], 'tuned_ddc': [1.6, 0.97, 1.02],
}


@pytest.mark.parametrize('name', ident.FIT_MODELS + ('tuned_ddc',))
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
    s, c, ds, dc = _chord_coefficients(t)
    s_p, c_p, _, _ = _chord_coefficients(t + h)
    s_m, c_m, _, _ = _chord_coefficients(t - h)
    np.testing.assert_allclose(ds, (s_p - s_m) / (2 * h), atol=1e-8)
    np.testing.assert_allclose(dc, (c_p - c_m) / (2 * h), atol=1e-8)
    assert _chord_coefficients(np.array([0.0]))[3][0] == 0.5


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


def test_robust_cost_is_scipys_cost():
    rng = np.random.default_rng(1)
    target = rng.normal(size=40)
    target[:3] += 10
    for loss in ident.LOSSES:
        res = optimize.least_squares(lambda p: target - p[0], [0.0], loss=loss, f_scale=0.7)
        assert ident.robust_cost(target - res.x[0], loss, 0.7) == pytest.approx(res.cost)


def test_heading_weight_has_one_default():
    # SegmentProblem, fit, identify's options, FitResult and identify_icr --heading-weight agree.
    default = ident.DEFAULT_HEADING_WEIGHT
    assert default == 1.0   # Martinez eq. (17) as written: metres and radians summed as they are
    for function in (ident.SegmentProblem, ident.fit):
        assert inspect.signature(function).parameters['heading_weight'].default == default
    assert IdentifyOptions().heading_weight == default
    assert ident.identify.__kwdefaults__['options'].heading_weight == default
    assert ident.FitResult(TRUTH, P_TRUE).heading_weight == default
    assert identify_icr.build_parser().get_default('heading_weight') == default


@pytest.mark.parametrize('weight', [0, 0.0, -1.0, math.nan, math.inf, 'auto', True])
def test_heading_weight_that_is_not_positive_is_refused(weight, clean_segments):
    # 0 used to mean "unset" (1 m/rad) in fit(); it is refused everywhere now, with one message.
    match = 'heading weight .* must be a finite number > 0 m/rad'
    with pytest.raises(TrackedKinematicsError, match=match) as refused:
        ident.SegmentProblem(TRUTH, clean_segments, weight)
    assert isinstance(refused.value, ValueError)
    assert not isinstance(refused.value, IdentificationError)   # the input, not the data
    with pytest.raises(TrackedKinematicsError, match=match):
        ident.fit(TRUTH, clean_segments, heading_weight=weight)
    assert ident.check_heading_weight(0.5) == 0.5


def test_heading_weight_refused_by_identify(clean):
    with pytest.raises(TrackedKinematicsError, match='heading weight'):
        ident.identify([clean], 'icr_scales', B, heading_weight=0.0, holdout=0.0)
    with pytest.raises(TrackedKinematicsError, match='heading weight'):
        ident.identify([clean], 'icr_scales', B, heading_weight=math.nan, holdout=0.0)


def test_heading_weight_none_is_the_auto_weight(clean_segments):
    # The explicit auto mode: the weight balances the residual noise, within its clip.
    result = ident.fit(TRUTH, clean_segments, heading_weight=None)
    assert 0.25 <= result.heading_weight <= 4.0
    np.testing.assert_allclose(result.p, P_TRUE, atol=1e-6)
