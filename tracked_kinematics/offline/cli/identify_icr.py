"""
identify_icr: fit the tread ICRs of a terrain from recorded rosbags.

Reads the track encoders and a ground-truth pose (motion capture, RTK GPS, scan matching)
from one or more bags, removes the delay of the ground-truth stamps behind the encoders,
fits a motion model to the ground truth (Martinez et al. 2005, sec. 4.2, by the
least-squares method of Fink & Stump, sec. III-A), compares every model and a tuned
diff_drive_controller on held-out time blocks, and writes a terrain parameter file for
``--params-file``.

Exit status: 0 success; 2 bad input (missing bag, topic, joint or transform; unreadable
bag; invalid option; an output path that may not be written); 3 too little motion, turning
or straight driving to identify the model, or a parameter determined but uncertain (without
--accept-uncertain); 4 the fit did not converge or gave an invalid model; 130 / 143
interrupted (SIGINT / SIGTERM). The outputs (YAML, report, plot) are written together at the
end or not at all (docs/output-files.md).

Documentation: docs/tools/identify_icr.md; the models it fits: docs/model.md; the terrain
file it writes: docs/parameters.md.
"""

from __future__ import annotations

import argparse
import sys

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bags import read_bags
from tracked_kinematics.offline.bags.reference_reader import read_reference_bag
from tracked_kinematics.offline.cli.common import (
    add_base_file_argument, add_ground_truth_arguments, add_output_argument,
    add_report_arguments, add_vehicle_groups, add_window_selection_arguments, bounded,
    encoder_source, ground_truth_source, identification_parser, min_speed, names,
    read_base_file, report_json, require_vehicle, run_main, warn, write_together)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.identification import (
    icr_from_poses, icr_from_references, TOOL as PROG)
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.terrain_file import terrain_text
from tracked_kinematics.params import (
    check_values, icr_from_values, TERRAIN_DEFAULTS, TERRAIN_PARAMS)

MODEL_CHOICES = ('symmetric',) + ident.FIT_MODELS

EPILOG = """examples:
  identify_icr run1/ run2/ --ground-truth-topic /mocap/pose --output hard_floor.yaml \\
      --sprocket-radius 0.1 --track-width 0.42 --report fit.json --plot fit.png
  identify_icr calib.bag --ground-truth-topic /tf --ground-truth-parent-frame map \\
      --params base.yaml --model general_slip --output grass.yaml --terrain grass
  identify_icr spins/ --ground-truth-topic /mocap/pose --spin-in-place --output sym.yaml
  identify_icr drive/ --imu-topic /imu/data --output grass.yaml --sprocket-radius 0.3 \\
      --track-width 1.08       # no ground truth: the gyro fits chi and the scale ratio
  identify_icr drive/ --imu-topic /imu/data --gnss-topic /gps/fix --output grass.yaml \\
      --params grass_base.yaml  # GNSS for the distance scale
"""


_HEADING_WEIGHT = bounded(0.001, 1000.0, 'm/rad')


def _heading_weight(text: str):
    return None if text == 'auto' else _HEADING_WEIGHT(text)


def _delay(text: str):
    if text == 'auto':
        return text
    return bounded(-5.0, 5.0, 's')(text)


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of identify_icr."""
    parser = identification_parser(PROG, __doc__, EPILOG,
                                   ' (required unless --imu-topic is given)')
    add_output_argument(parser)
    veh = add_vehicle_groups(parser, 'm; default from --params (required without '
                             'it: there is no default vehicle)')
    add_base_file_argument(veh, 'vehicle values, starting point, fixed scales of --model icr')
    add_ground_truth_arguments(parser.add_argument_group('ground truth'))
    ref = parser.add_argument_group(
        'no ground truth (docs/tools/identify_icr.md#no-ground-truth-use-the-imu)')
    ref.add_argument('--imu-topic', default=None, metavar='TOPIC',
                     help='sensor_msgs/Imu: the gyro as the heading reference (alone or with '
                     '--ground-truth-topic); fits chi and the scale ratio, holds the rest')
    ref.add_argument('--imu-delay', type=_delay, default='auto', metavar='auto|SECONDS',
                     help='delay of the IMU stamps behind the encoders: auto estimates it')
    ref.add_argument('--gnss-topic', default=None, metavar='TOPIC',
                     help='sensor_msgs/NavSatFix (status >= 0) or nav_msgs/Odometry: '
                     'positions for the distance scale (and icr.x where its noise allows)')
    ref.add_argument('--gnss-antenna', type=bounded(-10.0, 10.0, 'm'), nargs=2,
                     default=(0.0, 0.0), metavar=('X', 'Y'),
                     help='position of the GNSS antenna in base_link, m (an offset antenna '
                     'would otherwise pass for icr.x)')
    ref.add_argument('--straight-distance', type=bounded(0.1, 100000.0, 'm'), default=None,
                     metavar='M',
                     help='the bags are one straight drive of M metres (measured): fixes the '
                     'distance scale')
    fit = parser.add_argument_group('fit')
    fit.add_argument('--model', choices=MODEL_CHOICES, default='icr_scales',
                     help='model to fit and write')
    fit.add_argument('--method', choices=ident.METHODS, default='lsq',
                     help='lsq: least squares with analytic sensitivities; de: differential '
                     'evolution (global, derivative-free, slow), for comparison')
    fit.add_argument('--spin-in-place', action='store_true',
                     help='instead of fitting segments, measure the steering efficiency of the '
                     'spin-in-place runs (Martinez eq. 16) and write the symmetric model')
    fit.add_argument('--segment-length', type=bounded(0.01, 600.0, 's', zero=True), default=1.0,
                     metavar='SECONDS',
                     help='segment duration; 0 cuts at every ground-truth sample')
    fit.add_argument('--heading-weight', type=_heading_weight,
                     default=ident.DEFAULT_HEADING_WEIGHT, metavar='M_PER_RAD|auto',
                     help='lambda of the cost: metres that 1 rad of heading error counts as; '
                     'auto balances the noise of position and heading residuals')
    fit.add_argument('--loss', choices=ident.LOSSES, default='soft_l1',
                     help='robust loss against ground-truth glitches')
    fit.add_argument('--min-travel', type=bounded(0.0, 100.0, 'm'), default=0.01, metavar='M',
                     help='segments whose tracks travel less are stationary and left out')
    fit.add_argument('--max-nfev', type=bounded(0, 1_000_000, integer=True), default=None,
                     metavar='N', help='evaluation budget of one optimisation round')
    fit.add_argument('--accept-uncertain', action='store_true',
                     help='write a fit whose parameters the data determine, but with standard '
                     'errors beyond the limits (noisy ground truth); they are reported')
    ev = parser.add_argument_group('evaluation')
    ev.add_argument('--holdout', type=bounded(0.0, 0.9), default=0.2, metavar='FRACTION',
                    help='fraction of time blocks held out to compare the models (0: none); '
                    'short data hold every block out in turn')
    ev.add_argument('--holdout-block', type=bounded(1.0, 3600.0, 's'), default=30.0,
                    metavar='SECONDS',
                    help='longest time block, s of driving (shorter on short data)')
    ev.add_argument('--window', type=bounded(0.1, 3600.0, 's'), default=10.0, metavar='SECONDS',
                    help='duration of the held-out evaluation windows')
    ev.add_argument('--compare', type=names, default=','.join(ident.COMPARE_MODELS),
                    metavar='M1,M2',
                    help='models compared on the held-out blocks')
    add_window_selection_arguments(ev)
    out = parser.add_argument_group('output')
    out.add_argument('--terrain', default=None, metavar='NAME',
                     help='terrain name written to the file')
    add_report_arguments(out, 'JSON report: values, chi, e, cost, error statistics',
                         'paths (ground truth, ideal, fitted) and residual distributions')
    return parser


# Inputs ----------------------------------------------------------------------------------


def _vehicle(args):
    """Read the base terrain values and check the vehicle dimensions."""
    base_values = read_base_file(PROG, args.params)
    merged = {**TERRAIN_DEFAULTS, **{k: v for k, v in base_values.items()
                                     if k in TERRAIN_DEFAULTS}}
    if args.track_width is not None:
        merged['track_width'] = args.track_width
    if args.sprocket_radius is not None:
        merged['sprocket_radius'] = args.sprocket_radius
    # The values the fallback below builds a model from: a number each (not 'abc').
    problems = check_values([s for s in TERRAIN_PARAMS if s.name in (
        'track_width', 'sprocket_radius', 'scale.left', 'scale.right')], merged)
    if problems:
        raise UsageError(f'{args.params or "vehicle"}: {"; ".join(problems)}')
    require_vehicle({'--track-width': args.track_width if args.track_width is not None
                     else base_values.get('track_width'),
                     '--sprocket-radius': args.sprocket_radius if args.sprocket_radius is not None
                     else base_values.get('sprocket_radius')})
    base = None
    if args.params:
        try:
            base = icr_from_values(merged)
        except InvalidParameters:
            # The ICRs of a file made for another track width: keep its scales only.
            try:
                base = IcrParams.ideal(merged['track_width'])
                base = IcrParams(base.track_width, base.y_left, base.y_right, 0.0,
                                 merged['scale.left'], merged['scale.right'])
            except ValueError as err:   # the user's track width or scales
                raise UsageError(str(err)) from None
    return base_values, base, float(merged['track_width']), float(merged['sprocket_radius'])


def _uses_references(args) -> bool:
    return bool(args.imu_topic or args.gnss_topic or args.straight_distance is not None)


def _check_options(args) -> None:
    """Refuse options that contradict each other or that no fit can serve, before any work."""
    if _uses_references(args):
        _check_reference_options(args)
        return
    if not args.ground_truth_topic:
        raise UsageError('give --ground-truth-topic (a pose) or --imu-topic (a gyro)')
    unknown = [m for m in args.compare if m not in ident.COMPARE_MODELS]
    if unknown:
        raise UsageError(f'--compare: unknown model {", ".join(unknown)}; choose from '
                         f'{", ".join(ident.COMPARE_MODELS)}')
    if not args.spin_in_place and args.method == 'lsq' and args.max_nfev is not None \
            and args.max_nfev < 0:
        # Least squares refuses a negative budget; 0 takes the default one.
        raise UsageError(f'--max-nfev must not be negative, got {args.max_nfev}')


def _check_reference_options(args) -> None:
    """Refuse option combinations the reference calibration cannot serve."""
    if args.gnss_topic and not (args.imu_topic or args.ground_truth_topic):
        raise UsageError('--gnss-topic gives positions only: give --imu-topic (the heading) '
                         'as well')
    if args.straight_distance is not None and not args.imu_topic:
        raise UsageError('--straight-distance needs --imu-topic (to check that the drive is '
                         'straight)')
    if args.straight_distance is not None and args.gnss_topic:
        raise UsageError('give --straight-distance or --gnss-topic for the distance, not both')
    if args.spin_in_place:
        raise UsageError('--spin-in-place needs --ground-truth-topic, not --imu-topic')
    if args.model not in ('icr_scales', 'icr', 'symmetric'):
        raise UsageError(f'--model {args.model} needs a ground-truth pose; with --imu-topic '
                         'the constant-ICR model is fitted')


def _delay_option(value):
    return value if value == 'auto' else float(value)


def _from_poses(args, base_values, base, track_width, radius):
    """Read the bags with their ground-truth pose and identify."""
    recordings = read_bags(args.bags, encoder_source(args, radius), ground_truth_source(args),
                           progress=sys.stderr.isatty())
    return icr_from_poses(
        recordings, args.bags, track_width, radius, base=base, base_values=base_values,
        terrain=args.terrain, model=args.model, spin=args.spin_in_place, method=args.method,
        segment_length=args.segment_length, heading_weight=args.heading_weight,
        loss=args.loss, min_travel=args.min_travel, holdout=args.holdout,
        holdout_block=args.holdout_block, window=args.window, compare=args.compare,
        max_nfev=args.max_nfev, ground_truth_delay=args.ground_truth_delay,
        accept_uncertain=args.accept_uncertain, min_speed=min_speed(args))


def _from_references(args, base_values, base, track_width, radius):
    """Read the bags with their gyro, GNSS or pose references and calibrate."""
    encoders = encoder_source(args, radius)
    pose = ground_truth_source(args) if args.ground_truth_topic else None
    recordings = [read_reference_bag(b, encoders, args.imu_topic, args.gnss_topic, pose,
                                     progress=sys.stderr.isatty()) for b in args.bags]
    return icr_from_references(
        recordings, args.bags, track_width, radius, base=base, base_values=base_values,
        terrain=args.terrain, model=args.model, imu_delay=_delay_option(args.imu_delay),
        pose_delay=_delay_option(args.ground_truth_delay),
        segment_length=args.segment_length or 1.0, straight_distance=args.straight_distance,
        gnss_antenna=args.gnss_antenna)


# Outputs ---------------------------------------------------------------------------------


def _outputs(args) -> Outputs:
    """Check every output path before any work (docs/output-files.md)."""
    outputs = Outputs(force=args.force)
    outputs.add('--output', args.output)
    outputs.add('--report', args.report)
    if args.plot and (args.spin_in_place or _uses_references(args)):
        warn(PROG, '--plot is not drawn with --spin-in-place or without a ground-truth pose')
    elif args.plot:
        from tracked_kinematics.offline.plots import check_format
        outputs.add('--plot', args.plot)
        check_format('--plot', args.plot)
    outputs.refuse_inputs('BAG', args.bags)
    # --output may update the terrain file it starts from (it exists: with --force).
    outputs.refuse_inputs('--params', [args.params], allow=('--output',))
    return outputs


def _identify(args, out, outputs) -> None:
    """Identify, print the table, write the terrain file, the report and the plot."""
    _check_options(args)
    vehicle = _vehicle(args)
    found = (_from_references if _uses_references(args) else _from_poses)(args, *vehicle)
    print(found.text, file=out)
    outputs.write_text('--output', terrain_text(found.values, tool=PROG, date=found.date,
                                                note=found.note))
    if '--report' in outputs:
        outputs.write_text('--report', report_json(found.report))
    if '--plot' in outputs:
        from tracked_kinematics.offline.plots import plot_identification
        result = found.identification
        # The moving segments the fit used: those of --min-travel, delay removed.
        segments = ident.build_segments(result.recordings, result.segment_length)
        with outputs.path('--plot') as tmp:
            plot_identification(tmp, result.recordings, result,
                                segments.select(segments.travel >= args.min_travel))


def _run(args, out) -> int:
    return write_together(_outputs(args), lambda outputs: _identify(args, out, outputs), out)


def main(argv=None) -> int:
    """Run identify_icr; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
