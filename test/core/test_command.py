"""Command path core: twist -> limited nominal track setpoints, without ROS."""

import math

from hypothesis import assume, given
from hypothesis import strategies as st
import numpy as np
import pytest

from tracked_kinematics.core.command import (
    CommandLimiter, CommandLimits, envelope_setpoints, exceeds_envelope, limit_twist,
    saturate_tracks, setpoint_problem, setpoint_twist, track_setpoints, TRACK_SPEED_ENVELOPE)
from tracked_kinematics.core.kinematics import forward, IcrParams, true_speeds

# Martinez et al. (2005), sec. 5.3 and 6: Auriga-alpha on hard floor, in ROS axes.
AURIGA = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)
EPS = 1e-9

speeds = st.floats(-3.0, 3.0)
limits_or_inf = st.one_of(st.just(math.inf), st.floats(0.05, 5.0))


@st.composite
def icr_models(draw):
    width = draw(st.floats(0.2, 1.5))
    chi = draw(st.floats(0.3, 1.0))
    ecc = draw(st.floats(-0.3, 0.3))
    span = width / chi
    mid = -ecc * span / 2
    return IcrParams(width, mid + span / 2, mid - span / 2, draw(st.floats(-0.2, 0.2)),
                     draw(st.floats(0.8, 1.2)), draw(st.floats(0.8, 1.2)))


def twist_of(left, right, icr):
    """Return the body twist (v_x, w) that nominal setpoints give, through the odometry model."""
    v_x, _, w = forward(*true_speeds(left, right, icr), icr)
    return float(v_x), float(w)


def test_setpoints_golden_auriga():
    # Eqs. (10)-(11) in ROS axes: V_l = 0.5 - 0.353 * 0.3 = 0.3941, V_r = 0.5 + 0.425 * 0.3
    # = 0.6275 m/s true; nominal = true / scale (eqs. 20-21).
    left, right = track_setpoints(0.5, 0.3, AURIGA)
    assert left == pytest.approx(0.3941 / 1.0072)
    assert right == pytest.approx(0.6275 / 1.0275)


def test_setpoints_ideal_drive_is_diff_drive():
    left, right = track_setpoints([1.0, 0.0], [0.0, 2.0], IcrParams.ideal(0.5))
    np.testing.assert_allclose(left, [1.0, -0.5])
    np.testing.assert_allclose(right, [1.0, 0.5])


@given(icr_models(), speeds, speeds)
def test_round_trip_through_odometry_model(icr, v_x, w):
    # Setpoints, scaled back to true speeds and through the forward kinematics, give the
    # commanded v_x and w (and the lateral velocity -x w that cannot be commanded away).
    left, right = track_setpoints(v_x, w, icr)
    v_x2, v_y2, w2 = forward(*true_speeds(left, right, icr), icr)
    assert v_x2 == pytest.approx(v_x, abs=1e-9)
    assert w2 == pytest.approx(w, abs=1e-9)
    assert v_y2 == pytest.approx(-icr.x * w, abs=1e-9)


@given(speeds, speeds, limits_or_inf, limits_or_inf)
def test_twist_limits_met_and_curvature_kept(v_x, w, max_v, max_w):
    v2, w2 = limit_twist(v_x, w, max_v, max_w)
    assert abs(v2) <= max_v * (1 + EPS) and abs(w2) <= max_w * (1 + EPS)
    assert v2 * w == pytest.approx(w2 * v_x, abs=1e-12)  # same direction in (v, w)
    assert abs(v2) <= abs(v_x) and abs(w2) <= abs(w) and v2 * v_x >= 0 and w2 * w >= 0
    if abs(v_x) <= max_v and abs(w) <= max_w:
        assert (v2, w2) == (v_x, w)


def test_twist_limits_vectorised():
    v2, w2 = limit_twist([2.0, 0.5, 0.0], [1.0, 0.1, -4.0], max_linear=1.0, max_angular=2.0)
    np.testing.assert_allclose(v2, [1.0, 0.5, 0.0])
    np.testing.assert_allclose(w2, [0.5, 0.1, -2.0])


@given(icr_models(), speeds, speeds, st.floats(0.05, 2.0))
def test_saturation_keeps_curvature(icr, v_x, w, max_speed):
    assume(abs(v_x) + abs(w) > 1e-3)
    left, right = saturate_tracks(*track_setpoints(v_x, w, icr), max_speed)
    assert max(abs(left), abs(right)) <= max_speed * (1 + EPS)
    v2, w2 = twist_of(left, right, icr)
    assert v2 * w == pytest.approx(w2 * v_x, abs=1e-9)
    assert v2 * v_x >= -1e-12 and w2 * w >= -1e-12


def test_saturation_golden():
    # 1 m/s ahead with a 0.5 rad/s turn on an ideal 0.5 m drive: tracks 0.875 and 1.125 m/s;
    # a 0.9 m/s limit scales both by 0.8: 0.7 and 0.9 m/s, i.e. 0.8 m/s and 0.4 rad/s.
    left, right = saturate_tracks(*track_setpoints(1.0, 0.5, IcrParams.ideal(0.5)), 0.9)
    assert (float(left), float(right)) == pytest.approx((0.7, 0.9))


def test_limits_accept_inf():
    assert CommandLimits(max_track_speed=math.inf).max_track_speed == math.inf


def run_limiter(limiter, commands, dts):
    """Feed (v_x, w) commands, one per update after the given intervals; return setpoints."""
    t, out = 0.0, []
    limiter.update(t)
    for (v_x, w), dt in zip(commands, dts):
        t += dt
        limiter.command(v_x, w, t)
        out.append(limiter.update(t))
    return np.array(out)


@given(icr_models(),
       st.lists(st.tuples(speeds, speeds), min_size=1, max_size=30),
       st.lists(st.floats(0.001, 0.1), min_size=30, max_size=30),
       limits_or_inf, limits_or_inf, limits_or_inf, limits_or_inf, limits_or_inf,
       limits_or_inf)
def test_limiter_never_exceeds_limits(icr, commands, dts, max_speed, max_accel, max_v, max_a,
                                      max_w, max_alpha):
    limits = CommandLimits(max_speed, max_accel, max_v, max_a, max_w, max_alpha)
    limiter = CommandLimiter(icr, limits, timeout=10.0)
    out = run_limiter(limiter, commands, dts)
    prev = np.zeros(2)
    twist_prev = np.zeros(2)
    for (left, right), dt in zip(out, dts):
        twist = np.array(twist_of(left, right, icr))
        assert max(abs(left), abs(right)) <= max_speed * (1 + EPS) + EPS
        assert abs(twist[0]) <= max_v * (1 + EPS) + EPS
        assert abs(twist[1]) <= max_w * (1 + EPS) + EPS
        assert np.max(np.abs([left, right] - prev)) <= max_accel * dt * (1 + EPS) + EPS
        d_twist = np.abs(twist - twist_prev)
        assert d_twist[0] <= max_a * dt * (1 + EPS) + 1e-9
        assert d_twist[1] <= max_alpha * dt * (1 + EPS) + 1e-9
        prev, twist_prev = np.array([left, right]), twist


@given(icr_models(), speeds, speeds, st.floats(0.5, 5.0), st.floats(0.5, 5.0),
       st.floats(0.5, 5.0), st.floats(0.005, 0.05))
def test_ramp_from_rest_is_monotone_keeps_curvature_and_arrives(icr, v_x, w, max_accel,
                                                                max_a, max_alpha, dt):
    assume(abs(v_x) + abs(w) > 1e-3)
    limits = CommandLimits(max_track_accel=max_accel, max_linear_acceleration=max_a,
                           max_angular_acceleration=max_alpha)
    limiter = CommandLimiter(icr, limits, timeout=100.0)
    target = np.array(track_setpoints(v_x, w, icr), dtype=float)
    # Along a straight line the slowest limit sets the pace: the ramp lasts the longest of
    # distance / rate limit over the three limits.
    duration = max(np.max(np.abs(target)) / max_accel, abs(v_x) / max_a, abs(w) / max_alpha)
    n = math.ceil(duration / dt) + 2
    out = run_limiter(limiter, [(v_x, w)] * n, [dt] * n)
    # Every step is a non-negative fraction of the way to the target, side by side ...
    steps = np.diff(np.vstack([[0.0, 0.0], out]), axis=0) * np.sign(target)
    assert np.all(steps >= -1e-12)
    # ... on the line from rest to the target: the curvature is the commanded one ...
    np.testing.assert_allclose(out[:, 0] * target[1] - out[:, 1] * target[0], 0.0, atol=1e-9)
    # ... and the target is reached exactly.
    assert tuple(out[-1]) == tuple(target)


def test_ramp_duration_golden():
    # 1 m/s straight ahead from rest at 2 m/s^2, 10 ms steps: 0.02 m/s per step, 50 steps.
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(max_track_accel=2.0))
    out = run_limiter(limiter, [(1.0, 0.0)] * 60, [0.01] * 60)
    np.testing.assert_allclose(out[:50, 0], 0.02 * np.arange(1, 51))
    assert np.all(out[49:] == 1.0)


@given(icr_models(), speeds, speeds, limits_or_inf, limits_or_inf)
def test_zero_command_gives_zero_setpoints(icr, v_x, w, max_accel, max_speed):
    limiter = CommandLimiter(icr, CommandLimits(max_track_speed=max_speed,
                                                max_track_accel=max_accel), timeout=1e6)
    run_limiter(limiter, [(v_x, w)] * 5, [0.01] * 5)
    limiter.command(0.0, 0.0, 0.06)
    # Long enough for any ramp drawn here (setpoints below 20 m/s, accel above 0.05 m/s^2).
    assert limiter.update(1000.0) == (0.0, 0.0)
    assert limiter.update(1000.01) == (0.0, 0.0)


def test_timeout_stops_at_once_without_ramp():
    limiter = CommandLimiter(AURIGA, timeout=0.5)
    limiter.update(0.0)
    limiter.command(0.4, 0.2, 0.0)
    assert limiter.update(0.5) == pytest.approx(track_setpoints(0.4, 0.2, AURIGA))
    assert not limiter.is_stale(0.5) and limiter.is_stale(0.51)
    assert limiter.update(0.51) == (0.0, 0.0)


def test_timeout_ramps_to_zero_at_the_acceleration_limit():
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(max_track_accel=1.0),
                             timeout=0.2)
    limiter.update(0.0)
    limiter.command(0.5, 0.0, 0.0)
    times = np.arange(1, 121) * 0.01
    out = np.array([limiter.update(t) for t in times])
    # The ramp up (1 m/s^2) would take 0.5 s, but the command goes stale after 0.2 s: the
    # speed peaks at 0.2 m/s, then falls at 1 m/s^2 to zero by 0.4 s, and stays there.
    peak = int(np.argmax(out[:, 0]))
    assert times[peak] == pytest.approx(0.2) and out[peak, 0] == pytest.approx(0.2)
    assert np.all(np.diff(out[peak:, 0]) <= 0.0)
    assert np.all(np.abs(np.diff(out[:, 0])) <= 0.01 + 1e-12)
    assert np.all(out[times >= 0.4 + 1e-9] == 0.0)


def test_non_finite_command_refused_and_old_one_kept():
    limiter = CommandLimiter(AURIGA)
    limiter.command(0.3, 0.0, 0.0)
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(ValueError, match='non-finite'):
            limiter.command(bad, 0.0, 0.1)
        with pytest.raises(ValueError, match='non-finite'):
            limiter.command(0.0, bad, 0.1)
    assert limiter.update(0.2) == pytest.approx(track_setpoints(0.3, 0.0, AURIGA))
    # The refused commands did not refresh the timeout either.
    assert limiter.is_stale(0.51)


def test_stall_does_not_make_a_jump():
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(max_track_accel=1.0))
    limiter.update(0.0)
    limiter.command(1.0, 0.0, 0.0)
    limiter.command(1.0, 0.0, 0.3)
    left, _ = limiter.update(0.3, max_dt=0.04)  # 0.3 s late: ramps as over 0.04 s only
    assert left == pytest.approx(0.04)


def test_clock_going_backwards_holds_setpoints():
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(max_track_accel=1.0),
                             timeout=100.0)
    limiter.update(10.0)
    limiter.command(1.0, 0.0, 10.0)
    first = limiter.update(10.1)
    assert limiter.update(5.0) == first          # no negative interval, no motion
    assert limiter.update(5.1)[0] == pytest.approx(first[0] + 0.1)


def test_runtime_change_of_model_ramps_from_last_setpoints():
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(max_track_accel=1.0))
    limiter.update(0.0)
    limiter.command(0.0, 0.0, 0.0)
    limiter.update(0.1)
    limiter.icr = AURIGA
    limiter.limits = CommandLimits(max_track_accel=2.0)
    limiter.command(1.0, 0.0, 0.1)
    left, right = limiter.update(0.2)
    assert max(abs(left), abs(right)) == pytest.approx(0.2)


def test_reset_forgets_everything():
    limiter = CommandLimiter(AURIGA)
    limiter.command(0.3, 0.1, 0.0)
    limiter.update(0.0)
    limiter.reset()
    assert limiter.setpoints == (0.0, 0.0) and limiter.update(0.1) == (0.0, 0.0)


# The vehicle envelope, decelerations, the output guard (issues 14 and 15) ----------------

# Finite doubles of every kind a sender can put in a Twist: huge, tiny, subnormal, zero.
any_finite = st.floats(allow_nan=False, allow_infinity=False)
extreme = st.sampled_from([1.7976931348623157e308, -1.7976931348623157e308, 5e-324,
                           -5e-324, 1e-300, 1e300, 0.0, -0.0])
commands = st.one_of(any_finite, extreme)


@given(icr_models(), commands, commands, st.one_of(st.just(TRACK_SPEED_ENVELOPE),
                                                   st.floats(0.05, 5.0)))
def test_envelope_setpoints_finite_bounded_and_on_the_commanded_arc(icr, v_x, w, max_speed):
    left, right = envelope_setpoints(v_x, w, icr, max_speed)
    left, right = float(left), float(right)
    assert math.isfinite(left) and math.isfinite(right)
    assert max(abs(left), abs(right)) <= max_speed * (1 + EPS)
    # Same direction in setpoint space as the exact (overflow-free) setpoints of the command:
    # the curvature is kept. Compared on the command scaled down by a power of two (exact).
    scale = 2.0 ** -math.frexp(max(abs(v_x), abs(w), 1e-300))[1]
    exact_left, exact_right = (float(s) for s in track_setpoints(v_x * scale, w * scale, icr))
    norm = max(abs(exact_left), abs(exact_right))
    if norm > 1e-200 and max(abs(left), abs(right)) > 1e-200:
        assert left * exact_right - right * exact_left == pytest.approx(
            0.0, abs=1e-9 * norm * max(abs(left), abs(right)))
        assert left * exact_left + right * exact_right > 0.0


def test_envelope_setpoints_equal_the_plain_ones_within_the_envelope():
    left, right = envelope_setpoints([0.5, -2.0], [0.3, 1.0], AURIGA)
    exact = track_setpoints([0.5, -2.0], [0.3, 1.0], AURIGA)
    assert np.array_equal(left, exact[0]) and np.array_equal(right, exact[1])


def test_huge_twist_gives_the_envelope_golden():
    # 1.8e308 straight ahead on an ideal drive: both tracks at the 30 m/s envelope, not inf.
    left, right = envelope_setpoints(1.7976931348623157e308, 0.0, IcrParams.ideal(0.5))
    assert (float(left), float(right)) == (TRACK_SPEED_ENVELOPE, TRACK_SPEED_ENVELOPE)
    # The same on an arc of curvature 1/m: v_x = w; tracks v_x -+ 0.25 w in ratio 3:5.
    left, right = envelope_setpoints(1.7976931348623157e308, 1.7976931348623157e308,
                                     IcrParams.ideal(0.5))
    assert (float(left), float(right)) == pytest.approx((18.0, 30.0))


@pytest.mark.parametrize('limits', [
    CommandLimits(max_track_accel=2.0), CommandLimits(max_track_speed=1.0),
    CommandLimits(), CommandLimits(max_linear_acceleration=0.5, max_angular_acceleration=1.0),
], ids=['max_track_accel', 'max_track_speed', 'none', 'twist_accel'])
def test_huge_commands_never_latch_nan(limits):
    # Issue 14 item 1: two finite Twists of +-1.797e308 made inf setpoints, then 0 * inf = NaN
    # in the ramp, published forever.
    limiter = CommandLimiter(AURIGA, limits, timeout=0.5)
    big = 1.7976931348623157e308
    t, out = 0.0, []
    for k in range(200):
        t += 0.02
        if k < 2:
            limiter.command(big * (-1) ** k, big * (-1) ** k, t)
        out.append(limiter.update(t, max_dt=0.04))
    out = np.array(out)
    assert np.all(np.isfinite(out))
    assert np.max(np.abs(out)) <= min(limits.max_track_speed, TRACK_SPEED_ENVELOPE) * (1 + EPS)
    # Stale after 0.5 s: a stop reached (by 4 s at the slowest ramp here), not a latch.
    assert tuple(out[-1]) == (0.0, 0.0)
    for _ in range(100):
        t += 0.02
        limiter.command(0.3, 0.1, t)
        last = limiter.update(t, max_dt=0.04)
    assert last == pytest.approx(track_setpoints(0.3, 0.1, AURIGA))


@given(icr_models(), st.lists(st.tuples(commands, commands), min_size=1, max_size=20),
       limits_or_inf, limits_or_inf, limits_or_inf, limits_or_inf)
def test_limiter_output_always_finite_and_within_the_envelope(icr, cmds, max_speed,
                                                              max_accel, max_a, max_decel):
    limits = CommandLimits(max_speed, max_accel, max_linear_acceleration=max_a,
                           max_track_decel=max_decel)
    limiter = CommandLimiter(icr, limits, timeout=0.05)
    t = 0.0
    for v_x, w in cmds:
        t += 0.01
        limiter.command(v_x, w, t)
        left, right = limiter.update(t, max_dt=0.02)
        assert setpoint_problem(left, right, icr, limits) is None


def test_deceleration_limit_is_used_toward_zero_golden():
    # v_x up at 1 m/s^2, down at 4 m/s^2 (DDC's max_deceleration), 10 ms steps.
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(
        max_linear_acceleration=1.0, max_linear_deceleration=4.0), timeout=100.0)
    up = run_limiter(limiter, [(0.5, 0.0)] * 60, [0.01] * 60)
    np.testing.assert_allclose(up[:50, 0], 0.01 * np.arange(1, 51))
    t = 0.6
    limiter.command(0.0, 0.0, t)
    down = []
    for _ in range(20):
        t += 0.01
        down.append(limiter.update(t)[0])
    np.testing.assert_allclose(down[:12], 0.5 - 0.04 * np.arange(1, 13))
    assert down[12:] == [0.0] * 8
    # Reversing from +0.5 to -0.5 m/s: toward zero at 4, then away from it (reverse) at 1.
    limiter.command(0.5, 0.0, t)
    for _ in range(60):
        t += 0.01
        limiter.update(t)
    limiter.command(-0.5, 0.0, t)
    rev = []
    for _ in range(80):
        t += 0.01
        rev.append(limiter.update(t)[0])
    steps = -np.diff([0.5] + rev)
    assert steps[:12] == pytest.approx([0.04] * 12)  # decelerating from 0.5 to 0.02
    assert steps[12] == pytest.approx(0.04)  # from +0.02 through zero to -0.02
    assert np.all(steps[13:61] == pytest.approx(0.01))  # accelerating in reverse
    assert rev[-1] == -0.5


def test_unset_deceleration_is_the_acceleration_limit():
    limits = CommandLimits(max_track_accel=2.0, max_linear_acceleration=1.0)
    assert limits.max_track_decel == 2.0 and limits.max_linear_deceleration == 1.0
    assert limits.max_angular_deceleration == math.inf
    assert CommandLimits(max_track_accel=2.0, max_track_decel=math.inf).max_track_decel \
        == math.inf


def test_timeout_inf_never_goes_stale():
    limiter = CommandLimiter(AURIGA, timeout=math.inf)
    limiter.command(0.3, 0.0, 0.0)
    assert not limiter.is_stale(1e9)
    assert limiter.update(1e9) == pytest.approx(track_setpoints(0.3, 0.0, AURIGA))


def test_lower_velocity_limit_applies_at_once():
    # A velocity limit is never exceeded: lowered at runtime, the setpoints are scaled into
    # it at once (keeping the curvature), whatever the acceleration limits.
    limiter = CommandLimiter(IcrParams.ideal(0.5), timeout=100.0)
    limiter.command(1.0, 1.0, 0.0)
    assert limiter.update(0.0) == (0.75, 1.25)
    limiter.limits = CommandLimits(max_track_speed=0.5, max_track_accel=0.01)
    assert limiter.setpoints == pytest.approx((0.3, 0.5))
    limiter.limits = CommandLimits(max_linear_velocity=0.2, max_track_accel=0.01)
    assert twist_of(*limiter.setpoints, IcrParams.ideal(0.5)) == pytest.approx((0.2, 0.2))


def test_setpoint_problem_names_what_is_wrong():
    ideal, none = IcrParams.ideal(0.5), CommandLimits()
    assert setpoint_problem(0.5, 0.6, ideal, none) is None
    assert 'non-finite' in setpoint_problem(math.nan, 0.0, ideal, none)
    assert 'non-finite' in setpoint_problem(0.0, math.inf, ideal, none)
    assert 'vehicle envelope 30' in setpoint_problem(31.0, 0.0, ideal, none)
    assert 'max_track_speed 1' in setpoint_problem(
        1.5, 0.0, ideal, CommandLimits(max_track_speed=1.0))
    assert 'linear velocity limit' in setpoint_problem(
        1.0, 1.0, ideal, CommandLimits(max_linear_velocity=0.5))
    assert 'angular velocity limit' in setpoint_problem(
        -1.0, 1.0, ideal, CommandLimits(max_angular_velocity=1.0))
    assert setpoint_problem(1.0 + 1e-12, 0.0, ideal, CommandLimits(max_track_speed=1.0)) is None


def test_exceeds_envelope():
    assert not exceeds_envelope(1.0, 1.0, AURIGA)
    assert exceeds_envelope(31.0, 0.0, IcrParams.ideal(0.5))
    assert exceeds_envelope(1.7976931348623157e308, -1.7976931348623157e308, AURIGA)
    assert exceeds_envelope(0.0, 1e300, AURIGA)


def test_setpoint_twist_matches_forward_kinematics():
    v_x, w = setpoint_twist(0.4, 0.7, AURIGA)
    assert (v_x, w) == pytest.approx(twist_of(0.4, 0.7, AURIGA), abs=1e-15)


def test_force_stop_keeps_the_command():
    limiter = CommandLimiter(AURIGA, timeout=100.0)
    limiter.command(0.3, 0.0, 0.0)
    limiter.update(0.0)
    limiter.force_stop()
    assert limiter.setpoints == (0.0, 0.0)
    assert limiter.update(0.01) == pytest.approx(track_setpoints(0.3, 0.0, AURIGA))


def test_stale_on_either_clock_stays_stale_and_stop_ramps_on_the_given_dt():
    """Issue 27: a rewound clock cannot revive a stale command; a fault ramps on its own dt."""
    limiter = CommandLimiter(IcrParams.ideal(0.5), CommandLimits(max_track_accel=1.0),
                             timeout=0.5, steady_timeout=2.0)
    limiter.command(0.4, 0.0, t=10.0, steady=100.0)
    limiter.update(10.0, steady=100.0)
    assert limiter.update(10.5, steady=100.5) == pytest.approx((0.4, 0.4))
    assert limiter.is_stale(10.1, steady=102.1)  # the steady clock alone: stale
    assert limiter.update(11.0, max_dt=0.1, steady=101.0) == pytest.approx((0.3, 0.3))
    assert limiter.is_stale(10.1, steady=101.0)  # latched: the rewound clock does not revive
    limiter.command(0.4, 0.0, t=10.2, steady=101.1)  # a new command does
    assert not limiter.is_stale(10.3, steady=101.2)
    assert limiter.stop(0.1) == pytest.approx((0.2, 0.2))  # 0.1 s at 1 m/s^2
    assert limiter.is_stale(10.3, steady=101.2)
