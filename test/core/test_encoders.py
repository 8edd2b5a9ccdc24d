"""Encoder readings to track travel: positions, velocities, wrapping counters."""

from hypothesis import given
from hypothesis import strategies as st
import numpy as np
import pytest
from tracked_kinematics.core.encoders import (
    counter_increments, IncrementTracker, mean_over_joints, PLAUSIBILITY_SLACK, Status,
    travel_from_positions, travel_from_ticks, travel_from_velocities, unwrap_if_wrapped)

SECOND = 1_000_000_000


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
        # Random readings are not a vehicle: no plausibility limit here.
        tracker = IncrementTracker(max_dt=1.0, max_speed=1e9)
        steps = [tracker.update(int(ns), kind, values[0][i].item(), values[1][i].item(),
                                factors[kind], bits=16) for i, ns in enumerate(stamps_ns)]
        assert steps[0][0] == Status.FIRST
        assert all(step[0] == Status.STEP for step in steps[1:])
        got = np.array([step[1:3] for step in steps[1:]]).T
        np.testing.assert_allclose(got, expected[kind], rtol=1e-12, atol=1e-15, err_msg=kind)
        np.testing.assert_allclose([step[3] for step in steps[1:]], np.diff(t), rtol=1e-12)


def test_tracker_checks():
    tracker = IncrementTracker(max_dt=0.5)
    second = SECOND
    assert tracker.update(1 * second, 'position', 0.0, 0.0, 1.0)[0] == Status.FIRST
    # A non-finite sample is skipped; the baseline stays, so the travel across it is exact.
    assert tracker.update(2 * second // 10 * 6, 'position', np.nan, 0.0, 1.0)[0] == (
        Status.NON_FINITE)
    assert tracker.update(13 * second // 10, 'position', 1.0, 2.0, 1.0) == pytest.approx(
        (Status.STEP, 1.0, 2.0, 0.3))
    # The same sample again (delivered twice) is ignored; another one at the same time, or
    # time going back, restarts from the new sample.
    assert tracker.update(13 * second // 10, 'position', 1.0, 2.0, 1.0)[0] == Status.DUPLICATE
    assert tracker.update(13 * second // 10, 'position', 5.0, 5.0, 1.0)[0] == Status.TIME_BACK
    assert tracker.update(14 * second // 10, 'position', 5.5, 5.5, 1.0)[1] == 0.5
    assert tracker.update(1 * second, 'position', 0.0, 0.0, 1.0)[0] == Status.TIME_BACK
    # Positions integrate across a gap longer than max_dt: their travel is exact.
    assert tracker.update(2 * second, 'position', 9.0, 9.0, 1.0) == (
        Status.LONG_STEP, 9.0, 9.0, 1.0)
    assert tracker.update(21 * second // 10, 'position', 9.1, 9.0, 1.0)[1] == pytest.approx(0.1)
    # Switching to velocities restarts.
    assert tracker.update(22 * second // 10, 'velocity', 1.0, 1.0, 1.0)[0] == (
        Status.KIND_CHANGED)
    assert tracker.update(23 * second // 10, 'velocity', 1.0, 1.0, 1.0)[1] == pytest.approx(0.1)
    # Velocities are bridged up to max_dt only: beyond, the travel is unknown.
    assert tracker.update(27 * second // 10, 'velocity', 1.0, 1.0, 1.0)[1] == pytest.approx(0.4)
    assert tracker.update(33 * second // 10, 'velocity', 1.0, 1.0, 1.0) == pytest.approx(
        (Status.GAP, 0.0, 0.0, 0.6))
    assert tracker.update(34 * second // 10, 'velocity', 1.0, 1.0, 1.0)[0] == Status.STEP


def test_unwrap_if_wrapped_reads_continuous_joints():
    truth = np.linspace(0, 20, 400)
    angles = np.angle(np.exp(1j * truth))
    np.testing.assert_allclose(unwrap_if_wrapped(angles), truth, atol=1e-9)
    np.testing.assert_allclose(unwrap_if_wrapped(angles), np.unwrap(angles), atol=1e-12)
    cumulative = np.linspace(0, 20, 400)
    assert unwrap_if_wrapped(cumulative) is cumulative
    quiet = np.linspace(-1.0, 1.0, 50)  # within [-pi, pi], no jump: nothing to unwrap
    assert unwrap_if_wrapped(quiet) is quiet
    # A fast wheel's real step of 3.2 rad (more than pi, less than 1.5 pi) is no wrap.
    fast = np.array([-1.6, 1.6, -1.6])
    assert unwrap_if_wrapped(fast) is fast


@pytest.mark.parametrize('direction', [1.0, -1.0])
def test_tracker_unwraps_positions_as_the_bag_reader(direction):
    # A continuous joint reported in [-pi, pi]: 1 m of travel at r = 0.1 m is 10 rad.
    truth = direction * np.linspace(0.0, 10.0, 101)
    reported = np.angle(np.exp(1j * truth))
    tracker = IncrementTracker()
    travel = np.zeros(2)
    for i, (left, right) in enumerate(zip(reported, -reported)):
        status, d_left, d_right, _ = tracker.update(SECOND + i * SECOND // 50, 'position',
                                                    float(left), float(right), 0.1)
        if status in Status.STEPS:
            travel += (d_left, d_right)
    np.testing.assert_allclose(travel, [direction, -direction], atol=1e-12)
    expected = np.diff(unwrap_if_wrapped(reported)).sum() * 0.1
    assert travel[0] == pytest.approx(expected, abs=1e-12)


def test_cumulative_positions_are_not_unwrapped():
    # A cumulative joint that has left [-pi, pi] is never unwrapped, however far it jumps.
    tracker = IncrementTracker(max_speed=1000.0)
    tracker.update(SECOND, 'position', 4.0, 4.0, 0.1)
    assert tracker.update(2 * SECOND, 'position', 9.0, 0.0, 0.1) == pytest.approx(
        (Status.LONG_STEP, 0.5, -0.4, 1.0))


def test_gate_skips_absurd_positions_and_resumes():
    # Issue 14 item 6: left 1e100, 3e99, 0 rad are skipped; what follows is integrated.
    tracker = IncrementTracker(max_speed=10.0)
    t = [SECOND + i * SECOND // 100 for i in range(8)]
    assert tracker.update(t[0], 'position', 0.0, 0.0, 0.1)[0] == Status.FIRST
    status, d_left, _, dt = tracker.update(t[1], 'position', 1e100, 0.0, 0.1)
    assert status == Status.IMPLAUSIBLE and d_left == pytest.approx(1e99)
    assert tracker.update(t[2], 'position', 3e99, 0.0, 0.1)[0] == Status.IMPLAUSIBLE
    # 0 rad again: the step from the kept baseline is plausible (nothing moved).
    assert tracker.update(t[3], 'position', 0.0, 0.0, 0.1) == pytest.approx(
        (Status.STEP, 0.0, 0.0, 0.03))
    assert tracker.update(t[4], 'position', 0.1, 0.1, 0.1) == pytest.approx(
        (Status.STEP, 0.01, 0.01, 0.01))


def test_a_glitch_costs_no_travel():
    tracker = IncrementTracker(max_speed=10.0)
    readings = [0.0, 0.01, 55.0, 0.03, 0.04]  # rad; the third is a glitch
    steps = [tracker.update(SECOND + i * SECOND // 100, 'position', v, v, 1.0)
             for i, v in enumerate(readings)]
    assert [s[0] for s in steps] == [Status.FIRST, Status.STEP, Status.IMPLAUSIBLE,
                                     Status.STEP, Status.STEP]
    assert sum(s[1] for s in steps if s[0] in Status.STEPS) == pytest.approx(0.04)


def test_counter_restart_is_a_restart_not_a_step():
    # Issue 14: an int32 counter restarting from 1,000,000 to 0 is not a 153 m step.
    factor = 2 * np.pi * 0.1 / 4096
    tracker = IncrementTracker(max_speed=10.0)
    counts = [999_980, 999_990, 1_000_000, 0, 10, 20]
    steps = [tracker.update(SECOND + i * SECOND // 100, 'ticks', c, c, factor, 32)
             for i, c in enumerate(counts)]
    assert [s[0] for s in steps] == [Status.FIRST, Status.STEP, Status.STEP,
                                     Status.IMPLAUSIBLE, Status.RESUMED, Status.STEP]
    assert steps[3][1] == pytest.approx(-1_000_000 * factor)  # what was refused: -153 m
    assert sum(s[1] for s in steps if s[0] in Status.STEPS) == pytest.approx(40 * factor)


def test_implausible_speeds_are_skipped():
    tracker = IncrementTracker(max_dt=0.5, max_speed=10.0)
    tracker.update(SECOND, 'velocity', 1.0, 1.0, 0.1)
    assert tracker.update(SECOND + SECOND // 10, 'velocity', 1e6, 1.0, 0.1) == pytest.approx(
        (Status.IMPLAUSIBLE, 1e5, 0.1, 0.1))
    # The baseline is kept: the next sample is bridged from it (0.2 s at 0.1 m/s).
    assert tracker.update(SECOND + SECOND // 5, 'velocity', 1.0, 1.0, 0.1) == pytest.approx(
        (Status.STEP, 0.02, 0.02, 0.2))


@given(st.lists(st.tuples(st.integers(1, 10**9), st.integers(-2**63, 2**63 - 1),
                          st.integers(-2**63, 2**63 - 1)), min_size=2, max_size=60),
       st.sampled_from([32, 64]))
def test_garbage_counters_never_exceed_the_plausible_speed(samples, bits):
    factor = 2 * np.pi * 0.1 / 4096
    tracker = IncrementTracker(max_speed=10.0)
    t = SECOND
    for dt_ns, left, right in samples:
        t += dt_ns
        if bits == 32:
            left, right = (left % 2**32) - 2**31, (right % 2**32) - 2**31
        status, d_left, d_right, dt = tracker.update(t, 'ticks', left, right, factor, bits)
        if status in Status.STEPS:
            limit = 10.0 * (dt + PLAUSIBILITY_SLACK) * (1 + 1e-12)
            assert abs(d_left) <= limit and abs(d_right) <= limit


@given(st.lists(st.tuples(st.integers(-10**9, 10**9),
                          st.floats(allow_nan=True, allow_infinity=True, width=64),
                          st.floats(allow_nan=True, allow_infinity=True, width=64),
                          st.sampled_from(['position', 'velocity'])), max_size=60))
def test_any_input_gives_finite_plausible_steps(samples):
    tracker = IncrementTracker(max_dt=0.5, max_speed=10.0)
    t = SECOND
    for dt_ns, left, right, kind in samples:
        t += dt_ns
        status, d_left, d_right, dt = tracker.update(t, kind, left, right, 0.1)
        if status in Status.STEPS:
            assert dt > 0.0
            limit = 10.0 * (dt + PLAUSIBILITY_SLACK) * (1 + 1e-12)
            assert abs(d_left) <= limit and abs(d_right) <= limit
