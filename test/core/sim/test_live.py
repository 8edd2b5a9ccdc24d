"""The simulator stepped live (issue 22): same runs as simulate(), terrains, sensors, seeds."""

from dataclasses import replace
import math

import numpy as np
import pytest
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag
from tracked_kinematics.core.kinematics import forward
from tracked_kinematics.core.sim.live import DriveTrainStepper, LiveSimulator, SetpointHold
from tracked_kinematics.core.sim.live_sensors import (EncoderReadout, PoseModel, PoseStream,
                                                      Schedule)
from tracked_kinematics.core.sim.manoeuvres import manoeuvre
from tracked_kinematics.core.sim.simulation import Robot, simulate, TwistTable
from tracked_kinematics.core.sim.terrains import TERRAINS
from tracked_kinematics.params.vehicles import load_vehicle

DT = 0.01


@pytest.fixture(scope='module')
def robots():
    """Give the shipped vehicles (first-order and PID drive trains) and their dynamics."""
    out = {}
    for name in ('auriga_alpha', 'packbot'):
        robot = load_vehicle(name).robot
        out[name] = (robot, TwistTable(robot.vehicle))
    return out


def _commands(robot, seconds=60.0, seed=7):
    commands = manoeuvre('mixed', seconds, DT, robot.vehicle.track_width,
                         robot.vehicle.max_track_speed, np.random.default_rng(seed))
    commands[0] = 0.0  # the live simulator starts at rest with zero commands
    return commands


def _live_run(robot, table, commands):
    sim = LiveSimulator(robot, DT, table)
    states = [sim.state] + [sim.step(*c) for c in commands[1:]]
    return states


@pytest.mark.parametrize('name', ['auriga_alpha', 'packbot'])
def test_stepping_reproduces_the_offline_simulator(robots, name):
    robot, table = robots[name]
    robot = replace(robot, encoders=replace(robot.encoders, ticks_per_revolution=0.0,
                                            velocity_noise=0.0, position_noise=0.0))
    commands = _commands(robot)
    run = simulate(robot, commands, DT, table)
    states = _live_run(robot, table, commands)
    assert run.distance > 10.0  # a real drive, not a robot at rest
    pose = np.array([s.pose for s in states])
    np.testing.assert_allclose(pose, run.pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose([s.nominal for s in states], run.nominal, rtol=0, atol=1e-12)
    np.testing.assert_allclose([s.true_speeds for s in states], run.true_speeds, rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose([s.twist for s in states[1:]], run.twist, rtol=0, atol=1e-12)
    np.testing.assert_allclose([s.t for s in states], run.t, rtol=0, atol=1e-9)
    readout = EncoderReadout(robot.encoders.sprocket_radius)
    joints = np.array([readout.read(s.travel, s.nominal)[0] for s in states])
    np.testing.assert_allclose(joints, run.joint_position, rtol=0, atol=1e-9)


def test_steps_in_batches_are_the_same_run(robots):
    """step_many (what the node uses) equals step() after step() and simulate() to rounding."""
    robot, table = robots['packbot']
    commands = _commands(robot, 30.0, seed=2)
    run = simulate(robot, commands, DT, table)
    sim = LiveSimulator(robot, DT, table)
    rng = np.random.default_rng(0)
    parts, k = [], 1
    while k < len(commands):
        n = int(rng.integers(1, 40))
        parts.append(sim.step_many(commands[k:k + n]))
        k += n
    pose = np.vstack([np.zeros((1, 3))] + [part.pose for part in parts])
    np.testing.assert_allclose(pose, run.pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.vstack([part.twist for part in parts]), run.twist, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([part.t for part in parts]), run.t[1:],
                               atol=1e-9)
    travel = np.vstack([part.travel for part in parts]) / robot.encoders.sprocket_radius
    np.testing.assert_allclose(travel, run.joint_position[1:], atol=2e-3)  # ticks: floored
    assert sim.state == parts[-1].state(len(parts[-1]) - 1)
    assert sim.state.t == pytest.approx(run.t[-1])
    with pytest.raises(ValueError, match='finite'):
        sim.step_many([[0.1, 0.1], [math.nan, 0.0]])
    assert sim.state == parts[-1].state(len(parts[-1]) - 1)  # nothing taken


def test_encoder_ticks_match_the_offline_simulator(robots):
    """The tick phase comes first from the generator, as simulate() draws it."""
    robot, table = robots['auriga_alpha']
    robot = replace(robot, encoders=replace(robot.encoders, velocity_noise=0.0))
    commands = _commands(robot, 20.0)
    run = simulate(robot, commands, DT, table, rng=np.random.default_rng(5))
    readout = EncoderReadout(robot.encoders.sprocket_radius,
                             robot.encoders.ticks_per_revolution, rng=np.random.default_rng(5))
    joints = np.array([readout.read(s.travel, s.nominal)[0]
                       for s in _live_run(robot, table, commands)])
    tick = 2 * math.pi / robot.encoders.ticks_per_revolution
    # Equal but where the floor of one rounding differs from the other's: at most a tick.
    assert np.max(np.abs(joints - run.joint_position)) <= tick * 1.0001
    assert np.mean(joints == run.joint_position) > 0.99


def test_drive_train_stepper_matches_the_batch_response():
    drives = DriveTrain(delay=0.047, max_accel=2.0, max_speed=0.8, loop=FirstOrderLag(0.12))
    rng = np.random.default_rng(3)
    commands = np.repeat(rng.uniform(-1.5, 1.5, (40, 2)), 25, axis=0)
    commands[0] = 0.0
    stepper = DriveTrainStepper(drives, DT)
    got = [(0.0, 0.0)] + [stepper.step(*c) for c in commands[1:]]
    np.testing.assert_allclose(got, drives.simulate(commands, DT), rtol=0, atol=1e-12)
    assert np.max(np.abs(got)) <= 0.8 + 1e-12  # the speed limit holds


def test_a_non_finite_command_is_refused_and_the_state_kept(robots):
    robot, table = robots['auriga_alpha']
    sim = LiveSimulator(robot, DT, table)
    for _ in range(50):
        sim.step(0.5, 0.5)
    before = sim.state
    for bad in (math.nan, math.inf, -math.inf):
        with pytest.raises(ValueError, match='finite'):
            sim.step(bad, 0.5)
    assert sim.state == before
    assert all(map(math.isfinite, sim.step(1e300, -1e300).pose))  # huge: the drives limit it


def test_terrain_switch_changes_the_dynamics_from_the_next_step(robots):
    robot, floor = robots['auriga_alpha']
    grass = TwistTable(TERRAINS['grass'].apply(robot.vehicle))
    sim = LiveSimulator(robot, DT, floor)
    for _ in range(300):
        sim.step(0.2, 0.6)            # a steady left arc
    w_floor = sim.state.twist[2]
    drives_before = sim.state.nominal
    sim.set_table(grass)
    state = sim.step(0.2, 0.6)
    assert state.nominal == pytest.approx(drives_before, abs=1e-9)  # the drives run on
    speeds = state.true_speeds
    assert state.twist == pytest.approx([float(c) for c in grass(*speeds)], abs=1e-6)
    # Grass slips more in a turn: a lower steering efficiency, a slower turn.
    assert state.twist[2] < 0.9 * w_floor
    # On the floor the turn is the one the averaged ICR model of the vehicle predicts.
    assert w_floor == pytest.approx(forward(*speeds, robot.true_icr(n=11))[2], rel=0.05)


def test_terrain_presets_span_the_real_recordings():
    """The shipped frictions give distinct steering efficiencies on the Auriga-alpha."""
    robot = load_vehicle('auriga_alpha').robot
    chi = {}
    for name in ('hard_floor', 'grass', 'asphalt'):
        vehicle = TERRAINS[name].apply(robot.vehicle)
        chi[name] = Robot(vehicle, robot.drivetrain, robot.encoders).true_icr(n=9).chi
    assert chi['grass'] < chi['hard_floor'] < chi['asphalt']
    assert chi['hard_floor'] == pytest.approx(0.51, abs=0.02)


def _sensor_run(robot, table, seed, steps=400):
    """Return what a seeded live run reports: encoder readings and lidar poses."""
    enc_rng, lidar_rng = (np.random.default_rng(s)
                          for s in np.random.SeedSequence(seed).spawn(2))
    readout = EncoderReadout(0.1, 1000, 0.001, 0.01, rng=enc_rng)
    lidar = PoseStream(PoseModel(jump_rate=1.0), lidar_rng)
    sim = LiveSimulator(robot, DT, table)
    joints, poses = [], []
    for k in range(steps):
        state = sim.step(0.4, 0.6 if k < 200 else 0.1)
        joints.append(np.concatenate(readout.read(state.travel, state.nominal)))
        poses += [np.r_[t, p] for t, p in lidar.push(state.t, state.pose)]
    return np.array(joints), np.array(poses)


def test_a_run_is_reproducible_from_its_seed(robots):
    robot, table = robots['auriga_alpha']
    first = _sensor_run(robot, table, 11)
    again = _sensor_run(robot, table, 11)
    other = _sensor_run(robot, table, 12)
    for a, b, c in zip(first, again, other):
        np.testing.assert_array_equal(a, b)
        assert not np.allclose(a, c)


def test_encoder_wrap_and_noise():
    rng = np.random.default_rng(0)
    readout = EncoderReadout(0.1, 0.0, 0.0, 0.05, wrap=True, rng=rng)
    position, velocity = readout.read([1.0, -2.5], [0.3, -0.2])
    assert np.all((position >= -math.pi) & (position < math.pi))
    np.testing.assert_allclose(np.cos(position), np.cos([10.0, -25.0]), atol=1e-12)
    velocities = np.array([readout.read([0.0, 0.0], [0.3, -0.2])[1] for _ in range(4000)])
    np.testing.assert_allclose(velocities.mean(axis=0), [3.0, -2.0], atol=0.005)
    np.testing.assert_allclose(velocities.std(axis=0), 0.05, rtol=0.05)


@pytest.mark.parametrize('rate, expected',
                         [(50.0, 50), (100.0, 100), (500.0, 100), (30.0, 30)])
def test_schedules_sample_at_their_rate(rate, expected):
    schedule = Schedule(rate, DT)
    due = [k for k in range(1, 101) if schedule.due(k * DT)]
    assert len(due) == expected
    if rate == 50.0:
        assert due == list(range(2, 101, 2))


def test_pose_stream_is_delayed_noisy_and_jumps():
    model = PoseModel(rate=10.0, delay=0.25, position_noise=0.02, yaw_noise=0.01,
                      jump_rate=0.05, jump_size=0.5, jump_yaw=0.0)
    stream = PoseStream(model, np.random.default_rng(1))
    out = []
    step = 0.05
    for k in range(1, 40_001):
        t = k * step
        pose = (0.1 * t, 0.0, 0.01 * t)   # straight at 0.1 m/s, turning slowly
        for measured, value in stream.push(t, pose):
            assert measured + model.delay <= t + 1e-9       # never before the delay
            assert t - step < measured + model.delay + 1e-9  # and at once after it
            out.append((measured, *value))
    out = np.array(out)
    assert len(out) == pytest.approx(2000 * 10, abs=5)
    measured = out[:, 0]
    np.testing.assert_allclose(np.diff(measured), 0.1, atol=1e-9)
    err = out[:, 1:3] - np.column_stack([0.1 * measured, np.zeros_like(measured)])
    jumps = np.flatnonzero(np.hypot(*np.diff(err, axis=0).T) > 0.3)
    assert 40 <= stream.jumps <= 170  # 0.05 / s over 2000 s: 100 expected
    assert len(jumps) == pytest.approx(stream.jumps, abs=3)
    # Between the jumps the error is the white noise around a constant offset.
    steady = np.diff(err[:jumps[0]], axis=0)
    assert np.std(steady) == pytest.approx(0.02 * math.sqrt(2), rel=0.15)
    yaw_err = np.angle(np.exp(1j * (out[:, 3] - 0.01 * measured)))
    assert np.std(yaw_err) == pytest.approx(0.01, rel=0.1)


def test_pose_stream_without_noise_is_the_truth_of_the_measurement_time():
    model = PoseModel(rate=20.0, delay=0.05, position_noise=0.0, yaw_noise=0.0,
                      jump_rate=0.0)
    stream = PoseStream(model, np.random.default_rng(0))
    for k in range(1, 301):
        t = k * DT
        for measured, value in stream.push(t, (math.sin(t), t, 0.0)):
            np.testing.assert_allclose(value, [math.sin(measured), measured, 0.0], atol=1e-3)


def test_setpoint_hold_ignores_clamps_and_times_out():
    hold = SetpointHold(timeout=0.5, limit=30.0)
    assert hold.current(0.0, 100.0) == 0.0          # nothing yet
    assert hold.take(0.4, 1.0, 100.0) is None
    assert hold.current(1.2, 100.1) == 0.4
    for bad in (math.nan, math.inf, -math.inf, 'fast'):
        assert 'ignored' in hold.take(bad, 1.3, 100.2)
        assert hold.current(1.3, 100.2) == 0.4      # the last good one holds
    assert 'clamped' in hold.take(1e300, 1.4, 100.3)
    assert hold.current(1.4, 100.3) == 30.0
    assert hold.take(-1e300, 1.4, 100.3) and hold.current(1.4, 100.3) == -30.0
    # Stale only when old in both clocks: fast simulated time alone does not cut it off ...
    assert hold.current(5.0, 100.4) == -30.0
    # ... nor a stalled simulation, but both together do.
    assert hold.current(1.5, 101.0) == -30.0
    assert hold.current(5.0, 101.0) == 0.0
    never = SetpointHold(timeout=math.inf, limit=30.0)
    never.take(0.2, 0.0, 0.0)
    assert never.current(1e6, 1e6) == 0.2
