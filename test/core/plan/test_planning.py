"""Trajectory generation (issue 9): the planner and plan_trajectory."""

import csv
import math
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.command import CommandLimits, track_setpoints
from tracked_kinematics.core.drivetrain import DriveTrain
from tracked_kinematics.core.integration import relative_pose
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr, EffectiveWheelBase, GeneralKinematicSlip
from tracked_kinematics.core.plan import CANONICAL, canonical, Planner
from tracked_kinematics.offline.cli import plan_trajectory

BIN = Path(sys.executable).parent
ROOT = Path(__file__).resolve().parents[3]
TERRAIN = ROOT / 'config' / 'auriga_alpha_hard_floor.yaml'
# Packbot-like planning problem: Table II drive train, 0.40 m track width.
B = 0.40
ICR = IcrParams(B, 0.31, -0.29, 0.02, 1.01, 0.99)
GENERAL = np.array([-0.0022, 0.0355, -0.0386, 0.0409, -0.0173, -0.0602, -0.0549, -0.2785,
                    0.0605])   # Fink & Stump Table IV, concrete, left


def planner(model=None, p=None, **limits):
    model = model or ConstantIcr(B)
    p = ConstantIcr(B).from_icr(ICR) if p is None else p
    limits = CommandLimits(**{'max_track_speed': 1.5, 'max_track_accel': 4.0, **limits})
    return Planner(model, p, DriveTrain.fink_stump_packbot(), limits, command_icr=ICR)


# Planner -----------------------------------------------------------------------------


@pytest.mark.parametrize('goal, horizon', [((2.0, 1.0, 0.5), 4.0), ((-1.0, 0.5, 0.0), 4.0),
                                           ((0.0, 0.0, 1.5), 3.0)])
def test_reachable_goal_is_reached_in_the_planning_model(goal, horizon):
    plan = planner().plan_to(goal, horizon)
    assert plan.success, plan.message
    # Recompute the end pose independently: drive train, then the model's own integration.
    full = np.vstack([plan.commands, np.zeros((len(plan.poses) - len(plan.commands), 2))])
    speeds = DriveTrain.fink_stump_packbot().simulate(full, plan.dt)
    step = 0.5 * (speeds[1:] + speeds[:-1]) * plan.dt
    x, y, th = ConstantIcr(B).integrate(ConstantIcr(B).from_icr(ICR), step[:, 0],
                                        step[:, 1], plan.dt)
    dx, dy, dth = relative_pose(*goal, x[-1], y[-1], th[-1])
    assert math.hypot(dx, dy) <= 0.05 and abs(dth) <= 0.05
    assert np.all(plan.commands[0] == 0.0) and np.all(plan.commands[-1] == 0.0)


def test_general_slip_plan_reaches_goal_and_differs_from_ideal():
    general = planner(GeneralKinematicSlip(B), GENERAL).plan_to((1.5, 1.0, 1.0), 4.0)
    assert general.success, general.message
    ideal = planner(EffectiveWheelBase(B), [1.0]).plan_to((1.5, 1.0, 1.0), 4.0)
    # The slip model turns less per track speed difference: it must ask for more.
    turn = np.sum(np.diff(general.commands, axis=1))
    assert turn > 1.1 * np.sum(np.diff(ideal.commands, axis=1))


TRACK_LIMITS = {'max_track_speed': 0.6, 'max_track_accel': 1.0}
SPIN = (0.0, 0.0, 3.0)


@pytest.mark.parametrize('limits, goal', [
    # The spin under the track limits takes the optimiser 10 s of CPU: make stress runs it.
    pytest.param(limits, goal, marks=pytest.mark.long) if (limits, goal) == (TRACK_LIMITS, SPIN)
    else (limits, goal)
    for goal in [(3.0, 1.5, 1.0), SPIN, (-1.5, -1.0, 0.5)]
    for limits in [{}, TRACK_LIMITS,
                   {'max_linear_velocity': 0.4, 'max_angular_velocity': 0.8,
                    'max_linear_acceleration': 0.5, 'max_angular_acceleration': 1.0}]])
def test_limits_are_never_violated(limits, goal):
    plan = planner(**limits).plan_to(goal, 4.0)
    lim = CommandLimits(**{'max_track_speed': 1.5, 'max_track_accel': 4.0, **limits})
    tol = 1e-9
    assert np.max(np.abs(plan.commands)) <= lim.max_track_speed + tol
    assert np.max(np.abs(np.diff(plan.commands, axis=0))) / plan.dt <= lim.max_track_accel + tol
    v_x, w = plan.twists(ICR)
    assert np.max(np.abs(v_x)) <= lim.max_linear_velocity + tol
    assert np.max(np.abs(w)) <= lim.max_angular_velocity + tol
    assert np.max(np.abs(np.diff(v_x))) / plan.dt <= lim.max_linear_acceleration + tol
    assert np.max(np.abs(np.diff(w))) / plan.dt <= lim.max_angular_acceleration + tol
    # A plan that claims success is within tolerance; one that does not says so.
    if plan.success:
        assert plan.position_error <= 0.05 and plan.yaw_error <= 0.05
    else:
        assert 'tolerance' in plan.message or 'unreachable' in plan.message


def test_goal_beyond_reach_is_refused_with_the_reason():
    plan = planner().plan_to((20.0, 0.0, 0.0), 4.0)
    assert not plan.success
    assert 'unreachable' in plan.message and '20.00 m away' in plan.message
    assert np.all(plan.commands == 0.0)


def test_goal_missed_is_a_failed_plan_not_a_silent_one():
    # Half a metre sideways, heading unchanged, in 1 s: within track reach, not doable.
    plan = planner().plan_to((0.0, 0.5, 0.0), 1.0)
    assert not plan.success
    assert plan.position_error > 0.05 or plan.yaw_error > 0.05
    assert 'no plan within tolerance' in plan.message


@pytest.mark.parametrize('kwargs, match', [
    ({'goal': (1.0, math.nan, 0.0), 'horizon': 3.0}, 'goal must be finite'),
    ({'goal': (1.0, 0.0), 'horizon': 3.0}, 'three numbers'),
    ({'goal': (1.0, 0.0, 0.0), 'horizon': -1.0}, 'horizon'),
    ({'goal': (1.0, 0.0, 0.0), 'horizon': math.inf}, 'horizon'),
    ({'goal': (1.0, 0.0, 0.0), 'horizon': 3.0, 'tolerance': (0.0, 0.1)}, 'tolerance')])
def test_bad_requests_raise_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        planner().plan_to(**kwargs)


def test_follow_canonical_ends_at_its_goal_in_own_model():
    plan = planner(max_track_speed=2.0, max_track_accel=5.5).follow(canonical('left'))
    assert plan.success, plan.message
    assert math.isfinite(plan.path_deviation) and plan.path_deviation < 0.5


# Command line ------------------------------------------------------------------------


def test_cli_writes_csv_and_bag_the_translator_replays(tmp_path, capsys):
    status = plan_trajectory.main(['--params', str(TERRAIN), '--goal', '1.5', '0.5', '0.3',
                                   '--horizon', '6', '--csv', str(tmp_path / 'p.csv'),
                                   '--bag', str(tmp_path / 'bag')])
    out = capsys.readouterr().out
    assert status == 0, out
    assert 'planned with the icr_scales model' in out
    with open(tmp_path / 'p.csv', encoding='utf-8') as stream:
        rows = list(csv.DictReader(stream))
    left = np.array([float(r['left']) for r in rows])
    right = np.array([float(r['right']) for r in rows])
    twists = []
    with AnyReader([tmp_path / 'bag']) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == {
            '/cmd_vel': 'geometry_msgs/msg/Twist'}
        for conn, _, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            twists.append((msg.linear.x, msg.linear.y, msg.angular.z))
    twists = np.array(twists)
    assert len(twists) == len(rows) and np.all(np.isfinite(twists))
    assert np.all(twists[:, 1] == 0.0) and np.any(twists[:, 2] != 0.0)
    # The translator's inverse kinematics turns the cmd_vel back into the planned setpoints.
    icr = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)
    back_left, back_right = track_setpoints(twists[:, 0], twists[:, 2], icr)
    np.testing.assert_allclose(back_left, left, atol=1e-5)
    np.testing.assert_allclose(back_right, right, atol=1e-5)


@pytest.mark.parametrize('argv, message', [
    (['--goal', '1', '0', '0'], '--params'),
    (['--params', 'missing.yaml', '--goal', '1', '0', '0'], 'missing.yaml'),
    (['--params', str(TERRAIN), '--goal', '1', 'nan', '0'], 'finite'),
    (['--params', str(TERRAIN), '--goal', '1', '0', '0', '--model', 'general'],
     'alpha1..alpha9'),
    (['--params', str(TERRAIN), '--goal', '1', '0', '0', '--horizon', '0'], 'horizon'),
    (['--params', str(TERRAIN), '--canonical', 'loop'], 'invalid choice'),
    (['--params', str(TERRAIN), '--goal', '1', '0', '0', '--vehicle', 'tank'], 'tank'),
    (['--params', str(TERRAIN), '--goal', '1', '0', '0', '--csv', '/no/such/dir/p.csv'],
     '--csv'),
])
def test_cli_bad_input_exits_2_with_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        sys.exit(plan_trajectory.main(argv))
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith('plan_trajectory: ') and message in err
    assert len(err.strip().splitlines()) == 1


def test_cli_unreachable_goal_exits_1_and_writes_nothing(tmp_path, capsys):
    status = plan_trajectory.main(['--params', str(TERRAIN), '--goal', '30', '0', '0', '--horizon',
                                   '5', '--csv', str(tmp_path / 'p.csv')])
    err = capsys.readouterr().err
    assert status == 1 and 'unreachable' in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / 'p.csv').exists()


def test_console_script_canonical_with_plot(tmp_path):
    run = subprocess.run([str(BIN / 'plan_trajectory'), '--params', str(TERRAIN),
                          '--canonical', 'right', '--model', 'effective', '--plot', 'p.png'],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert 'simulated with the dynamics of auriga_alpha' in run.stdout
    assert (tmp_path / 'p.png').stat().st_size > 10_000
    assert CANONICAL  # the names the CLI offers come from core.planning
