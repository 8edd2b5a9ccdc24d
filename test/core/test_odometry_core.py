"""The odometry state machine against the vectorised core and closed forms."""

import math

from helpers.manoeuvres import MANOEUVRES, track_speeds
import numpy as np
import pytest
from tracked_kinematics.core.covariance import (body_jacobian, full_matrix, MAX_VARIANCE,
                                                TrackNoise, TWIST_TIME)
from tracked_kinematics.core.integration import integrate
from tracked_kinematics.core.kinematics import forward, IcrParams, true_speeds
from tracked_kinematics.core.odometry import Odometry

AURIGA = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)


def manoeuvre(name, rate=100.0):
    """Nominal track travel per step of a scripted manoeuvre, and the step duration."""
    dt = 1.0 / rate
    # 6 s; the S-curve's turn rate follows a sine over the run.
    v_left, v_right = track_speeds(name, np.arange(0.0, 6.0, dt), 6.0, 0.25)
    return v_left * dt, v_right * dt, dt


@pytest.mark.parametrize('name', MANOEUVRES)
def test_steps_match_vectorised_core(name):
    d_left, d_right, dt = manoeuvre(name)
    odo = Odometry(AURIGA)
    poses = []
    for dl, dr in zip(d_left, d_right):
        assert odo.update(dl, dr, dt)
        poses.append(odo.pose)
    x, y, theta = integrate(*forward(*true_speeds(d_left, d_right, AURIGA), AURIGA))
    np.testing.assert_allclose(np.array(poses), np.stack([x, y, theta], -1), atol=1e-12)
    assert odo.steps == d_left.size


def test_constant_turn_closed_form_with_lateral_slip():
    # True track speeds 0.2 and 0.6 m/s: w = 0.4 / 0.778, v_x from eq. (8), v_y = -x w.
    # The body moves on a circle of radius hypot(v_x, v_y) / w about (-v_y / w, v_x / w).
    odo = Odometry(AURIGA)
    dt, n = 0.01, 700
    for _ in range(n):
        odo.update(0.2 * dt / AURIGA.scale_left, 0.6 * dt / AURIGA.scale_right, dt)
    span = AURIGA.y_left - AURIGA.y_right
    w = 0.4 / span
    v_x = 0.4 + w * (AURIGA.y_left + AURIGA.y_right) / 2
    v_y = -AURIGA.x * w
    t = n * dt
    centre = np.array([-v_y / w, v_x / w])
    x, y, theta = odo.pose
    assert theta == pytest.approx(w * t, abs=1e-12)
    # Rotating the start point about the centre by w t gives the end point.
    c, s = math.cos(w * t), math.sin(w * t)
    expected = centre + np.array([[c, -s], [s, c]]) @ (-centre)
    np.testing.assert_allclose([x, y], expected, atol=1e-12)
    twist, _ = odo.take_twist()
    np.testing.assert_allclose(twist, [v_x, v_y, w], atol=1e-12)
    assert twist[1] < 0.0  # the ICRs ahead of base_link push the body out of the turn


def test_invalid_steps_leave_the_state_alone():
    odo = Odometry(AURIGA)
    odo.update(0.01, 0.02, 0.01)
    before = (odo.pose, odo.covariance_upper, odo.steps)
    for args in [(math.nan, 0.0, 0.01), (0.0, math.inf, 0.01), (0.0, 0.0, 0.0),
                 (0.0, 0.0, -0.1), (0.0, 0.0, math.nan), (1e308, -1e308, 0.01)]:
        assert not odo.update(*args)
    assert (odo.pose, odo.covariance_upper, odo.steps) == before


def test_reset_zeroes_pose_and_covariance_and_keeps_the_model():
    odo = Odometry(AURIGA)
    for _ in range(10):
        odo.update(0.01, 0.03, 0.01)
    odo.reset()
    assert odo.pose == (0.0, 0.0, 0.0) and odo.steps == 0
    assert not odo.covariance.any()
    odo.update(0.01, 0.01, 0.01)
    assert odo.pose[0] == pytest.approx(forward(*true_speeds(0.01, 0.01, AURIGA), AURIGA)[0])


def test_twist_is_the_mean_over_the_window():
    noise = TrackNoise(1e-3, 2e-3, 1e-9)
    odo = Odometry(AURIGA, noise)
    steps = [(0.01, 0.02, 0.01), (0.012, 0.018, 0.02), (-0.003, 0.02, 0.01)]
    for step in steps:
        odo.update(*step)
    twist, cov = odo.take_twist()
    d = np.array(steps)
    duration = d[:, 2].sum()
    expected = np.array(forward(*true_speeds(d[:, 0].sum(), d[:, 1].sum(), AURIGA), AURIGA))
    np.testing.assert_allclose(twist, expected / duration, rtol=1e-12)
    # The covariance: the noise model's travel variance over TWIST_TIME at the window's
    # distance rates, as speeds.
    b = np.array(body_jacobian(AURIGA))
    rates = np.abs(d[:, :2]).sum(axis=0) / duration
    q = np.diag([1e-3 * rates[0] * TWIST_TIME + 1e-9, 2e-3 * rates[1] * TWIST_TIME + 1e-9])
    expected = b @ q @ b.T / TWIST_TIME ** 2
    expected[1, 1] += 1e-9 / TWIST_TIME ** 2  # the floor on v_y: never a zero variance
    np.testing.assert_allclose(full_matrix(cov), expected, rtol=1e-12)
    # The window restarted: nothing since, so no motion and the floor's covariance.
    twist, cov = odo.take_twist()
    assert twist == (0.0, 0.0, 0.0)
    assert np.all(np.diag(full_matrix(cov)) > 0.0)


def test_absurd_travel_never_freezes_the_state():
    # Issue 14 item 6, in the core: absurd steps are refused whole, the covariance cannot
    # overflow, and a 90 degree spin afterwards turns the heading by 90 degrees.
    odo = Odometry(IcrParams.ideal(0.42))
    for d_left in (1e100, 3e99, 0.0, 1e10):
        odo.update(d_left, 0.0, 0.01)
    assert all(map(math.isfinite, odo.pose + odo.covariance_upper))
    heading = odo.pose[2]
    quarter = 0.5 * math.pi * 0.21  # track travel of a 90 degree spin
    for _ in range(10):
        assert odo.update(-quarter / 10, quarter / 10, 0.01)
    assert odo.pose[2] - heading == pytest.approx(0.5 * math.pi, abs=1e-9)


def test_a_step_whose_twist_overflows_is_not_integrated():
    # Finite travel over a tiny dt would publish an infinite twist: no hidden jump.
    odo = Odometry(AURIGA)
    assert not odo.update(1e10, 1e10, 1e-300)
    assert not odo.update(1e300, 0.0, 1.0)
    assert odo.pose == (0.0, 0.0, 0.0) and odo.steps == 0
    twist, cov = odo.take_twist()
    assert twist == (0.0, 0.0, 0.0) and all(map(math.isfinite, cov))


def test_covariance_saturates_instead_of_overflowing():
    odo = Odometry(IcrParams.ideal(0.42), TrackNoise(1.0, 1.0, 1.0))
    for _ in range(200):
        assert odo.update(1e8, -1e8, 10.0)   # huge spins: the heading variance explodes
        assert odo.update(1e8, 1e8, 10.0)    # huge straights: position variance too
    assert max(odo.covariance_upper) <= MAX_VARIANCE
    assert np.linalg.eigvalsh(odo.covariance / MAX_VARIANCE).min() > -1e-9
    # Still integrating: a small step moves the pose by its length.
    x, y, theta = odo.pose
    assert abs(theta) <= 2e6
    assert odo.update(0.1, 0.1, 0.1)
    assert math.hypot(odo.pose[0] - x, odo.pose[1] - y) == pytest.approx(0.1, rel=1e-6)


def test_set_model_keeps_the_pose_and_applies_from_the_next_step():
    odo = Odometry(IcrParams.ideal(0.42))
    odo.update(0.1, 0.1, 0.1)
    odo.set_model(AURIGA)
    assert odo.pose == pytest.approx((0.1, 0.0, 0.0))
    odo.update(0.0, 0.1, 0.1)
    assert odo.pose[2] == pytest.approx(0.1 * AURIGA.scale_right / 0.778)
