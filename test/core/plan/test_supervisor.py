"""The calibration drive's protocol and safety supervisor (issue 22): each rule on its own."""

import math

from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from tracked_kinematics.core.plan.calibration_protocol import (
    ARC_YAW_FRACTIONS, fence_exit, FenceOdometry, predict_step, protocol, Step, total_duration)
from tracked_kinematics.core.plan.supervisor import (
    cap, Inputs, pose_jump, STATES, Supervisor, SupervisorConfig)

CFG = SupervisorConfig(geofence_radius=3.0, max_speed=0.5, max_yaw_rate=1.0)


# The protocol ------------------------------------------------------------------------


def test_default_protocol_is_three_minutes_of_every_manoeuvre():
    steps = protocol()
    assert total_duration(steps) == pytest.approx(180.0, rel=0.02)
    kinds = {s.kind for s in steps}
    assert kinds == {'straight', 'arc', 'turn'}
    # Straights both ways at several speeds.
    straights = [s for s in steps if s.kind == 'straight']
    assert {np.sign(s.v) for s in straights} == {1.0, -1.0}
    assert len({abs(s.v) for s in straights}) == 3
    # Arcs of several radii, both ways.
    arcs = [s for s in steps if s.kind == 'arc']
    assert {np.sign(s.w) for s in arcs} == {1.0, -1.0}
    assert len({round(abs(s.v / s.w), 3) for s in arcs}) >= 3 * len(ARC_YAW_FRACTIONS) - 1
    # Turns in place both ways.
    turns = [s for s in steps if s.kind == 'turn']
    assert all(s.v == 0.0 for s in turns) and {np.sign(s.w) for s in turns} == {1.0, -1.0}
    # Roughly a third of the time straight or turning in place, the rest curves.
    assert 0.25 < sum(s.duration for s in arcs) / 180.0 < 0.75


@pytest.mark.parametrize('duration', [15.0, 30.0, 60.0, 100.0, 180.0, 600.0])
def test_protocol_duration_and_caps(duration):
    steps = protocol(duration, max_speed=0.8, max_yaw_rate=0.6, geofence_radius=2.0)
    assert total_duration(steps) == pytest.approx(duration, rel=0.25)
    assert all(abs(s.v) <= 0.8 + 1e-12 and abs(s.w) <= 0.6 + 1e-12 for s in steps)
    # How far it goes from the start: test_calibration.py.


@pytest.mark.parametrize('kwargs', [{'duration': 10.0}, {'duration': math.nan},
                                    {'max_speed': 0.0}, {'max_yaw_rate': -1.0},
                                    {'geofence_radius': math.inf}])
def test_protocol_refuses_bad_arguments(kwargs):
    with pytest.raises(ValueError):
        protocol(**kwargs)


def test_step_refuses_non_finite():
    with pytest.raises(ValueError):
        Step(math.nan, 0.0, 1.0, 'straight')
    with pytest.raises(ValueError):
        Step(0.1, 0.0, 0.0, 'straight')


def test_predicted_arc_is_exact():
    # A full circle of radius 1 returns to its start; a half circle ends 2 m to the left.
    x, y, yaw = predict_step((1.0, 2.0, 0.5), 0.5, 0.5, 2 * math.pi / 0.5)
    assert (x[-1], y[-1]) == pytest.approx((1.0, 2.0), abs=1e-9)
    x, y, _ = predict_step((0.0, 0.0, 0.0), 0.5, 0.5, math.pi / 0.5)
    assert (x[-1], y[-1]) == pytest.approx((0.0, 2.0), abs=1e-9)
    x, y, _ = predict_step((0.0, 0.0, math.pi / 2), 0.4, 0.0, 2.0)
    assert (x[-1], y[-1]) == pytest.approx((0.0, 0.8), abs=1e-12)


def test_fence_exit_time():
    step = Step(0.5, 0.0, 10.0, 'straight')
    # From the centre heading +x, the 2-m circle is left after 4 s.
    assert fence_exit((0.0, 0.0, 0.0), step, (0.0, 0.0), 2.0) == pytest.approx(4.0, abs=0.21)
    assert fence_exit((0.0, 0.0, 0.0), step, (0.0, 0.0), 6.0) is None
    assert fence_exit((0.0, 0.0, math.nan), step, (0.0, 0.0), 6.0) == 0.0


# The supervisor: a helper that drives it like the node does --------------------------


class Bench:
    """Feeds the supervisor fresh sensors and moves an ideal (or slipping) vehicle."""

    def __init__(self, steps=None, config=CFG, turn_gain=1.0, dt=0.05, encoders=True):
        self.sup = Supervisor(steps or protocol(60.0), config)
        self.travel = [0.0, 0.0] if encoders else None
        self.travel_t = None      # the stamp of the encoders' latest sample (None: now)
        self.frozen = set()       # 'encoders', 'pose', 'yaw': what reports no change
        self.reported = [0.0, 0.0, 0.0]
        self.lateness = 0.0
        self.fault = ''
        self.t = 0.0
        self.pose = [0.0, 0.0, 0.0]
        self.deadman = True
        self.deadman_t = 0.0
        self.encoder_t = 0.0
        self.reference_t = 0.0
        self.dt = dt
        self.turn_gain = turn_gain
        self.max_distance = 0.0
        self.outputs = []
        self.rtf = None           # simulated time this many times faster than the steady clock

    def inputs(self):
        if 'pose' not in self.frozen:
            self.reported[:2] = self.pose[:2]
        if 'pose' not in self.frozen and 'yaw' not in self.frozen:
            self.reported[2] = self.pose[2]
        steady = {} if self.rtf is None else {
            'steady': self.t / self.rtf, 'deadman_steady': self.deadman_t / self.rtf,
            'encoder_steady': self.encoder_t / self.rtf,
            'reference_steady': self.reference_t / self.rtf}
        return Inputs(self.t, self.deadman, self.deadman_t, self.encoder_t, self.reference_t,
                      tuple(self.reported),
                      travel=None if self.travel is None else tuple(self.travel),
                      travel_t=self.travel_t, lateness=self.lateness, fault=self.fault, **steady)

    def tick(self, hold=True, sensors=True):
        if hold:
            self.deadman_t = self.t
        if sensors:
            self.encoder_t = self.reference_t = self.t
        out = self.sup.update(self.inputs())
        self.outputs.append(out)
        # Move the vehicle by the command (a slipping one turns turn_gain as fast).
        v, w = out.v, self.turn_gain * out.w
        if self.travel is not None and 'encoders' not in self.frozen:
            half = 0.5 * self.sup.config.track_width
            self.travel[0] += (out.v - half * out.w) * self.dt
            self.travel[1] += (out.v + half * out.w) * self.dt
        x, y, yaw = predict_step(self.pose, v, w, self.dt, 1)
        self.pose = [float(x[0]), float(y[0]), float(yaw[0])]
        self.t += self.dt
        self.max_distance = max(self.max_distance, math.hypot(*self.pose[:2]))
        return out

    def run(self, seconds, **kwargs):
        for _ in range(int(round(seconds / self.dt))):
            out = self.tick(**kwargs)
        return out

    def start(self):
        return self.sup.start(self.inputs())


def test_idle_until_start_then_runs_the_protocol_to_the_end():
    bench = Bench()
    assert bench.run(1.0).state == 'idle' and not bench.outputs[-1].moving
    ok, _ = bench.start()
    assert ok
    out = bench.tick()
    assert out.state == 'running' and out.moving
    out = bench.run(200.0)
    assert out.state == 'finished' and not out.moving
    assert bench.sup.start(bench.inputs())[0] is False


def test_auto_start_waits_for_the_deadman():
    bench = Bench(config=SupervisorConfig(auto_start=True))
    bench.deadman = False
    assert bench.run(1.0).state == 'idle'
    bench.deadman = True
    # A press counts once it comes rearm_time (0.1 s) after the last release message.
    assert [bench.tick().state for _ in range(4)] == ['idle', 'idle', 'running', 'running']


def test_deadman_release_zeroes_at_once_and_the_step_restarts():
    bench = Bench(steps=[Step(0.3, 0.0, 4.0, 'straight'), Step(0.0, 0.5, 2.0, 'turn')])
    bench.start()
    bench.run(2.0)
    assert bench.outputs[-1].step_elapsed == pytest.approx(1.95, abs=0.06)
    bench.deadman = False
    out = bench.tick(hold=True)   # a False message, fresh: released
    assert (out.v, out.w) == (0.0, 0.0) and out.state == 'paused'
    assert out.reason == 'deadman released'
    bench.run(1.0)
    bench.deadman = True
    # A press counts once it comes rearm_time (0.1 s) after the last release message.
    outs = [bench.tick() for _ in range(4)]
    assert [o.moving for o in outs] == [False, False, True, True]
    out = outs[2]
    # Resumed: the same step, from its beginning.
    assert out.state == 'running' and out.step == 0 and out.step_elapsed == 0.0
    assert out.v == pytest.approx(0.3)


def test_stale_deadman_zeroes_after_its_timeout():
    bench = Bench(steps=[Step(0.3, 0.0, 10.0, 'straight')])
    bench.start()
    bench.run(1.0)
    last_held = bench.deadman_t
    t_zero = None
    for _ in range(40):
        out = bench.tick(hold=False)     # still True, but no new message
        if not out.moving:
            t_zero = bench.t - bench.dt
            break
    assert t_zero is not None and out.state == 'paused'
    assert 'not held within 0.3 s' in out.reason
    assert t_zero - last_held == pytest.approx(0.3, abs=bench.dt + 1e-9)


def test_stale_encoders_stop_and_start_resumes_when_fresh():
    bench = Bench(steps=[Step(0.3, 0.0, 10.0, 'straight')])
    bench.start()
    bench.run(1.0)
    for _ in range(20):
        out = bench.sup.update(Inputs(bench.t, True, bench.t, bench.t - 0.6, bench.t,
                                      tuple(bench.pose)))
        bench.t += bench.dt
    assert out.state == 'stopped' and not out.moving and 'encoders stale' in out.reason
    ok, message = bench.sup.start(Inputs(bench.t, True, bench.t, bench.t - 0.6, bench.t,
                                         tuple(bench.pose)))
    assert not ok and 'encoders stale' in message
    bench.encoder_t = bench.reference_t = bench.deadman_t = bench.t
    ok, _ = bench.start()
    assert ok
    out = bench.tick()
    assert out.state == 'running' and out.moving


@pytest.mark.parametrize('pose', [None, (math.nan, 0.0, 0.0), (0.0, 0.0, math.inf)])
def test_stale_reference_stops(pose):
    bench = Bench(steps=[Step(0.3, 0.0, 10.0, 'straight')])
    bench.start()
    bench.run(1.0)
    out = bench.sup.update(Inputs(bench.t, True, bench.t, bench.t, bench.t - 1.0,
                                  tuple(bench.pose)))
    assert out.state == 'stopped' and 'reference stale' in out.reason and not out.moving
    bench2 = Bench(steps=[Step(0.3, 0.0, 10.0, 'straight')])
    bench2.start()
    out = bench2.sup.update(Inputs(0.0, True, 0.0, 0.0, 0.0, pose))
    assert out.state == 'stopped' and not out.moving


def test_stop_service_mid_step_is_final():
    bench = Bench(steps=[Step(0.3, 0.2, 10.0, 'arc')])
    bench.start()
    assert bench.run(2.0).moving
    ok, _ = bench.sup.stop(bench.inputs())
    assert ok
    out = bench.tick()
    assert out.state == 'stopped' and out.reason == 'stopped by ~/stop' and not out.moving
    assert not bench.start()[0]
    assert not bench.run(2.0).moving


def test_pause_service_and_resume():
    bench = Bench(steps=[Step(0.3, 0.0, 10.0, 'straight')])
    bench.start()
    bench.run(2.0)
    assert bench.sup.pause(bench.inputs())[0]
    out = bench.run(1.0)
    assert out.state == 'paused' and not out.moving and out.reason == 'paused by ~/pause'
    assert bench.start()[0]
    out = bench.tick()
    assert out.state == 'running' and out.step_elapsed == 0.0 and out.moving


def test_a_step_that_would_leave_the_geofence_is_preceded_by_a_return():
    # The vehicle starts at the centre, drives 2 m out, then is told to drive 2 m further.
    steps = [Step(0.5, 0.0, 4.0, 'straight'), Step(0.5, 0.0, 4.0, 'straight')]
    bench = Bench(steps=steps)
    bench.start()
    out = bench.tick()
    while out.state == 'running' and out.step == 0:
        out = bench.tick()
    assert bench.t == pytest.approx(4.05, abs=0.06)
    assert out.state == 'returning' and 'would leave' in out.reason
    # It turns in place towards the centre first, then drives back.
    assert out.v == 0.0 and out.w != 0.0
    states = [bench.tick().state for _ in range(400)]
    assert 'running' in states
    assert bench.max_distance <= 0.85 * 3.0 + 0.05


def test_geofence_pushes_back_a_vehicle_that_slips():
    # An uncalibrated vehicle turns at half the commanded rate: its arcs are twice as wide as
    # planned (circles of 2.5 m that fit the plan, of 5 m driven). The guard turns it back; it
    # never leaves the fence.
    bench = Bench(steps=[Step(0.5, 0.4, 15.0, 'arc'), Step(0.5, -0.4, 15.0, 'arc')],
                  turn_gain=0.5)
    bench.start()
    bench.run(100.0)
    assert bench.outputs[-1].state == 'finished'
    assert any(o.state == 'returning' for o in bench.outputs)
    assert bench.max_distance <= 3.0


def test_a_step_too_long_even_from_the_centre_is_cut():
    bench = Bench(steps=[Step(0.5, 0.0, 20.0, 'straight')])
    bench.start()
    out = bench.tick()
    assert out.state == 'running'
    assert bench.sup._d.step.duration < 0.85 * 3.0 / 0.5 + 1e-9
    bench.run(30.0)
    assert bench.outputs[-1].state == 'finished'
    assert bench.max_distance <= 0.85 * 3.0 + 0.05


def test_return_that_never_arrives_stops():
    cfg = SupervisorConfig(return_timeout=5.0)
    # The vehicle cannot turn at all (and no encoders: the cross-checks would stop it).
    bench = Bench(steps=[Step(0.5, 0.0, 4.0, 'straight'), Step(0.5, 0.0, 4.0, 'straight')],
                  config=cfg, turn_gain=0.0, encoders=False)
    bench.start()
    out = bench.run(20.0)
    assert out.state == 'stopped' and 'return' in out.reason and not out.moving


def test_caps_scale_both_components():
    assert cap(1.0, 0.5, 0.5, 1.0) == (0.5, 0.25)
    assert cap(0.2, 3.0, 0.5, 1.0) == pytest.approx((0.2 / 3.0, 1.0))
    assert cap(math.nan, 0.1, 0.5, 1.0) == (0.0, 0.0)
    bench = Bench(steps=[Step(2.0, 4.0, 2.0, 'arc')])
    bench.start()
    out = bench.tick()
    assert abs(out.v) <= 0.5 and abs(out.w) <= 1.0 and out.v / out.w == pytest.approx(0.5)


def test_config_refuses_bad_values():
    # max_speed, geofence_radius, ... are checked where they enter: calibration_drive's
    # parameters (test/ros/test_calibration_drive.py).
    with pytest.raises(ValueError, match='return_timeout must be > 0, got 0'):
        SupervisorConfig(return_timeout=0)
    with pytest.raises(ValueError):
        SupervisorConfig(inner_fraction=0.9)
    with pytest.raises(ValueError):
        Supervisor([])


# Sensors that lie by standing still, faults, the deadman latch, a late loop (issue 27) --


def _stopped_within(bench, seconds):
    for _ in range(int(round(seconds / bench.dt))):
        out = bench.tick()
        if out.state == 'stopped':
            return out
    return None


@pytest.mark.parametrize('step', [Step(0.4, 0.0, 30.0, 'straight'),
                                  Step(0.0, 0.8, 30.0, 'turn'), Step(0.3, 0.5, 30.0, 'arc')])
def test_frozen_encoders_stop_the_drive(step):
    bench = Bench(steps=[step])
    bench.start()
    assert bench.run(3.0).state == 'running'
    bench.frozen.add('encoders')
    out = _stopped_within(bench, 2.0)
    assert out is not None and not out.moving
    assert out.reason.startswith('encoders do not follow the command')


@pytest.mark.parametrize('step', [Step(0.4, 0.0, 30.0, 'straight'),
                                  Step(0.3, 0.8, 30.0, 'arc')])
def test_frozen_pose_stops_the_drive(step):
    bench = Bench(steps=[step])
    bench.start()
    assert bench.run(3.0).state == 'running'
    bench.frozen.add('pose')
    out = _stopped_within(bench, 2.0)
    assert out is not None and out.reason.startswith('pose reference does not follow')


def test_stuck_gyro_stops_a_turn():
    cfg = SupervisorConfig(reference='imu')
    bench = Bench(steps=[Step(0.2, 0.8, 30.0, 'arc')], config=cfg)
    bench.start()
    assert bench.run(3.0).state == 'running'
    bench.frozen.add('yaw')
    out = _stopped_within(bench, 2.0)
    assert out is not None and out.reason.startswith('gyro does not follow')


def test_a_reversal_through_a_lagging_drive_train_is_not_a_frozen_sensor():
    # Straights each followed by its reverse (the protocol's pairs); tracks that follow the
    # command through a first-order lag of 0.3 s, the vehicle moving with them, and the
    # encoders reported 0.3 s late (a loaded machine): across a reversal the encoders
    # travel a fraction of the command, and the pose and the encoders reverse at different
    # instants.
    steps = [Step(sign * 0.5, 0.0, 1.5, 'straight') for sign in (1, -1, 1, -1, 1, -1)]
    bench = Bench(steps=steps)
    bench.frozen.add('encoders')      # the test moves the vehicle and the encoders itself
    speed, delayed = 0.0, []
    bench.start()
    for _ in range(int(10.0 / bench.dt)):
        out = bench.sup.update(bench.inputs())
        assert out.state in ('running', 'finished'), out.reason
        if out.state == 'finished':
            break
        speed += (out.v - speed) * bench.dt / 0.3
        bench.pose[0] += speed * bench.dt
        delayed.append(speed)
        if len(delayed) > int(0.3 / bench.dt):
            late = delayed.pop(0)
            bench.travel[0] += late * bench.dt
            bench.travel[1] += late * bench.dt
        bench.t += bench.dt
        bench.deadman_t = bench.encoder_t = bench.reference_t = bench.t
    assert out.state == 'finished'


@pytest.mark.parametrize('frozen', [False, True])
def test_encoders_delivered_late_are_judged_by_their_stamps(frozen):
    # A loaded machine delivers the encoder samples 0.8 s late (honest stamps): the command
    # is compared over the window their stamps cover. Frozen data with fresh stamps still
    # travels nothing and stops the drive.
    bench = Bench(steps=[Step(0.4, 0.0, 30.0, 'straight'), Step(0.0, 0.8, 30.0, 'turn')])
    bench.frozen.add('encoders')
    samples = []
    bench.start()
    for k in range(int(12.0 / bench.dt)):
        out = bench.sup.update(bench.inputs())
        half = 0.5 * bench.sup.config.track_width
        last = samples[-1][1] if samples else (0.0, 0.0)
        moved = not (frozen and bench.t > 5.0)
        samples.append((bench.t, (last[0] + moved * (out.v - half * out.w) * bench.dt,
                                  last[1] + moved * (out.v + half * out.w) * bench.dt)))
        while samples[0][0] <= bench.t - 0.8:    # what has arrived by now
            bench.travel_t, bench.travel[:] = samples.pop(0)
        if frozen and bench.t > 5.0:
            bench.travel_t = bench.t - 0.8        # fresh stamps on frozen values
        x, y, yaw = predict_step(bench.pose, out.v, out.w, bench.dt, 1)
        bench.pose = [float(x[0]), float(y[0]), float(yaw[0])]
        bench.t += bench.dt
        bench.deadman_t = bench.encoder_t = bench.reference_t = bench.t
        if out.state != 'running':
            break
    if frozen:
        assert out.state == 'stopped' and 5.0 < bench.t < 8.0, (bench.t, out.reason)
        assert out.reason.startswith('encoders do not follow the command')
    else:
        assert out.state == 'running', out.reason


def frozen_at_start(comes_up_after, rtf=None, until=8.0):
    """Drive with encoders frozen until ``comes_up_after`` (s simulated); the last output, t."""
    bench = Bench(steps=[Step(0.0, 1.0, 60.0, 'turn')])
    bench.rtf = rtf
    bench.frozen.add('encoders')
    bench.start()
    while bench.t < until:
        if bench.t >= comes_up_after:
            bench.frozen.discard('encoders')
        out = bench.tick()
        if out.state != 'running':
            break
    return out, bench.t


@pytest.mark.parametrize('comes_up_after', [2.0, math.inf])
def test_a_command_path_that_comes_up_late_has_a_grace(comes_up_after):
    # At start the tracks may not move for a while (cmd_vel_translator discovered late, its
    # /clock not yet received): start_grace (3 s) before the encoders are judged; a path
    # that never comes up stops the drive, and the reason says where to look.
    out, t = frozen_at_start(comes_up_after)
    if math.isinf(comes_up_after):
        assert out.state == 'stopped' and 3.5 < t < 5.0, (t, out.reason)
        assert 'the tracks have not moved since the start' in out.reason
    else:
        assert out.state == 'running', out.reason


@pytest.mark.parametrize('comes_up_after', [2.0 * 3.0, math.inf])
def test_the_grace_is_wall_time_in_a_simulation_faster_than_real(comes_up_after):
    # At three times real time, 3 s of simulated time are 1 s of wall time: too short for
    # processes to discover each other on a loaded machine (the page's walk stopped so at
    # its start). The grace runs on both clocks: 2 s of wall time (6 s simulated) is within it.
    out, t = frozen_at_start(comes_up_after, rtf=3.0, until=30.0)
    if math.isinf(comes_up_after):
        # After the grace of wall time (4 s: the window and the grace), 12 s simulated.
        assert out.state == 'stopped' and 12.0 <= t < 14.0, (t, out.reason)
        assert 'the tracks have not moved since the start' in out.reason
    else:
        assert out.state == 'running', out.reason


def test_heavy_slip_is_not_a_frozen_sensor():
    # On ice the vehicle turns at 0.3 of the commanded rate (effective track width 3.3x):
    # the reference still follows the encoders well enough; the drive finishes.
    bench = Bench(steps=protocol(60.0), turn_gain=0.3)
    bench.start()
    bench.run(200.0)
    assert bench.outputs[-1].state == 'finished', bench.sup.events[-3:]
    assert bench.max_distance <= 3.0


def test_a_fault_of_the_node_stops_and_blocks_start():
    bench = Bench(steps=[Step(0.3, 0.0, 30.0, 'straight')])
    bench.fault = '2 publishers on /deadman'
    ok, message = bench.start()
    assert not ok and '2 publishers' in message
    bench.fault = ''
    assert bench.start()[0] and bench.run(1.0).moving
    bench.fault = 'implausible gyro'
    out = bench.tick()
    assert out.state == 'stopped' and out.reason == 'implausible gyro' and not out.moving
    assert not bench.start()[0]
    bench.fault = ''
    assert bench.start()[0] and bench.run(0.5).moving


def test_stale_deadman_is_latched_until_released_and_pressed_again():
    bench = Bench(steps=[Step(0.3, 0.0, 30.0, 'straight')])
    bench.start()
    assert bench.run(1.0).moving
    assert not bench.run(1.0, hold=False).moving          # stale
    # Fresh "true" messages again (a link that recovers, late deliveries): still zero.
    out = bench.run(1.0)
    assert not out.moving and 'press it again' in out.reason
    bench.deadman = False
    assert not bench.run(0.3).moving                      # let go ...
    bench.deadman = True
    assert bench.run(0.3).moving                          # ... and pressed again


def test_two_deadman_publishers_that_disagree_never_move():
    bench = Bench(steps=[Step(0.3, 0.0, 30.0, 'straight')], dt=0.025)
    bench.start()
    bench.deadman = False
    bench.run(0.5)
    moving = []
    for k in range(200):                 # true and false alternating every 25 ms
        bench.deadman = k % 2 == 0
        moving.append(bench.tick().moving)
    assert not any(moving)


def test_deadman_age_on_the_steady_clock():
    # The ROS clock stands still; the steady clock runs: the deadman goes stale on it.
    sup = Supervisor([Step(0.3, 0.0, 30.0, 'straight')])
    pose = (0.0, 0.0, 0.0)
    inputs = Inputs(5.0, True, 5.0, 5.0, 5.0, pose, steady=100.0, deadman_steady=100.0,
                    encoder_steady=100.0, reference_steady=100.0)
    assert sup.start(inputs)[0] and sup.update(inputs).moving
    out = sup.update(Inputs(5.0, True, 5.0, 5.0, 5.0, pose, steady=100.5,
                            deadman_steady=100.0, encoder_steady=100.5,
                            reference_steady=100.5))
    assert not out.moving and 'deadman not held' in out.reason


@pytest.mark.parametrize('ros_age, steady_age, stale', [
    (1.0, 0.05, False),     # a simulation faster than real time
    (0.05, 1.0, False),     # slower than real time
    (1.0, 1.0, True)])
def test_sensors_are_stale_only_when_old_on_both_clocks(ros_age, steady_age, stale):
    sup = Supervisor([Step(0.3, 0.0, 30.0, 'straight')])
    pose = (0.0, 0.0, 0.0)
    assert sup.start(Inputs(10.0, True, 10.0, 10.0, 10.0, pose))[0]
    out = sup.update(Inputs(10.0, True, 10.0, 10.0 - ros_age, 10.0, pose, steady=50.0,
                            deadman_steady=50.0, encoder_steady=50.0 - steady_age,
                            reference_steady=50.0))
    assert (out.state == 'stopped') == stale and out.moving != stale
    assert not stale or 'encoders stale' in out.reason


def test_a_late_loop_slows_down_and_turns_back_earlier():
    margin = 0.5 * (1.0 - CFG.guard_fraction) * CFG.geofence_radius
    bench = Bench(steps=[Step(0.5, 0.0, 30.0, 'straight')])
    bench.start()
    assert bench.tick().v == pytest.approx(0.5)
    bench.lateness = 0.5
    out = bench.tick()
    assert out.v == pytest.approx(margin / (CFG.reaction_time + 0.5))
    bench.lateness = math.nan
    assert not bench.tick().moving
    # Late all along, the guard turns back before the stopping distance reaches the fence.
    bench = Bench(steps=[Step(0.5, 0.0, 30.0, 'straight')], dt=0.3)
    bench.lateness = 0.25
    bench.start()
    bench.run(20.0)
    assert bench.max_distance <= CFG.geofence_radius


def test_a_return_that_comes_no_closer_stops():
    # The pose says the vehicle stands at 2.7 m whatever it does (no encoders here).
    cfg = SupervisorConfig(return_progress_time=4.0)
    bench = Bench(steps=[Step(0.5, 0.0, 6.0, 'straight'), Step(0.5, 0.0, 4.0, 'straight')],
                  config=cfg, encoders=False)
    bench.start()
    while bench.tick().state == 'running':
        pass
    bench.frozen.add('pose')
    out = _stopped_within(bench, 6.0)
    assert out is not None and 'came no closer' in out.reason


def test_a_pose_far_outside_the_fence_stops():
    bench = Bench(steps=[Step(0.3, 0.0, 30.0, 'straight')], encoders=False)
    bench.start()
    bench.run(0.5)
    bench.pose = [3.5, 0.0, 0.0]
    out = bench.tick()
    assert out.state == 'stopped' and out.reason.startswith('outside the geofence')


def test_pose_jump():
    assert pose_jump((0.0, 0.0, 0.0), (0.01, 0.0, 0.0), 0.02, 0.5, 1.0) == ''
    assert pose_jump((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 1.0, 0.5, 1.0) == ''
    assert 'jumped' in pose_jump((2.5, 0.0, 0.0), (0.0, 0.0, 0.0), 0.02, 0.5, 1.0)
    assert 'jumped' in pose_jump((0.0, 0.0, 0.0), (0.0, 0.0, 3.0), 0.02, 0.5, 1.0)
    assert 'jumped' in pose_jump((0.0, 0.0, 0.0), (0.2, 0.0, 0.0), -1.0, 0.5, 1.0)


# Properties ------------------------------------------------------------------------

_maybe_time = st.one_of(st.none(), st.floats(allow_nan=True, allow_infinity=True,
                                             width=32))
_pose = st.one_of(st.none(), st.tuples(*[st.floats(-1e3, 1e3, allow_nan=False)] * 2,
                                       st.floats(-10, 10)),
                  st.tuples(*[st.floats(allow_nan=True, allow_infinity=True)] * 3))
_event = st.tuples(st.floats(0.0, 0.5), st.booleans(), st.floats(-0.1, 1.0),
                   st.floats(-0.1, 1.0), st.floats(-0.1, 1.0), _pose,
                   st.sampled_from(['', '', '', 'start', 'pause', 'stop']))


@settings(max_examples=150, deadline=None)
@given(st.lists(_event, min_size=1, max_size=60),
       st.floats(0.05, 2.0), st.floats(0.05, 3.0), st.booleans())
def test_command_is_finite_within_caps_and_zero_without_a_fresh_deadman(
        events, max_speed, max_yaw_rate, auto_start):
    cfg = SupervisorConfig(max_speed=max_speed, max_yaw_rate=max_yaw_rate,
                           auto_start=auto_start)
    sup = Supervisor(protocol(30.0, max_speed, max_yaw_rate, 3.0), cfg)
    t = 0.0
    for dt, held, deadman_age, enc_age, ref_age, pose, service in events:
        t += dt
        inputs = Inputs(t, held, t - deadman_age, t - enc_age, t - ref_age, pose)
        if service:
            getattr(sup, service)(inputs)
        out = sup.update(inputs)
        assert math.isfinite(out.v) and math.isfinite(out.w)
        assert abs(out.v) <= max_speed * (1 + 1e-12) and abs(out.w) <= max_yaw_rate * (1 + 1e-12)
        assert out.state in STATES
        fresh = held and -cfg.deadman_timeout <= deadman_age <= cfg.deadman_timeout
        if not fresh:
            assert (out.v, out.w) == (0.0, 0.0)


@settings(max_examples=100, deadline=None)
@given(st.floats(allow_nan=True, allow_infinity=True), _maybe_time, _maybe_time, _maybe_time,
       _pose, st.booleans())
def test_any_single_input_gives_a_finite_command(t, deadman_t, encoder_t, reference_t, pose,
                                                 held):
    sup = Supervisor(protocol(30.0), SupervisorConfig(auto_start=True))
    out = sup.update(Inputs(t, held, deadman_t, encoder_t, reference_t, pose))
    assert math.isfinite(out.v) and math.isfinite(out.w)


# The geofence pose of the IMU reference ---------------------------------------------


def test_fence_odometry_measures_the_gyro_bias_standing_still():
    fence = FenceOdometry()
    t = 0.0
    for _ in range(200):        # 2 s standing, a gyro reading 0.002 rad/s of bias
        t += 0.01
        fence.add_gyro(t, 0.002, still=True)
    assert fence.settled and fence.bias == pytest.approx(0.002)
    yaw0 = fence.yaw
    for _ in range(6000):       # a minute driving straight: no heading drift from the bias
        t += 0.01
        fence.add_gyro(t, 0.002)
        fence.add_travel(0.005, 0.005)
    assert fence.yaw - yaw0 == pytest.approx(0.0, abs=1e-9)
    assert fence.x == pytest.approx(30.0) and abs(fence.y) < 1e-6


def test_fence_odometry_skips_non_finite_and_gaps():
    fence = FenceOdometry(1.02, 0.98)
    fence.add_gyro(0.0, 0.5)
    fence.add_gyro(math.nan, 0.5)
    fence.add_gyro(5.0, 0.5)           # a 5-s gap is not integrated
    assert fence.yaw == 0.0 and not fence.settled
    fence.add_travel(math.nan, 1.0)
    fence.add_travel(1.0, 1.0)
    assert fence.pose == pytest.approx((1.0, 0.0, 0.0))


def test_fence_odometry_refuses_an_implausible_gyro():
    fence = FenceOdometry(max_rate=5.0, max_jump=2.5)
    t = 0.0
    for _ in range(100):
        t += 0.01
        assert fence.add_gyro(t, 0.5) == ''
    yaw = fence.yaw
    # A saturation burst (+2000 deg/s for 90 ms), 1e308, NaN: refused, not integrated.
    for rate in [math.radians(2000.0)] * 9 + [1e308, math.nan, -math.inf]:
        t += 0.01
        assert fence.add_gyro(t, rate) != ''
    assert fence.yaw == pytest.approx(yaw)
    assert fence.add_gyro(t + 0.01, 0.6) == ''
    # A jump within the range but faster than a vehicle accelerates.
    assert 'jumped' in fence.add_gyro(t + 0.02, 4.0)
    assert fence.add_gyro(t + 0.03, 0.6) == ''
    assert abs(fence.yaw - yaw) < 0.1


def test_start_waits_until_ready():
    bench = Bench()
    ok, message = bench.sup.start(Inputs(0.0, True, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0),
                                         'measuring the gyro bias'))
    assert not ok and 'gyro bias' in message
    sup = Supervisor(protocol(30.0), SupervisorConfig(auto_start=True))
    out = sup.update(Inputs(0.0, True, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0), 'measuring the gyro'))
    assert out.state == 'idle' and not out.moving and 'gyro' in out.reason
    out = sup.update(Inputs(0.1, True, 0.1, 0.1, 0.1, (0.0, 0.0, 0.0)))
    assert out.state == 'running' and out.moving
