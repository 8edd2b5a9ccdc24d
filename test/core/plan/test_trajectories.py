"""core.plan.trajectories: the canonical reference inputs of Fink & Stump Table V."""

import numpy as np
import pytest
from tracked_kinematics.core.plan import canonical, trapezoid_profile


def test_trapezoid_is_table_v_speed_profile():
    # p_v = [0 m/s, 5 m/s^2, 1 m/s, 5 m/s^2, 0 m/s] over 4 s: 0.2 s ramps, 3.8 m.
    t = (np.arange(400) + 0.5) * 0.01
    v = trapezoid_profile(t, 4.0, 0.0, 5.0, 1.0, 5.0, 0.0)
    assert v.max() == pytest.approx(1.0)
    assert np.sum(v) * 0.01 == pytest.approx(3.8, abs=1e-3)
    assert np.all(np.abs(np.diff(v)) <= 5.0 * 0.01 + 1e-12)


def test_canonical_left_right_mirror_and_s_curve_turns_both_ways():
    left, right = canonical('left'), canonical('right')
    assert left.duration == pytest.approx(4.0) and canonical('s_curve').duration == 6.0
    np.testing.assert_allclose(right.path[:, 1], -left.path[:, 1], atol=1e-12)
    assert left.goal[2] > 1.0          # kappa 1.5 1/m at the middle knot: a sharp turn
    w = canonical('s_curve').w
    assert w.min() < -0.5 and w.max() > 0.5
    lane = canonical('lane_change').goal
    assert abs(lane[2]) < 0.05 and lane[1] > 0.5   # left first, then back
    spin = canonical('spin')
    assert np.all(spin.v == 0.0) and np.hypot(*spin.goal[:2]) < 1e-9 and spin.goal[2] > 1.0
    with pytest.raises(ValueError, match='choose one of'):
        canonical('loop')
