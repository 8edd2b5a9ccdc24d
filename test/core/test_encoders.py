"""Encoder readings to track travel: positions, velocities, wrapping counters."""

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest
from tracked_kinematics.core.encoders import (
    counter_increments, IncrementTracker, mean_over_joints, Status, travel_from_positions,
    travel_from_ticks, travel_from_velocities)


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


def test_tracker_matches_the_vectorised_functions():
    rng = np.random.default_rng(4)
    stamps = np.cumsum(rng.uniform(0.005, 0.02, 50))
    stamps_ns = (stamps * 1e9).astype(np.int64)
    positions = np.cumsum(rng.normal(size=(2, 50)), axis=1)
    counts = rng.integers(-2**31, 2**31, size=(2, 50))
    t = stamps_ns * 1e-9
    expected = {
        'position': [travel_from_positions(p, 0.1) for p in positions],
        'velocity': [travel_from_velocities(p, t, 0.1) for p in positions],
        'ticks': [travel_from_ticks(counter_increments(c, 16), 1024, 0.1) for c in counts % 2**16],
    }
    readings = {'position': positions, 'velocity': positions, 'ticks': counts % 2**16}
    factors = {'position': 0.1, 'velocity': 0.1, 'ticks': 2 * np.pi * 0.1 / 1024}
    for kind, values in readings.items():
        tracker = IncrementTracker(max_dt=1.0)
        steps = [tracker.update(int(ns), kind, values[0][i].item(), values[1][i].item(),
                                factors[kind], bits=16) for i, ns in enumerate(stamps_ns)]
        assert steps[0][0] == Status.FIRST
        assert all(step[0] == Status.STEP for step in steps[1:])
        got = np.array([step[1:3] for step in steps[1:]]).T
        np.testing.assert_allclose(got, expected[kind], rtol=1e-12, atol=1e-15, err_msg=kind)
        np.testing.assert_allclose([step[3] for step in steps[1:]], np.diff(t), rtol=1e-12)


def test_tracker_checks():
    tracker = IncrementTracker(max_dt=0.5)
    second = 1_000_000_000
    assert tracker.update(1 * second, 'position', 0.0, 0.0, 1.0)[0] == Status.FIRST
    # A non-finite sample is skipped; the baseline stays, so the travel across it is exact.
    assert tracker.update(2 * second // 10 * 6, 'position', np.nan, 0.0, 1.0)[0] == (
        Status.NON_FINITE)
    assert tracker.update(13 * second // 10, 'position', 1.0, 2.0, 1.0) == pytest.approx(
        (Status.STEP, 1.0, 2.0, 0.3))
    # Time going back or standing still restarts from the new sample.
    assert tracker.update(13 * second // 10, 'position', 5.0, 5.0, 1.0)[0] == Status.TIME_BACK
    assert tracker.update(14 * second // 10, 'position', 5.5, 5.5, 1.0)[1] == 0.5
    assert tracker.update(1 * second, 'position', 0.0, 0.0, 1.0)[0] == Status.TIME_BACK
    # A gap longer than max_dt restarts as well, without a step over the gap.
    assert tracker.update(2 * second, 'position', 9.0, 9.0, 1.0) == (
        Status.GAP, 0.0, 0.0, 1.0)
    assert tracker.update(21 * second // 10, 'position', 9.1, 9.0, 1.0)[1] == pytest.approx(0.1)
    # Switching to velocities restarts.
    assert tracker.update(22 * second // 10, 'velocity', 1.0, 1.0, 1.0)[0] == (
        Status.KIND_CHANGED)
    assert tracker.update(23 * second // 10, 'velocity', 1.0, 1.0, 1.0)[1] == pytest.approx(0.1)
