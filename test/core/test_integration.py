"""Pose integration: closed-form circles, rate independence, vectorised = sequential."""

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest

from tracked_kinematics.core.integration import (
    arc_chord, compose, integrate, integrate_twist, relative_pose, wrap_angle)


def test_wrap_angle():
    np.testing.assert_allclose(wrap_angle([0.0, np.pi / 2, 3 * np.pi, -3 * np.pi / 2, 7.0]),
                               [0.0, np.pi / 2, -np.pi, np.pi / 2, 7.0 - 2 * np.pi])


def test_constant_turn_matches_closed_form_circle():
    # v = 0.4 m/s, w = 0.5 rad/s: circle of radius 0.8 m centred at (0, 0.8).
    v, w, dt, n = 0.4, 0.5, 0.01, 1000
    x, y, th = integrate_twist(np.full(n, v), np.zeros(n), np.full(n, w), dt)
    t = dt * np.arange(1, n + 1)
    r = v / w
    np.testing.assert_allclose(x, r * np.sin(w * t), atol=1e-9)
    np.testing.assert_allclose(y, r * (1 - np.cos(w * t)), atol=1e-9)
    np.testing.assert_allclose(th, w * t, atol=1e-12)


def test_closed_circle_returns_to_start():
    # A full turn of 2 pi in 10,000 steps comes back to the origin to round-off.
    n = 10_000
    x, y, th = integrate_twist(np.full(n, 1.0), np.zeros(n), np.full(n, 1.0), 2 * np.pi / n)
    assert abs(x[-1]) < 1e-9 and abs(y[-1]) < 1e-9
    assert th[-1] == pytest.approx(2 * np.pi)


def test_lateral_velocity_circle():
    # A twist with lateral slip: the body still moves on a circle of radius |v| / |w|, and
    # the heading lags the velocity direction by atan2(v_y, v_x).
    v_x, v_y, w, dt, n = 0.3, -0.05, 0.7, 0.02, 400
    x, y, th = integrate_twist(np.full(n, v_x), np.full(n, v_y), np.full(n, w), dt)
    speed = np.hypot(v_x, v_y)
    centre = np.array([-v_y / w, v_x / w])
    np.testing.assert_allclose(np.hypot(x - centre[0], y - centre[1]), speed / w, atol=1e-9)


def test_rate_independent_for_constant_twist():
    coarse = integrate_twist(np.full(10, 0.5), np.full(10, 0.1), np.full(10, -1.2), 0.1)
    fine = integrate_twist(np.full(1000, 0.5), np.full(1000, 0.1), np.full(1000, -1.2), 0.001)
    for a, b in zip(coarse, fine):
        assert a[-1] == pytest.approx(b[-1], abs=1e-12)


def test_straight_line_and_pure_spin():
    x, y, th = integrate([0.1, 0.1], [0.0, 0.0], [0.0, 0.0], pose0=(1.0, 2.0, np.pi / 2))
    np.testing.assert_allclose([x[-1], y[-1], th[-1]], [1.0, 2.2, np.pi / 2], atol=1e-12)
    x, y, th = integrate([0.0], [0.0], [1.0])
    assert (x[-1], y[-1], th[-1]) == (0.0, 0.0, 1.0)


def test_arc_chord_small_angle_limit():
    cx, cy = arc_chord(1.0, 0.0, 1e-12)
    assert cx == pytest.approx(1.0)
    assert cy == pytest.approx(0.5e-12)
    cx, cy = arc_chord(1.0, 0.0, 0.0)
    assert (cx, cy) == (1.0, 0.0)


increments = st.lists(st.tuples(st.floats(-1, 1), st.floats(-0.3, 0.3), st.floats(-2, 2)),
                      min_size=1, max_size=40)


@given(increments, st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-4, 4)))
def test_vectorised_equals_sequential_composition(steps, pose0):
    dx, dy, dth = np.array(steps).T
    x, y, th = integrate(dx, dy, dth, pose0=pose0)
    px, py, pth = pose0
    for k in range(len(dx)):
        cx, cy = arc_chord(dx[k], dy[k], dth[k])
        px, py, pth = compose(px, py, pth, cx, cy, dth[k])
    assert x[-1] == pytest.approx(float(px), abs=1e-9)
    assert y[-1] == pytest.approx(float(py), abs=1e-9)
    assert th[-1] == pytest.approx(float(pth), abs=1e-9)


@given(increments)
def test_relative_pose_inverts_compose(steps):
    dx, dy, dth = np.array(steps).T
    x, y, th = integrate(dx, dy, dth, pose0=(0.3, -0.2, 1.0))
    rx, ry, rth = relative_pose(x[0], y[0], th[0], x[-1], y[-1], th[-1])
    bx, by, bth = compose(x[0], y[0], th[0], rx, ry, rth)
    assert float(bx) == pytest.approx(x[-1], abs=1e-9)
    assert float(by) == pytest.approx(y[-1], abs=1e-9)
    assert float(wrap_angle(bth - th[-1])) == pytest.approx(0.0, abs=1e-9)


def test_segment_increments_from_one_integration():
    # Relative poses between points of one integrated path equal integrating each segment
    # from the origin: what lets identification integrate a whole log once.
    rng = np.random.default_rng(3)
    dx, dy, dth = rng.normal(0, 0.05, size=(3, 300))
    x, y, th = integrate(dx, dy, dth)
    seg = slice(120, 180)
    rel = relative_pose(x[119], y[119], th[119], x[179], y[179], th[179])
    sx, sy, sth = integrate(dx[seg], dy[seg], dth[seg])
    np.testing.assert_allclose(rel, [sx[-1], sy[-1], wrap_angle(sth[-1])], atol=1e-12)
