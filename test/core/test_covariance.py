"""Linearised error propagation: Jacobians, closed forms, Monte Carlo, PSD."""

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from tracked_kinematics.core.covariance import (
    arc_step, body_jacobian, full_matrix, MAX_VARIANCE, propagate, ros_covariance, saturate,
    TrackNoise, twist_covariance, TWIST_TIME, twist_variances, UNOBSERVED_VARIANCE)
from tracked_kinematics.core.integration import arc_chord, compose
from tracked_kinematics.core.kinematics import forward, IcrParams, true_speeds
from tracked_kinematics.core.odometry import Odometry

AURIGA = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)
finite = st.floats(-2.0, 2.0, allow_nan=False)


def reference_step(theta0, dx, dy, dtheta):
    """World displacement of one arc step, through core.integration (independent code)."""
    cx, cy = arc_chord(dx, dy, dtheta)
    x, y, _ = compose(0.0, 0.0, theta0, cx, cy, dtheta)
    return np.array([float(x), float(y)])


@pytest.mark.parametrize('dtheta', [0.0, 1e-9, 3e-3, -9.9e-3, 1.01e-2, 0.3, -2.5])
@given(theta0=st.floats(-4.0, 4.0), dx=finite, dy=finite)
def test_arc_step_matches_integration_and_its_jacobian_finite_differences(
        dtheta, theta0, dx, dy):
    delta_x, delta_y, m = arc_step(theta0, dx, dy, dtheta)
    np.testing.assert_allclose([delta_x, delta_y], reference_step(theta0, dx, dy, dtheta),
                               atol=1e-12)
    h = 1e-6
    numeric = np.empty((2, 3))
    for j in range(3):
        step = np.zeros(3)
        step[j] = h
        args = np.array([dx, dy, dtheta])
        numeric[:, j] = (reference_step(theta0, *(args + step))
                         - reference_step(theta0, *(args - step))) / (2 * h)
    np.testing.assert_allclose(np.array(m), numeric, atol=1e-7)


def test_body_jacobian_is_the_forward_kinematics():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(2, 20))
    expected = np.array(forward(*true_speeds(d[0], d[1], AURIGA), AURIGA))
    np.testing.assert_allclose(np.array(body_jacobian(AURIGA)) @ d, expected, atol=1e-15)


@given(st.lists(finite, min_size=6, max_size=6), finite, finite, st.floats(0, 1), st.floats(0, 1))
def test_propagate_equals_the_matrix_products(raw, delta_x, delta_y, var_l, var_r):
    a = np.array(raw).reshape(2, 3)
    p = a.T @ a  # any PSD matrix
    upper = (p[0, 0], p[0, 1], p[0, 2], p[1, 1], p[1, 2], p[2, 2])
    g = np.arange(6.0).reshape(3, 2) - 2.5
    f = np.array([[1, 0, -delta_y], [0, 1, delta_x], [0, 0, 1]])
    expected = f @ p @ f.T + g @ np.diag([var_l, var_r]) @ g.T
    got = full_matrix(propagate(upper, delta_x, delta_y, tuple(map(tuple, g)), var_l, var_r))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_straight_line_matches_kelly_closed_form():
    # Ideal drive, equal noise k on both tracks, straight line of length s in N steps.
    # x = (d_l + d_r) / 2: var x = k s / 2. theta = (d_r - d_l) / B: var theta = 2 k s / B^2.
    # A heading error made at u moves the end sideways by (s - u) theta: var y = 2 k s^3 /
    # (3 B^2) -- lateral uncertainty grows with the cube of the distance (Kelly 2004).
    k, width, s, n = 1e-3, 0.5, 10.0, 4000
    odo = Odometry(IcrParams.ideal(width), TrackNoise(k, k, 0.0))
    for _ in range(n):
        assert odo.update(s / n, s / n, 0.01)
    p = odo.covariance
    assert p[0, 0] == pytest.approx(k * s / 2, rel=1e-9)
    assert p[2, 2] == pytest.approx(2 * k * s / width ** 2, rel=1e-9)
    assert p[1, 1] == pytest.approx(2 * k * s ** 3 / (3 * width ** 2), rel=1e-3)
    assert p[1, 2] == pytest.approx(k * s ** 2 / width ** 2, rel=1e-3)
    assert p[0, 1] == pytest.approx(0.0, abs=1e-12)


def test_spin_in_place_heading_variance_closed_form():
    k, n = 1e-3, 500
    odo = Odometry(AURIGA, TrackNoise(k, k, 0.0))
    d = np.pi * 0.39 / n  # about half a turn
    for _ in range(n):
        odo.update(-d / AURIGA.scale_left, d / AURIGA.scale_right, 0.01)
    p = odo.covariance
    span = AURIGA.y_left - AURIGA.y_right
    dist = n * d  # true distance of each track; the nominal one is dist / scale
    # theta = (s_r d_r - s_l d_l) / span, var(d) = k dist / s on each side.
    expected_tt = k * dist * (AURIGA.scale_left + AURIGA.scale_right) / span ** 2
    assert p[2, 2] == pytest.approx(expected_tt, rel=1e-9)


def monte_carlo(icr, noise, d_left, d_right, runs, seed):
    """Replay a travel sequence ``runs`` times with noise; return the final poses."""
    rng = np.random.default_rng(seed)
    body = np.array(body_jacobian(icr))
    x = np.zeros(runs)
    y = np.zeros(runs)
    theta = np.zeros(runs)
    for dl, dr in zip(d_left, d_right):
        var_l, var_r = noise.travel_variances(dl, dr)
        noisy = np.stack([dl + rng.normal(0, np.sqrt(var_l), runs),
                          dr + rng.normal(0, np.sqrt(var_r), runs)])
        dx, dy, dth = body @ noisy
        cx, cy = arc_chord(dx, dy, dth)
        x, y, theta = compose(x, y, theta, cx, cy, dth)
    return np.stack([x, y, theta])


@pytest.mark.parametrize('name, v_left, v_right', [
    ('straight', 0.5, 0.5), ('turn', 0.2, 0.6), ('spin', -0.4, 0.4),
    ('reverse arc', -0.5, -0.3),
])
def test_propagation_matches_monte_carlo(name, v_left, v_right):
    # 4000 noisy runs of a 10 s manoeuvre at 20 Hz. The linearised covariance must match
    # the sample covariance within 10 % of sqrt(P_ii P_jj) per entry (the sampling error
    # of a variance from 4000 runs is about 2.2 %; the rest is linearisation).
    noise = TrackNoise(2e-4, 4e-4, 1e-8)
    n, dt = 200, 0.05
    d_left = np.full(n, v_left * dt)
    d_right = np.full(n, v_right * dt)
    odo = Odometry(AURIGA, noise)
    for dl, dr in zip(d_left, d_right):
        odo.update(dl, dr, dt)
    predicted = odo.covariance
    samples = monte_carlo(AURIGA, noise, d_left, d_right, 4000, seed=7)
    sampled = np.cov(samples)
    scale = np.sqrt(np.outer(np.diag(predicted), np.diag(predicted)))
    assert np.all(np.abs(sampled - predicted) <= 0.1 * scale), (sampled, predicted)
    # The mean run ends where the noise-free odometry does, to sampling error and the
    # second-order bias of heading errors (1 - cos e ~ e^2 / 2 over the path).
    error = np.abs(samples.mean(axis=1) - odo.pose)
    path = n * dt * max(abs(v_left), abs(v_right))
    assert np.all(error <= 4 * np.sqrt(np.diag(predicted) / 4000) + path * predicted[2, 2] / 2)


def test_propagation_matches_monte_carlo_on_an_s_curve():
    noise = TrackNoise(3e-4, 3e-4, 0.0)
    t = np.linspace(0.0, 12.0, 240)
    dt = t[1] - t[0]
    w = 0.8 * np.sin(2 * np.pi * t / 12.0)
    d_left = (0.4 - 0.2 * w) * dt
    d_right = (0.4 + 0.2 * w) * dt
    odo = Odometry(AURIGA, noise)
    for dl, dr in zip(d_left, d_right):
        odo.update(dl, dr, dt)
    sampled = np.cov(monte_carlo(AURIGA, noise, d_left, d_right, 4000, seed=3))
    predicted = odo.covariance
    scale = np.sqrt(np.outer(np.diag(predicted), np.diag(predicted)))
    assert np.all(np.abs(sampled - predicted) <= 0.1 * scale)


@given(st.lists(st.tuples(finite, finite), min_size=1, max_size=60),
       st.floats(0.2, 1.0), st.floats(0.0, 0.3), st.floats(-0.3, 0.3))
def test_pose_covariance_stays_symmetric_psd_and_grows(travel, chi, ecc, icr_x):
    width = 0.4
    span = width / chi
    icr = IcrParams(width, span * (1 - ecc) / 2, -span * (1 + ecc) / 2, icr_x, 0.9, 1.1)
    odo = Odometry(icr, TrackNoise(1e-3, 2e-3, 1e-9))
    previous = odo.covariance
    for dl, dr in travel:
        assert odo.update(0.1 * dl, 0.1 * dr, 0.02)
        p = odo.covariance
        assert np.array_equal(p, p.T)
        tol = 1e-12 * max(1.0, np.abs(p).max())
        assert np.linalg.eigvalsh(p).min() >= -tol
        # Heading errors only accumulate (the position variance may shrink when the
        # vehicle drives back, as the heading error's lever arm shortens).
        assert p[2, 2] >= previous[2, 2]
        previous = p


def test_twist_covariance_of_the_noise_model():
    body = body_jacobian(AURIGA)
    got = full_matrix(twist_covariance(body, 2e-6, 3e-6, 0.02))
    b = np.array(body)
    np.testing.assert_allclose(got, b @ np.diag([2e-6, 3e-6]) @ b.T / 0.02 ** 2, rtol=1e-12)


@pytest.mark.parametrize('rate', [10.0, 50.0, 100.0, 1000.0])
def test_twist_covariance_is_rate_independent_and_realistic(rate):
    # Issue 15: at 100 Hz sigma(v_x) was 0.12 m/s at v_x = 0.3 m/s. Driving straight at
    # 0.3 m/s and taking the twist at every step, sigma(v_x) no longer depends on the rate.
    icr = IcrParams.ideal(0.42)
    odometry = Odometry(icr, TrackNoise())
    for _ in range(int(rate)):
        odometry.update(0.3 / rate, 0.3 / rate, 1.0 / rate)
        twist, covariance = odometry.take_twist()
    assert twist[0] == pytest.approx(0.3)
    # var(v_l) = (k |v| tau + floor) / tau^2 for each track; v_x is their mean.
    var_track = (1e-3 * 0.3 * TWIST_TIME + 1e-9) / TWIST_TIME ** 2
    assert covariance[0] == pytest.approx(var_track / 2, rel=1e-9)
    assert 0.005 < covariance[0] ** 0.5 < 0.02
    # Standing still, the twist is known to the floor only.
    odometry.update(0.0, 0.0, 1.0 / rate)
    assert odometry.take_twist()[1][0] == pytest.approx(1e-9 / 2, rel=1e-9)


def test_twist_variances_of_the_noise_model():
    noise = TrackNoise(2e-3, 1e-3, 1e-8)
    assert twist_variances(noise, 0.5, 0.25) == pytest.approx(
        ((2e-3 * 0.5 * TWIST_TIME + 1e-8) / TWIST_TIME ** 2 * TWIST_TIME ** 2,
         (1e-3 * 0.25 * TWIST_TIME + 1e-8)))


def test_saturate_caps_variances_and_keeps_psd():
    rng = np.random.default_rng(3)
    for _ in range(100):
        a = rng.normal(size=(3, 3)) * 10.0 ** rng.uniform(-3, 9, size=(3, 1))
        p = a @ a.T
        upper = (p[0, 0], p[0, 1], p[0, 2], p[1, 1], p[1, 2], p[2, 2])
        got = full_matrix(saturate(upper, 1e6))
        assert np.all(np.diag(got) <= 1e6 * (1 + 1e-12))
        assert np.linalg.eigvalsh(got / np.abs(got).max()).min() > -1e-9
        small = np.diag(p) <= 1e6
        np.testing.assert_allclose(np.diag(got)[small], np.diag(p)[small], rtol=1e-12)
    small = (1.0, 0.1, 0.0, 2.0, 0.0, 0.5)
    assert saturate(small) is small
    capped = saturate((np.inf, 0.0, 0.0, 1.0, np.nan, 1.0))
    assert all(map(np.isfinite, capped)) and capped[0] == MAX_VARIANCE


def test_ros_covariance_layout():
    upper = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    full = ros_covariance(upper).reshape(6, 6)
    np.testing.assert_array_equal(full, full.T)
    np.testing.assert_array_equal(full[np.ix_([0, 1, 5], [0, 1, 5])], full_matrix(upper))
    assert full[2, 2] == full[3, 3] == full[4, 4] == UNOBSERVED_VARIANCE
    assert np.count_nonzero(full) == 9 + 3
