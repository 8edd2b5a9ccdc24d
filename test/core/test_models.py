"""Motion models: one interface, Jacobians, equivalences, the reconstructed EKF model."""

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from tracked_kinematics.core.kinematics import forward, IcrParams, true_speeds
from tracked_kinematics.core.models import (
    AdaptiveIcr, ConstantIcr, EffectiveWheelBase, GeneralKinematicSlip, IdealDiffDrive,
    make_model, MODEL_NAMES)

B = 0.42
RNG = np.random.default_rng(0)
V_L, V_R = RNG.uniform(-1.0, 1.0, size=(2, 200))

# A non-trivial parameter vector per model, for Jacobian checks.
SAMPLE_PARAMS = {
    'ideal': np.zeros(0),
    'effective_wheel_base': np.array([0.7]),
    'symmetric': np.array([0.55]),
    'icr': np.array([0.353, -0.425, 0.032]),
    'icr_scales': np.array([0.353, -0.425, 0.032, 1.0072, 1.0275]),
    # Fink & Stump Table IV, concrete, left column (row-major alpha_1..alpha_9).
    'general_slip': np.array([-0.0022, 0.0355, -0.0386, 0.0409, -0.0173, -0.0602,
                              -0.0549, -0.2785, 0.0605]),
    'adaptive_icr': np.array([0.05, 0.07, 0.09, 0.08, 0.02, 0.03]),
}


def test_registry_covers_every_model():
    assert set(MODEL_NAMES) == set(SAMPLE_PARAMS)
    with pytest.raises(ValueError, match='unknown motion model .*choose one of'):
        make_model('bicycle', B)


@pytest.mark.parametrize('name', MODEL_NAMES)
def test_initial_parameters_give_ideal_drive(name):
    model = make_model(name, B)
    assert model.initial().shape == (model.n_params,)
    twist = np.stack(model.twist(model.initial(), V_L, V_R), -1)
    ideal = np.stack(IdealDiffDrive(B).twist((), V_L, V_R), -1)
    np.testing.assert_allclose(twist, ideal, atol=1e-12)


@pytest.mark.parametrize('name', MODEL_NAMES)
def test_jacobian_matches_finite_differences(name):
    model = make_model(name, B)
    p = SAMPLE_PARAMS[name]
    twist, jac = model.twist_and_jacobian(p, V_L, V_R)
    assert twist.shape == (len(V_L), 3)
    assert jac.shape == (len(V_L), 3, model.n_params)
    np.testing.assert_allclose(twist, np.stack(model.twist(p, V_L, V_R), -1), atol=1e-12)
    h = 1e-6
    for j in range(model.n_params):
        dp = np.zeros_like(p)
        dp[j] = h
        plus, _ = model.twist_and_jacobian(p + dp, V_L, V_R)
        minus, _ = model.twist_and_jacobian(p - dp, V_L, V_R)
        np.testing.assert_allclose(jac[..., j], (plus - minus) / (2 * h), atol=1e-6,
                                   err_msg=f'{name}: d twist / d {model.param_names[j]}')


def test_constant_icr_equals_kinematics_forward():
    icr = IcrParams(B, 0.353, -0.425, 0.032, 1.0072, 1.0275)
    model = ConstantIcr(B, with_scales=True)
    p = model.from_icr(icr)
    expected = forward(*true_speeds(V_L, V_R, icr), icr)
    np.testing.assert_allclose(np.stack(model.twist(p, V_L, V_R)), np.stack(expected))
    assert model.as_icr(p) == icr


def test_effective_wheel_base_is_symmetric_icr():
    # Fink's alpha scales the turn rate; Martinez's symmetric model has chi = alpha.
    alpha = 0.6471  # Fink & Stump Table IV, concrete, right column
    ewb = EffectiveWheelBase(B)
    sym = ewb.as_icr([alpha])
    assert sym.chi == pytest.approx(alpha)
    np.testing.assert_allclose(np.stack(ewb.twist([alpha], V_L, V_R)),
                               np.stack(forward(V_L, V_R, sym)), atol=1e-12)


def test_general_slip_structure():
    # Pure spin: v_x = 0, so only the |v_theta| terms of c_x and v_theta terms act.
    model = GeneralKinematicSlip(B)
    p = SAMPLE_PARAMS['general_slip']
    v_x, v_y, w = model.twist(p, -0.21, 0.21)  # v_theta = 1 rad/s
    assert float(v_x) == pytest.approx(p[1])           # alpha2 |v_theta|
    assert float(v_y) == pytest.approx(p[4])           # alpha5 v_theta
    assert float(w) == pytest.approx(1.0 + p[7])       # v_theta + alpha8 v_theta
    assert not model.linear


def test_adaptive_icr_straight_line_is_ideal():
    # EKF paper sec. 5.2: on a straight line the ICRs converge to -B/2, B/2 and 0.
    model = AdaptiveIcr(B)
    y_l, y_r, x = model.icr(SAMPLE_PARAMS['adaptive_icr'], 0.8, 0.8)
    assert (float(y_l), float(y_r), float(x)) == pytest.approx((B / 2, -B / 2, 0.0))


def test_adaptive_icr_features():
    model = AdaptiveIcr(B)
    # v = 0.5, w = 0.5 / 0.42: a = v w, k = w / v.
    accel, curv = model.features(0.25, 0.75)
    w = 0.5 / B
    assert float(accel) == pytest.approx(0.5 * w)
    assert float(curv) == pytest.approx(w / 0.5)
    # Counter-rotating tracks: curvature saturates at 2 / B instead of diverging.
    _, curv_spin = model.features(-0.3, 0.3)
    assert float(curv_spin) == pytest.approx(2 / B)
    # Standing still: no NaN.
    accel0, curv0 = model.features(0.0, 0.0)
    assert (float(accel0), float(curv0)) == (0.0, 0.0)


def test_adaptive_icr_moves_outwards_with_turning():
    model = AdaptiveIcr(B)
    p = SAMPLE_PARAMS['adaptive_icr']
    gentle = model.icr(p, 0.45, 0.55)
    sharp = model.icr(p, 0.1, 0.9)
    assert sharp[0] > gentle[0] > B / 2
    assert sharp[1] < gentle[1] < -B / 2


def test_adaptive_icr_never_divides_by_zero():
    model = AdaptiveIcr(B)
    twist, jac = model.twist_and_jacobian(np.array([-10.0, -10.0, -10.0, -10.0, 0, 0]),
                                          V_L, V_R)
    assert np.all(np.isfinite(twist)) and np.all(np.isfinite(jac))


@pytest.mark.parametrize('name', MODEL_NAMES)
def test_increments_handle_zero_dt(name):
    model = make_model(name, B)
    dx, dy, dth = model.increments(SAMPLE_PARAMS[name], [0.01, 0.0], [0.02, 0.0], [0.0, 0.0])
    assert np.all(np.isfinite(dx)) and np.all(np.isfinite(dth))


@given(st.floats(0.01, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_linear_models_increment_is_rate_independent(dt, v_l, v_r):
    model = ConstantIcr(B)
    p = SAMPLE_PARAMS['icr_scales']
    inc = model.increments(p, v_l * dt, v_r * dt, dt)
    twist = model.twist(p, v_l, v_r)
    np.testing.assert_allclose(np.stack(inc), np.stack(twist) * dt, atol=1e-12)


def test_invalid_track_width():
    with pytest.raises(ValueError, match='track_width'):
        IdealDiffDrive(float('nan'))
