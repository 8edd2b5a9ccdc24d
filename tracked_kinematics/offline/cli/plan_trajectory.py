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
import math
import os
from pathlib import Path
import sys

import numpy as np
from rosbags.rosbag2 import WriterError
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.plan import CANONICAL, canonical, Plan, Planner
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.offline.cli.common import positive
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.planning import (
    compare, execute, final_error, identify_on_sweep, limits_from, model_from_terrain, MODELS,
    write_bag, write_csv)
from tracked_kinematics.offline.vehicle_file import load_vehicle
from tracked_kinematics.params import icr_from_values, read_params_file

PROG = 'plan_trajectory'


# Output --------------------------------------------------------------------------------


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
