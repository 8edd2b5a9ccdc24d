"""Encoder readings to track travel: positions, velocities, wrapping counters."""

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest
from tracked_kinematics.core.encoders import (
    counter_increments, mean_over_joints, travel_from_positions, travel_from_ticks,
    travel_from_velocities)


def test_positions_give_exact_travel():
    np.testing.assert_allclose(travel_from_positions([0.0, 1.0, 0.5], 0.1), [0.1, -0.05])


def test_mean_over_joints():
    np.testing.assert_allclose(mean_over_joints([[1.0, 3.0], [2.0, 2.0]]), [2.0, 2.0])
    np.testing.assert_allclose(mean_over_joints([1.0, 2.0]), [1.0, 2.0])


def test_velocities_trapezoidal_exact_for_linear_ramp():
    t = np.linspace(0.0, 2.0, 21)
    v = 0.5 * t  # travel = t^2 / 4
    travel = travel_from_velocities(v, t, scale=0.1)
    assert travel.sum() == pytest.approx(0.1 * 1.0)


@pytest.mark.parametrize('bits', [32, 64])
def test_counter_wraps_forwards_and_backwards(bits):
    top = (1 << (bits - 1)) - 1
    bottom = -(1 << (bits - 1))
    np.testing.assert_array_equal(counter_increments([top - 1, top, bottom, bottom + 5], bits),
                                  [1, 1, 5])
    np.testing.assert_array_equal(counter_increments([bottom + 1, top - 2], bits), [-4])


@given(st.lists(st.integers(-1000, 1000), min_size=1, max_size=50),
       st.integers(-2**31, 2**31 - 1))
def test_unwrapped_counter_recovers_true_increments(steps, start):
    true = np.cumsum([start] + steps)
    wrapped = (true + 2**31) % 2**32 - 2**31  # what an Int32 counter shows
    np.testing.assert_array_equal(counter_increments(wrapped, 32), steps)


def test_ticks_to_travel():
    # 1024 ticks per revolution, r = 0.1 m: one revolution is 0.2 pi m.
    assert float(travel_from_ticks(1024, 1024, 0.1)) == pytest.approx(0.2 * np.pi)
