"""
evaluate_model: score terrain models on recorded rosbags, from the encoders and the commands.

Reads the track encoders, a ground-truth pose and, where the bag has them, the commands
(per-track setpoints or cmd_vel), and scores each terrain file next to the ideal
differential drive of its track width: odometry from the encoders (final errors after
windows, drift, evo's relative pose error per 1 m and 10 m), predictions over a horizon from
the measured travel and from the commands through the file's drive train, and with
``--online`` the same for the icr_estimator's EKF replayed over the bags from each file.

The windows are those in which the vehicle moves (mean track speed at least
``--min-speed``, 0.1 m/s), so that a figure does not depend on how long the robot stood
still; ``--all-windows`` scores the idle ones too.

With ``--imu-topic`` instead of ``--ground-truth-topic`` the reference is the gyro: heading
only (its bias and delay behind the encoders estimated as identify_icr does); the position
figures are null in the report and ``-`` in the table, and there is no prediction from the
commands.

Exit status, as identify_icr: 0 success; 2 bad input (missing bag, topic or joint; unreadable
bag or terrain file; invalid option; an output that may not be written); 3 too little data
(no gap-free stretch of encoders and ground truth; with ``--imu-topic``, a gyro the tracks
cannot time: give ``--imu-delay``).

Documentation: docs/tools/evaluate_model.md (every figure of the report and how it is
computed).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import sys

import numpy as np
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.offline.bags import read_recording
from tracked_kinematics.offline.cli.common import (
    add_command_arguments, add_ground_truth_arguments, add_imu_delay_argument,
    add_imu_mount_argument,
    add_vehicle_groups, add_window_selection_arguments, command_source, encoder_source,
    ground_truth_source, identification_parser, imu_mount_of, positive, require_vehicle,
    run_main)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.model_evaluation import (
    check_gyro_rate, commands_of, evaluate_models, gyro_references, pose_references,
    read_terrain_models, References)
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.params import positive as check_positive
from tracked_kinematics.params.dimensions import check_same_vehicle, dimensions_of

PROG = 'evaluate_model'

EPILOG = """examples:
  evaluate_model run1/ run2/ --ground-truth-topic /mocap/pose --params hard_floor.yaml
  evaluate_model husky_wetgrass_part1 --ground-truth-topic /icp/pose \\
      --params husky_wetgrass.yaml --sprocket-radius 0.15875 --online \\
      --report eval.json --plot eval.png
  evaluate_model field.bag --ground-truth-topic /gps/odom --params grass.yaml gravel.yaml \\
      --window 2 5 10 30 --horizon 3 --command-source cmd_vel
  evaluate_model drive/ --imu-topic /imu/data --params grass.yaml   # heading only
"""


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of evaluate_model."""
    parser = identification_parser(PROG, __doc__, EPILOG, ' (or --imu-topic)')
    parser.add_argument('--imu-topic', default=None, metavar='TOPIC',
                        help='instead of a ground-truth pose, a gyro (sensor_msgs/Imu): scores '
                        'heading only; the position figures are null')
    add_imu_delay_argument(parser)
    parser.add_argument('--fuse-imu', default=None, metavar='TOPIC',
                        help='also score each terrain file gyro-aided (row <name>+imu): the '
                        "gyro's heading, as odometry_node with imu_topic (sensor_msgs/Imu)")
    add_imu_mount_argument(parser, "the terrain files' imu_mount.* (which must agree)")
    parser.add_argument('--params', nargs='+', required=True, metavar='A.yaml',
                        help='terrain files to score (each named by its file stem)')
    add_vehicle_groups(parser, 'm, of the ideal drive and of the cmd_vel inverse; '
                       "default the first file's")
    gt = parser.add_argument_group('ground truth')
    add_ground_truth_arguments(gt)
    gt.add_argument('--keep-jumps', action='store_true',
                    help='score across ground-truth jumps (re-localisations, glitches: as '
                    'identify_icr finds them); by default they cut the data like gaps')
    cmd = parser.add_argument_group('commands')
    add_command_arguments(cmd)
    cmd.add_argument('--max-command-age', type=positive, default=0.5, metavar='SECONDS',
                     help='a command older than this is no longer in force')
    score = parser.add_argument_group('scores')
    score.add_argument('--window', type=positive, nargs='+', default=[5.0, 10.0],
                       metavar='SECONDS', help='odometry windows')
    add_window_selection_arguments(score)
    score.add_argument('--horizon', type=positive, default=2.0, metavar='SECONDS',
                       help='prediction horizon')
    score.add_argument('--prediction-dt', type=positive, default=0.05, metavar='SECONDS',
                       help='step of the predictions from the commands (DRIVE: 20 Hz)')
    score.add_argument('--rpe-distance', type=positive, nargs='+', default=[1.0, 10.0],
                       metavar='M', help='path lengths of the relative pose errors')
    score.add_argument('--online', action='store_true',
                       help='also replay the icr_estimator EKF over the bags from each file')
    out = parser.add_argument_group('output')
    out.add_argument('--report', default=None, metavar='OUT.json',
                     help='JSON report with every figure')
    out.add_argument('--plot', default=None, metavar='OUT.png',
                     help='error against window length, and paths')
    out.add_argument('--consistency-plot', default=None, metavar='OUT.png',
                     help='the normalised final position errors against the published 50 %% '
                     'and 95 %% ellipses: NEES histogram and scatter per terrain file')
    out.add_argument('--tum', default=None, metavar='DIR',
                     help='new directory: ground truth and odometry of each piece as TUM '
                     'trajectories, to check the RPE with evo_rpe')
    out.add_argument('--force', action='store_true', help='replace existing output files')
    return parser


# Inputs ----------------------------------------------------------------------------------


def _vehicle(args, models):
    """
    Return the track width of the ideal drive and the sprocket radius.

    Each dimension comes from its option or the files; where both, or several files, give
    it, they must agree (:func:`check_same_vehicle`): a terrain file of another vehicle is
    refused.
    """
    files = [(m.path, dimensions_of(m.values)) for m in models]
    for flag, key in (('--track-width', 'track_width'), ('--sprocket-radius', 'sprocket_radius')):
        option = getattr(args, key)
        first = (flag, {key: option}) if option is not None else next(
            (source for source in files if source[1][key] is not None), None)
        for source in files:
            if first is not None and source is not first:
                check_same_vehicle(first, source, keys=(key,))
    radius = args.sprocket_radius
    if radius is None:
        given = [m.values.get('sprocket_radius') for m in models]
        require_vehicle({'--sprocket-radius': None if None in given else 0.0},
                        'every terrain file')
        radius = given[0]
    track_width = args.track_width
    if track_width is None:
        first = models[0].values
        require_vehicle({'--track-width': first.get('track_width')}, 'the first terrain file')
        track_width = first['track_width']
    for name, value in (('sprocket_radius', radius), ('track_width', track_width)):
        if check_positive(value):
            raise UsageError(f'{name} must be a finite number > 0, got {value!r}')
    return float(track_width), float(radius)


def _check_options(args) -> None:
    if bool(args.ground_truth_topic) == bool(args.imu_topic):
        raise UsageError('give --ground-truth-topic (a pose) or --imu-topic (a gyro, heading '
                         'only), one of them')
    if args.imu_delay != 'auto' and not args.imu_topic:
        raise UsageError('--imu-delay goes with --imu-topic (the gyro as the reference); '
                         "--fuse-imu's gyro is timed by each terrain file's imu_delay")
    if args.imu_topic and args.online:
        raise UsageError('--online needs --ground-truth-topic (the estimator uses poses)')
    if args.imu_topic and args.fuse_imu:
        raise UsageError('--fuse-imu needs --ground-truth-topic (the gyro cannot be both the '
                         'reference and an input)')
    if args.imu_topic and args.consistency_plot:
        raise UsageError('--consistency-plot needs --ground-truth-topic (position errors)')
    if args.prediction_dt >= args.horizon:
        raise UsageError(f'--prediction-dt ({args.prediction_dt:g} s) must be shorter than '
                         f'--horizon ({args.horizon:g} s)')
    for flag, values in (('--window', args.window), ('--rpe-distance', args.rpe_distance)):
        if len(set(values)) != len(values):
            raise UsageError(f'{flag} lists a value twice: {" ".join(f"{v:g}" for v in values)}')


def _read(args, track_width, radius, imu_mount) -> References:
    """Read every bag; return the recordings to score on (their reference's delay taken off)."""
    encoders = encoder_source(args, radius)
    progress = sys.stderr.isatty()
    if args.imu_topic:
        found = [read_recording(bag, encoders, imu_topic=args.imu_topic, progress=progress,
                                imu_mount=imu_mount) for bag in args.bags]
        return gyro_references(args.bags, found, track_width, args.imu_delay)
    # One pass over each bag: the pose, the commands and, with --fuse-imu, the gyro.
    streams = {'ground_truth': ground_truth_source(args), 'imu_topic': args.fuse_imu,
               'commands': command_source(args, track_width)}
    recordings = [read_recording(bag, encoders, progress=progress, imu_mount=imu_mount,
                                 **streams) for bag in args.bags]
    if args.fuse_imu:
        for bag, recording in zip(args.bags, recordings):
            check_gyro_rate(bag, recording, args.fuse_imu)
    found = [(recording, commands_of(recording)) for recording in recordings]
    return pose_references(args.bags, found, args.ground_truth_delay)


# Outputs ---------------------------------------------------------------------------------


def _write_tum(directory: Path, evaluation, names) -> None:
    """
    Write each piece's ground truth and odometry as TUM trajectories (``t x y z qx qy qz qw``).

    ``piece007.ground_truth.tum`` and ``piece007.<model>.tum``: the same times, so that
    ``evo_rpe tum piece007.ground_truth.tum piece007.<model>.tum --delta 1 --delta_unit m``
    finds the report's ``rpe.1m.pieces`` entry of piece 7.
    """
    directory.mkdir()
    for k, piece in enumerate(evaluation.pieces):
        paths = {'ground_truth': piece.truth,
                 **{name: evaluation.paths[name][k] for name in names}}
        for name, path in paths.items():
            half = 0.5 * path[:, 2]
            rows = np.column_stack([piece.t, path[:, 0], path[:, 1], np.zeros(len(path)),
                                    np.zeros(len(path)), np.zeros(len(path)), np.sin(half),
                                    np.cos(half)])
            np.savetxt(directory / f'piece{k:03d}.{name}.tum', rows, fmt='%.9f')


# Main ----------------------------------------------------------------------------------


def _run(args, out) -> int:
    _check_options(args)
    from tracked_kinematics.offline.model_evaluation_plot import (
        check_format, plot_consistency, plot_evaluation)
    fmt = check_format(args.plot) if args.plot else None
    with Outputs(force=args.force) as outputs:
        outputs.add('--report', args.report)
        outputs.add('--plot', args.plot)
        outputs.add('--consistency-plot', args.consistency_plot)
        outputs.add('--tum', args.tum, directory=True)
        try:
            models = read_terrain_models(args.params)
        except OSError as err:
            raise UsageError(f'--params {err.filename}: {err.strerror}') from None
        track_width, radius = _vehicle(args, models)
        # The gyro read as odometry_node reads it, given the terrain files' parameters.
        imu_mount = imu_mount_of(args.imu_mount, [(m.path, m.values) for m in models])
        references = _read(args, track_width, radius, imu_mount)
        settings = ev.Settings(tuple(args.window), args.horizon, args.prediction_dt,
                               tuple(args.rpe_distance), args.max_command_age,
                               not args.keep_jumps, track_width,
                               None if args.all_windows else args.min_speed)
        report = evaluate_models(references, models, settings, sprocket_radius=radius,
                                 command_source=args.command_source, online=args.online,
                                 fuse_imu=args.fuse_imu or False)
        print(report.table(), file=out)
        if args.report:
            outputs.write_text('--report', report.json())
        if args.tum:
            with outputs.path('--tum') as tmp:
                _write_tum(tmp, report.evaluation, report.names)
        if args.plot:
            with outputs.path('--plot') as tmp:
                plot_evaluation(tmp, report.evaluation, report.names, settings.windows,
                                fmt=fmt, min_speed=settings.min_speed)
        if args.consistency_plot:
            with outputs.path('--consistency-plot') as tmp:
                plot_consistency(tmp, report.normalised, settings.windows,
                                 fmt=check_format(args.consistency_plot))
    written = [p for p in (args.report, args.plot, args.consistency_plot, args.tum) if p]
    if written:
        print(f'wrote {", ".join(written)}', file=out)
    return 0


_BAG_SUFFIXES = ('.mcap', '.db3', '.bag')


def bags_out_of_params(argv):
    """
    Return ``argv`` with the bags that follow ``--params`` files moved to the front.

    ``--params`` takes one or more files, so ``--params a.yaml BAG`` would read the bag as a
    terrain file and miss the BAG argument; a directory or a ``.mcap``, ``.db3`` or ``.bag``
    file is never a terrain file, and is taken as a bag.
    """
    argv = list(argv)
    bags, out, i = [], [], 0
    while i < len(argv):
        out.append(argv[i])
        if argv[i] == '--params':
            i += 1
            while i < len(argv) and not argv[i].startswith('-'):
                word = argv[i]
                is_bag = os.path.isdir(word) or word.lower().endswith(_BAG_SUFFIXES)
                (bags if is_bag else out).append(word)
                i += 1
            continue
        i += 1
    return bags + out


def main(argv=None) -> int:
    """Run evaluate_model; return the exit status (see the module docstring)."""
    argv = sys.argv[1:] if argv is None else argv
    return run_main(PROG, _run, build_parser().parse_args(bags_out_of_params(argv)))


if __name__ == '__main__':
    sys.exit(main())
