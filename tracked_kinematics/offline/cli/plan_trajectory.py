"""
``plan_trajectory``: plan track-speed commands with an identified model (issue 9).

Plans the setpoints that bring the robot to a goal pose (or along a canonical trajectory of
Fink & Stump Table V) through a motion model of a terrain file and the drive-train model of
a vehicle file (:mod:`tracked_kinematics.core.plan`), prints them, and writes them as a
CSV and as a rosbag2 of ``geometry_msgs/Twist`` on ``/cmd_vel`` that ``cmd_vel_translator``
turns back into the same setpoints. ``--plot`` draws the planned path next to the path the
truth-like dynamic simulator drives with the same commands. ``--compare`` reproduces the
comparison of Fink & Stump Table VI on the simulated vehicle.

Exit status: 0 planned; 1 no plan (goal out of reach, or missed by more than the tolerance:
nothing is written); 2 bad input.

Documentation: docs/tools/plan_trajectory.md.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
from pathlib import Path
import sys

import numpy as np
from rosbags.rosbag2 import WriterError
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.command import CommandLimits
from tracked_kinematics.core.integration import relative_pose
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import MotionModel
from tracked_kinematics.core.plan import (
    CANONICAL, canonical, path_deviation, Plan, Planner)
from tracked_kinematics.core.sim.manoeuvres import fink_stump_sweep
from tracked_kinematics.core.sim.simulation import GroundTruth, Robot, simulate, TwistTable
from tracked_kinematics.offline.bags import BagWriter
from tracked_kinematics.offline.cli.common import positive
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.vehicle_file import load_vehicle
from tracked_kinematics.params import icr_from_values, LIMIT_FIELDS, read_params_file

PROG = 'plan_trajectory'
MODELS = ('ideal', 'effective', 'icr', 'general')
_MODEL_NAMES = {'ideal': 'ideal', 'effective': 'effective_wheel_base', 'icr': 'icr_scales',
                'general': 'general_slip'}
# Models --------------------------------------------------------------------------------


def model_from_terrain(name: str, icr: IcrParams, values=None) -> tuple[MotionModel, np.ndarray]:
    """
    Build the planning model of a terrain file.

    ``ideal``: its track width; ``effective``: ``alpha = chi`` of its ICRs (the effective
    wheel base equals the symmetric ICR model with that steering efficiency); ``icr``: its
    ICRs and scales; ``general``: ``identification.parameters.alpha1..alpha9``, which
    ``identify_icr --model general_slip`` writes.

    Raises
    ------
    UsageError
        For ``general`` without those parameters in the file.

    """
    model = ident.build_model(_MODEL_NAMES[name], icr.track_width)
    if name == 'ideal':
        return model, model.initial()
    if name == 'effective':
        return model, np.array([icr.chi])
    if name == 'icr':
        return model, model.from_icr(icr)
    keys = [f'identification.parameters.alpha{i}' for i in range(1, 10)]
    values = values or {}
    missing = [k for k in keys if k not in values]
    if missing:
        raise UsageError('--model general needs identification.parameters.alpha1..alpha9 in '
                         'the terrain file (identify_icr --model general_slip writes them)')
    try:
        p = np.array([float(values[k]) for k in keys])
    except (TypeError, ValueError):
        raise UsageError('identification.parameters.alpha1..alpha9 must be numbers') from None
    if not np.all(np.isfinite(p)):
        raise UsageError('identification.parameters.alpha1..alpha9 must be finite')
    return model, p


def limits_from(values, robot: Robot, max_track_speed=None, max_track_accel=None):
    """Return the translator limits: command line, else terrain file, else drive train."""
    kwargs = {}
    for param, field_name in LIMIT_FIELDS.items():
        if param in values:
            try:
                value = float(values[param])
            except (TypeError, ValueError):
                raise UsageError(f'{param} must be a number, got {values[param]!r}') from None
            kwargs[field_name] = math.inf if value == 0.0 else value
    if max_track_speed is not None:
        kwargs['max_track_speed'] = max_track_speed
    if max_track_accel is not None:
        kwargs['max_track_accel'] = max_track_accel
    kwargs.setdefault('max_track_speed', robot.drivetrain.max_speed)
    kwargs.setdefault('max_track_accel', robot.drivetrain.max_accel)
    try:
        return CommandLimits(**kwargs)
    except ValueError as err:
        raise UsageError(str(err).replace('max_track_', '--max-track-')) from None


# Execution on the dynamic simulator ----------------------------------------------------


def execute(robot: Robot, plan: Plan, table: TwistTable, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """
    Poses of the truth-like simulator driven by the plan's commands, settling included.

    Returns
    -------
    ndarray, shape like ``plan.poses``

    """
    settle = len(plan.poses) - len(plan.commands)
    commands = np.vstack([plan.commands, np.zeros((settle, 2))])
    return simulate(robot, commands, plan.dt, table=table, pose0=tuple(start)).pose


def final_error(poses, goal) -> tuple[float, float]:
    """Return the final position (m) and ``|heading|`` (rad) error of a path to a goal."""
    ex, ey, eth = relative_pose(*goal, *poses[-1])
    return math.hypot(ex, ey), abs(float(eth))


# Table VI ------------------------------------------------------------------------------


def identify_on_sweep(robot: Robot, table: TwistTable, dt: float = 0.02, seed: int = 0):
    """
    Planning models of the simulated vehicle, fitted on its Fink & Stump sweep.

    Drives the trapezoidal speed x curvature sweep of sec. IV-B on the dynamic simulator
    (ground truth at 10 Hz with 2 mm / 2 mrad noise), then fits the effective wheel-base,
    ICR (with scales) and 9-parameter general slip models by the least squares of
    :func:`tracked_kinematics.core.identify.fit` on 1 s segments of the encoder travel.

    Returns
    -------
    dict
        ``{'ideal' | 'effective' | 'icr' | 'general': (model, p)}``.

    """
    b = robot.vehicle.track_width
    commands = fink_stump_sweep(dt, b, robot.drivetrain.max_speed)
    run = simulate(robot, commands, dt, table=table,
                   ground_truth=GroundTruth(10.0, 0.002, 0.002),
                   rng=np.random.default_rng(seed))
    radius = robot.encoders.sprocket_radius
    rec = ident.Recording(run.t, run.joint_position[:, 0] * radius,
                          run.joint_position[:, 1] * radius, run.gt_t, run.gt_pose[:, 0],
                          run.gt_pose[:, 1], run.gt_pose[:, 2], name='sweep')
    segments = ident.build_segments([rec], 1.0)
    segments = segments.select(segments.travel >= 0.01)
    models = {'ideal': (ident.build_model('ideal', b), np.zeros(0))}
    for short in ('effective', 'icr', 'general'):
        model = ident.build_model(_MODEL_NAMES[short], b)
        models[short] = (model, ident.fit(model, segments, heading_weight=None, check=False).p)
    return models


def compare(robot: Robot, table: TwistTable, models, limits: CommandLimits, speed: float,
            dt: float = 0.02, names=CANONICAL, out=sys.stdout):
    """
    Plan every canonical trajectory with every model, execute it, tabulate (Table VI).

    Returns
    -------
    dict
        ``{model: {trajectory: (planned position error, executed position error,
        executed heading error, executed max path deviation, plan seconds)}}``.

    """
    results = {}
    for short, (model, p) in models.items():
        planner = Planner(model, p, robot.drivetrain, limits, dt=dt)
        results[short] = {}
        for name in names:
            ref = canonical(name, dt=dt, speed=speed)
            plan = planner.follow(ref)
            driven = execute(robot, plan, table)
            pos, yaw = final_error(driven, ref.goal)
            dev = float(np.max(path_deviation(driven, ref.path)))
            results[short][name] = (plan.position_error, pos, yaw, dev, plan.seconds)
    print(f'{"model":<10}' + ''.join(f'{n:>12}' for n in names)
          + f'{"mean":>9}{"max dev":>9}{"mean dev":>9}', file=out)
    print(f'{"":<10}' + ''.join(f'{"cm / deg":>12}' for _ in names)
          + f'{"cm":>9}{"m":>9}{"m":>9}', file=out)
    for short, row in results.items():
        cells = ''.join(f'{r[1] * 100:>6.1f} /{math.degrees(r[2]):>4.0f}' for r in row.values())
        mean = np.mean([r[1] for r in row.values()]) * 100
        devs = [r[3] for r in row.values()]
        print(f'{short:<10}{cells}{mean:>9.1f}{max(devs):>9.2f}{np.mean(devs):>9.2f}',
              file=out)
    return results


# Outputs -------------------------------------------------------------------------------


def write_csv(path, plan: Plan, icr: IcrParams) -> None:
    """Write ``t, left, right, v_x, w, x, y, yaw`` per command (setpoints and planned pose)."""
    v_x, w = plan.twists(icr)
    with open(path, 'w', newline='', encoding='utf-8') as stream:
        writer = csv.writer(stream)
        writer.writerow(['t', 'left', 'right', 'v_x', 'w', 'x', 'y', 'yaw'])
        for k, t in enumerate(plan.t):
            x, y, yaw = plan.poses[k]
            writer.writerow([f'{t:.4f}', f'{plan.commands[k, 0]:.6f}',
                             f'{plan.commands[k, 1]:.6f}', f'{v_x[k]:.6f}', f'{w[k]:.6f}',
                             f'{x:.6f}', f'{y:.6f}', f'{yaw:.6f}'])


def write_bag(path, plan: Plan, icr: IcrParams, storage: str = 'sqlite3',
              topic: str = '/cmd_vel') -> int:
    """Write the plan as geometry_msgs/Twist on ``topic``, one per command; return the count."""
    v_x, w = plan.twists(icr)
    with BagWriter(path, storage) as bag:
        for k, t in enumerate(plan.t):
            bag.write(topic, int(round(t * 1e9)), bag.twist(v_x[k], w[k]))
    return len(v_x)


def print_plan(plan: Plan, icr: IcrParams, out=sys.stdout) -> None:
    """Print the setpoints at the knots, and the plan's summary line."""
    v_x, w = plan.twists(icr)
    step = max(1, int(round(len(plan.commands) / max(len(plan.knots) + 1, 1))))
    print(f'{"t (s)":>7}{"left":>9}{"right":>9}{"v_x":>9}{"w":>9}   (setpoints m/s; '
          'cmd_vel m/s, rad/s)', file=out)
    for k in list(range(0, len(plan.commands), step)) + [len(plan.commands) - 1]:
        print(f'{plan.t[k]:>7.2f}{plan.commands[k, 0]:>9.3f}{plan.commands[k, 1]:>9.3f}'
              f'{v_x[k]:>9.3f}{w[k]:>9.3f}', file=out)
    peak = np.max(np.abs(plan.commands))
    accel = np.max(np.abs(np.diff(plan.commands, axis=0))) / plan.dt
    print(f'{len(plan.commands)} setpoints every {plan.dt:g} s; peak track speed {peak:.3f} '
          f'm/s, peak track acceleration {accel:.3f} m/s^2; {plan.nfev} predictions in '
          f'{plan.seconds:.2f} s', file=out)


# Command line --------------------------------------------------------------------------


def _finite(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'expected a finite number, got {text!r}')
    return value


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(2, f'{self.prog}: {message}\n')


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``plan_trajectory``."""
    parser = _Parser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description='Plan track-speed commands that bring a tracked robot to a goal pose (or '
                    'along a canonical trajectory of Fink & Stump Table V) through a motion '
                    'model and the drive-train model, within the cmd_vel_translator limits; '
                    'write them as CSV and as a /cmd_vel bag.',
        epilog='examples:\n'
               '  plan_trajectory --params config/auriga_alpha_hard_floor.yaml --goal 2 1 0.5 '
               '--horizon 8 --model icr --csv plan.csv --bag plan_bag --plot plan.png\n'
               '  plan_trajectory --params grass.yaml --canonical left --model general '
               '--vehicle packbot --bag left_bag\n'
               '  plan_trajectory --compare --vehicle packbot      # Table VI on the simulator')
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument('--goal', nargs=3, type=_finite, metavar=('X', 'Y', 'YAW'),
                      help='goal pose from the start pose: m, m, rad')
    what.add_argument('--canonical', choices=CANONICAL,
                      help='follow a canonical trajectory (Table V and ours)')
    what.add_argument('--compare', action='store_true',
                      help='Table VI: identify every model on a simulated sweep of --vehicle, '
                           'plan every canonical trajectory with each, execute on the '
                           'simulator, print the errors')
    parser.add_argument('--params', help='terrain YAML (track_width, icr.*, scale.*; '
                                         'translator limits when present)')
    parser.add_argument('--model', choices=MODELS, default='icr',
                        help='planning model (default icr)')
    parser.add_argument('--vehicle', default='auriga_alpha',
                        help='vehicle YAML or shipped name (auriga_alpha, packbot): drive '
                             'train, and the dynamic simulator of --plot (default '
                             'auriga_alpha)')
    parser.add_argument('--horizon', type=positive, default=None,
                        help='time to the goal, s (default 3 s + distance / half the max '
                             'track speed; canonical: its own duration)')
    parser.add_argument('--speed', type=positive, default=None,
                        help='travelling speed of a canonical trajectory, m/s (default half '
                             'the max track speed: 1 m/s on the packbot as in Table V)')
    parser.add_argument('--max-track-speed', type=positive, default=None,
                        help="largest track setpoint, m/s (default: the terrain file's "
                             "max_track_speed, else the vehicle's)")
    parser.add_argument('--max-track-accel', type=positive, default=None,
                        help='largest track setpoint change, m/s^2 (default: the terrain '
                             "file's max_track_accel, else the vehicle's)")
    parser.add_argument('--dt', type=positive, default=0.02,
                        help='command period, s (default 0.02: the translator at 50 Hz)')
    parser.add_argument('--tolerance', nargs=2, type=positive, default=(0.05, 0.05),
                        metavar=('METRES', 'RADIANS'),
                        help='final pose tolerance of a successful plan (default 0.05 0.05)')
    parser.add_argument('--csv', help='write the setpoints, cmd_vel and planned poses here')
    parser.add_argument('--bag', help='write a rosbag2 of geometry_msgs/Twist on /cmd_vel '
                                      'here (a directory that must not exist)')
    parser.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3',
                        help='bag storage (default sqlite3)')
    parser.add_argument('--plot', help='PNG of the planned path against the path simulated '
                                       'with the dynamic model of --vehicle')
    return parser


def _load(args):
    try:
        vehicle = load_vehicle(args.vehicle)
    except (OSError, ValueError) as err:
        raise UsageError(str(err)) from None
    if args.compare:
        return vehicle, None, {}
    if not args.params:
        raise UsageError('--params TERRAIN.yaml is needed to plan (or use --compare)')
    try:
        values = read_params_file(args.params)
        icr = icr_from_values(values)
    except (OSError, ValueError) as err:
        raise UsageError(f'{args.params}: {err}') from None
    return vehicle, icr, values


def _check_outputs(args):
    for option in ('csv', 'plot'):
        path = getattr(args, option)
        if path and not Path(path).resolve().parent.is_dir():
            raise UsageError(f'--{option}: no directory {str(Path(path).parent)!r}')
    if args.bag and os.path.exists(args.bag):
        raise UsageError(f'--bag: {args.bag!r} exists; give a new directory')
    if args.bag and not Path(args.bag).resolve().parent.is_dir():
        raise UsageError(f'--bag: no directory {str(Path(args.bag).parent)!r}')


def main(argv=None) -> int:
    """Run ``plan_trajectory``; return the exit status."""
    args = build_parser().parse_args(argv)
    try:
        _check_outputs(args)
        vehicle, icr, values = _load(args)
        robot = vehicle.robot
        limits = limits_from(values, robot, args.max_track_speed, args.max_track_accel)
        speed = args.speed or 0.5 * min(limits.max_track_speed, robot.drivetrain.max_speed)
        if args.compare:
            return _compare(robot, vehicle.name, limits, speed, args.dt)
        model, p = model_from_terrain(args.model, icr, values)
        if abs(model.track_width - robot.vehicle.track_width) > 1e-6 and args.plot:
            print(f'{PROG}: note: the terrain track width {model.track_width} m differs '
                  f"from the vehicle's {robot.vehicle.track_width} m", file=sys.stderr)
        planner = Planner(model, p, robot.drivetrain, limits, command_icr=icr, dt=args.dt)
        ref = None
        if args.canonical:
            ref = canonical(args.canonical, dt=args.dt, speed=speed)
            plan = planner.follow(ref, tolerance=args.tolerance)
        else:
            goal = np.asarray(args.goal)
            horizon = args.horizon or 3.0 + math.hypot(*goal[:2]) / (0.5 * planner.max_speed)
            plan = planner.plan_to(goal, horizon, tolerance=args.tolerance)
    except (UsageError, ValueError) as err:
        print(f'{PROG}: {err}', file=sys.stderr)
        return 2
    if not plan.success:
        print(f'{PROG}: {plan.message}; nothing written', file=sys.stderr)
        return 1
    print_plan(plan, icr)
    print(plan.message)
    try:
        if args.csv:
            write_csv(args.csv, plan, icr)
            print(f'csv   {args.csv}')
        if args.bag:
            count = write_bag(args.bag, plan, icr, args.storage)
            print(f'bag   {args.bag} ({count} geometry_msgs/Twist on /cmd_vel, {args.storage})')
        if args.plot:
            table = TwistTable(robot.vehicle)
            driven = execute(robot, plan, table)
            pos, yaw = final_error(driven, plan.goal)
            print(f'simulated with the dynamics of {vehicle.name}: final pose {pos * 100:.1f} '
                  f'cm and {math.degrees(yaw):.1f} deg from the goal')
            title = (f'{args.canonical or "goal"}: {plan.model} model, vehicle '
                     f'{vehicle.name}; simulated final error {pos * 100:.1f} cm')
            from tracked_kinematics.offline.plots import plot_plan
            plot_plan(args.plot, plan, driven, ref, title)
            print(f'plot  {args.plot}')
    except (OSError, WriterError) as err:
        print(f'{PROG}: cannot write: {err}', file=sys.stderr)
        return 2
    return 0


def _compare(robot, name, limits, speed, dt) -> int:
    table = TwistTable(robot.vehicle)
    models = identify_on_sweep(robot, table, dt)
    print(f'vehicle {name}: models fitted on a simulated Fink & Stump sweep')
    for short, (model, p) in models.items():
        print(f'  {short:<10}{", ".join(f"{v:.4f}" for v in p) or "(no parameter)"}')
    print(f'canonical trajectories at {speed:g} m/s, executed on the dynamic simulator: final '
          'position / heading error, and the max path deviation (Table VI)')
    compare(robot, table, models, limits, speed, dt)
    return 0


if __name__ == '__main__':
    sys.exit(main())
