"""
``plan_trajectory``: plan track-speed commands with an identified model (issue 9).

Plans the setpoints that bring the robot to a goal pose (or along a canonical trajectory of
Fink & Stump Table V) through a motion model of a terrain file and the drive-train model of
a vehicle file (:mod:`tracked_kinematics.core.plan`), prints them, and writes them as a
CSV and as a rosbag2 of ``geometry_msgs/Twist`` on ``/cmd_vel`` that ``cmd_vel_translator``
turns back into the same setpoints. ``--plot`` draws the planned path next to the path the
truth-like dynamic simulator drives with the same commands. ``--compare`` reproduces the
comparison of Fink & Stump Table VI on the simulated vehicle.

Exit status: 0 planned; 1 no plan (goal out of reach within the horizon, or missed by more
than the tolerance, also when the optimiser stopped at ``--time-limit``: nothing is written);
2 bad input (an option out of its range, a file, an output path that may not be written);
130 / 143 interrupted. The outputs are written together at the end or not at all
(docs/output-files.md).

Documentation: docs/tools/plan_trajectory.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys

import numpy as np
from tracked_kinematics.core.errors import TrackedKinematicsError
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.plan import CANONICAL, canonical, Plan, Planner
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.offline.cli.common import (
    add_force_argument, add_plot_output, ArgumentParser, bounded, run_main,
    warn_unknown_terrain_keys)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.planning import (
    compare, csv_text, execute, final_error, identify_on_sweep, limits_from, model_from_terrain,
    MODELS, write_bag)
from tracked_kinematics.offline.vehicle_file import load_vehicle, vehicle_path
from tracked_kinematics.params import icr_from_values, read_params_file
from tracked_kinematics.params.dimensions import check_same_vehicle, dimensions_of

PROG = 'plan_trajectory'
DEFAULT_VEHICLE = 'auriga_alpha'
MAX_HORIZON = 30.0
"""Longest horizon, s: 75 knots per track, a plan in well under a minute."""
MIN_HORIZON = 0.8
"""Shortest horizon, s: two knots (0.4 s apart)."""
TIME_LIMIT = 60.0
"""Default ``--time-limit`` of the optimiser, s."""


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


def build_parser() -> argparse.ArgumentParser:
    """Argument parser of ``plan_trajectory``."""
    parser = ArgumentParser(
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
    what.add_argument('--goal', nargs=3, type=bounded(-1000.0, 1000.0), metavar=('X', 'Y', 'YAW'),
                      help='goal pose from the start pose: m, m, rad (each within +-1000)')
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
    parser.add_argument('--vehicle', default=None,
                        help='vehicle YAML or shipped name (auriga_alpha, packbot): drive '
                             'train, and the dynamic simulator of --plot (default '
                             'auriga_alpha)')
    parser.add_argument('--horizon', type=bounded(MIN_HORIZON, MAX_HORIZON, 's'), default=None,
                        help=f'time to the goal, s, {MIN_HORIZON:g}-{MAX_HORIZON:g} (default 3 s '
                             '+ distance / half the max track speed, at most '
                             f'{MAX_HORIZON:g} s; canonical: its own duration)')
    parser.add_argument('--speed', type=bounded(0.01, 10.0, 'm/s'), default=None,
                        help='travelling speed of a canonical trajectory, m/s, 0.01-10 (default '
                             'half the max track speed: 1 m/s on the packbot as in Table V)')
    parser.add_argument('--max-track-speed', type=bounded(0.01, 10.0, 'm/s'), default=None,
                        help='largest track setpoint, m/s, 0.01-10 (default: the terrain '
                             "file's max_track_speed, else the vehicle's)")
    parser.add_argument('--max-track-accel', type=bounded(0.01, 100.0, 'm/s^2'), default=None,
                        help='largest track setpoint change, m/s^2, 0.01-100 (default: the '
                             "terrain file's max_track_accel, else the vehicle's)")
    parser.add_argument('--dt', type=bounded(0.005, 0.1, 's'), default=0.02,
                        help='command period, s, 0.005-0.1 (default 0.02: the translator at '
                             '50 Hz)')
    parser.add_argument('--tolerance', nargs=2, type=bounded(0.001, 10.0), default=(0.05, 0.05),
                        metavar=('METRES', 'RADIANS'),
                        help='final pose tolerance of a successful plan, each 0.001-10 '
                             '(default 0.05 0.05)')
    parser.add_argument('--time-limit', type=bounded(1.0, 3600.0, 's'), default=TIME_LIMIT,
                        metavar='SECONDS',
                        help='the optimiser stops after this long with its best plan, which '
                             f'must still meet the tolerance (default {TIME_LIMIT:g})')
    parser.add_argument('--csv', help='write the setpoints, cmd_vel and planned poses here')
    parser.add_argument('--bag', help='write a rosbag2 of geometry_msgs/Twist on /cmd_vel '
                                      'here (a directory that must not exist)')
    parser.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3',
                        help='bag storage (default sqlite3)')
    parser.add_argument('--plot', help='PNG of the planned path against the path simulated '
                                       'with the dynamic model of --vehicle')
    add_force_argument(parser)
    return parser


def _load(args):
    vehicle = load_vehicle(args.vehicle or DEFAULT_VEHICLE)
    if args.compare:
        return vehicle, None, {}
    if not args.params:
        raise UsageError('--params TERRAIN.yaml is needed to plan (or use --compare)')
    try:
        values = read_params_file(args.params)
        icr = icr_from_values(values)
    except (OSError, TrackedKinematicsError) as err:
        message = err.strerror if isinstance(err, OSError) and err.strerror else err
        raise UsageError(f'{args.params}: {message}') from None
    warn_unknown_terrain_keys(PROG, args.params, values)
    # The drive train and the simulator are the vehicle file's: of the terrain's vehicle.
    given = (f'--vehicle {vehicle.path}' if args.vehicle
             else f'--vehicle {DEFAULT_VEHICLE} (the default: give --vehicle)')
    check_same_vehicle((args.params, dimensions_of(values)),
                       (given, dimensions_of(vehicle.values)))
    return vehicle, icr, values


def _outputs(args) -> Outputs:
    """Check every output path before any work (docs/output-files.md)."""
    outputs = Outputs(force=args.force)
    if args.compare:
        for flag in ('csv', 'bag', 'plot'):
            if getattr(args, flag):
                raise UsageError(f'--{flag} is not written with --compare')
        return outputs
    outputs.add('--csv', args.csv)
    outputs.add('--bag', args.bag, directory=True)
    add_plot_output(outputs, args.plot)
    outputs.refuse_inputs('--params', [args.params])
    outputs.refuse_inputs('--vehicle', [vehicle_path(args.vehicle or DEFAULT_VEHICLE)])
    return outputs


def _plan(args, planner, speed):
    """Plan to the goal or along the canonical trajectory; refuse what the bounds exclude."""
    if args.canonical:
        ref = canonical(args.canonical, dt=args.dt, speed=speed)   # 3-6 s each
        return ref, planner.follow(ref, tolerance=args.tolerance, time_limit=args.time_limit)
    goal = np.asarray(args.goal)
    horizon = args.horizon
    if horizon is None:
        horizon = 3.0 + math.hypot(*goal[:2]) / (0.5 * planner.max_speed)
        horizon = min(horizon, MAX_HORIZON)
    plan = planner.plan_to(goal, horizon, tolerance=args.tolerance,
                           time_limit=args.time_limit)
    if not plan.success and 'stopped at its time limit' in plan.message:
        plan = dataclasses.replace(plan, message=plan.message + (
            ': give a larger --time-limit, a shorter --horizon or a nearer goal'))
    if not plan.success and args.horizon is None and horizon == MAX_HORIZON:
        plan = dataclasses.replace(plan, message=plan.message.replace(
            'give a longer horizon or a nearer goal',
            f'the horizon is at most {MAX_HORIZON:g} s: give a nearer goal'))
    return None, plan


def _run(args, out) -> int:
    with _outputs(args) as outputs:
        vehicle, icr, values = _load(args)
        robot = vehicle.robot
        limits = limits_from(values, robot, args.max_track_speed, args.max_track_accel,
                             source=str(args.params or ''))
        speed = args.speed or 0.5 * min(limits.max_track_speed, robot.drivetrain.max_speed)
        if args.compare:
            return _compare(robot, vehicle.name, limits, speed, args.dt, out)
        model, p = model_from_terrain(args.model, icr, values)
        planner = Planner(model, p, robot.drivetrain, limits, command_icr=icr, dt=args.dt)
        ref, plan = _plan(args, planner, speed)
        if not plan.success:
            print(f'{PROG}: {plan.message}; nothing written', file=sys.stderr)
            return 1
        print_plan(plan, icr, out)
        print(plan.message, file=out)
        if '--csv' in outputs:
            outputs.write_text('--csv', csv_text(plan, icr))
        if '--bag' in outputs:
            with outputs.path('--bag') as tmp:
                count = write_bag(tmp, plan, icr, args.storage)
        if '--plot' in outputs:
            table = TwistTable.of(robot.vehicle)
            driven = execute(robot, plan, table)
            pos, yaw = final_error(driven, plan.goal)
            print(f'simulated with the dynamics of {vehicle.name}: final pose {pos * 100:.1f} '
                  f'cm and {math.degrees(yaw):.1f} deg from the goal', file=out)
            title = (f'{args.canonical or "goal"}: {plan.model} model, vehicle '
                     f'{vehicle.name}; simulated final error {pos * 100:.1f} cm')
            from tracked_kinematics.offline.plots import plot_plan
            with outputs.path('--plot') as tmp:
                plot_plan(tmp, plan, driven, ref, title)
    if '--csv' in outputs:
        print(f'csv   {args.csv}', file=out)
    if '--bag' in outputs:
        print(f'bag   {args.bag} ({count} geometry_msgs/Twist on /cmd_vel, {args.storage})',
              file=out)
    if '--plot' in outputs:
        print(f'plot  {args.plot}', file=out)
    return 0


def main(argv=None) -> int:
    """Run ``plan_trajectory``; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


def _compare(robot, name, limits, speed, dt, out=sys.stdout) -> int:
    table = TwistTable.of(robot.vehicle)
    models = identify_on_sweep(robot, table, dt)
    print(f'vehicle {name}: models fitted on a simulated Fink & Stump sweep', file=out)
    for short, (model, p) in models.items():
        print(f'  {short:<10}{", ".join(f"{v:.4f}" for v in p) or "(no parameter)"}',
              file=out)
    print(f'canonical trajectories at {speed:g} m/s, executed on the dynamic simulator: final '
          'position / heading error, and the max path deviation (Table VI)', file=out)
    compare(robot, table, models, limits, speed, dt, out=out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
