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
or straight driving to identify the model, a parameter determined but uncertain (without
--accept-uncertain), or a gyro reference that cannot be timed (give --imu-delay); 4 the fit
did not converge or gave an invalid model; 130 / 143 interrupted (SIGINT / SIGTERM). The
outputs (YAML, report, plot) are written together at the
end or not at all (docs/output-files.md).

Documentation: docs/tools/identify_icr.md; the models it fits: docs/model.md; the terrain
file it writes: docs/parameters.md.
"""

from __future__ import annotations

import argparse
import sys

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.identify.procedure import IdentifyOptions
from tracked_kinematics.offline.cli.common import (
    add_base_file_argument, add_ground_truth_arguments, add_imu_delay_argument,
    add_imu_mount_argument, add_output_argument, add_plot_output, add_report_arguments,
    add_vehicle_groups, add_window_selection_arguments, bounded, encoder_settings,
    ground_truth_source, identification_parser, min_speed, names, refuse_another_vehicle,
    run_main, warn, write_together)
from tracked_kinematics.offline.identification import (
    fit, FitOptions, MODELS as MODEL_CHOICES, TOOL as PROG, write_fit)
from tracked_kinematics.offline.outputs import Outputs

DEFAULT = IdentifyOptions()
"""The defaults of the fit options."""

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
    add_imu_mount_argument(ref, "--params' imu_mount.*")
    add_imu_delay_argument(ref)
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
    group = parser.add_argument_group('fit')
    group.add_argument('--model', choices=MODEL_CHOICES, default='icr_scales',
                       help='model to fit and write')
    group.add_argument('--method', choices=ident.METHODS, default=DEFAULT.method,
                       help='lsq: least squares with analytic sensitivities; de: differential '
                       'evolution (global, derivative-free, slow), for comparison')
    group.add_argument('--spin-in-place', action='store_true',
                       help='instead of fitting segments, measure the steering efficiency of the '
                       'spin-in-place runs (Martinez eq. 16) and write the symmetric model')
    group.add_argument('--segment-length', type=bounded(0.01, 600.0, 's', zero=True),
                       default=DEFAULT.segment_length, metavar='SECONDS',
                       help='segment duration; 0 cuts at every ground-truth sample')
    group.add_argument('--heading-weight', type=_heading_weight,
                       default=DEFAULT.heading_weight, metavar='M_PER_RAD|auto',
                       help='lambda of the cost: metres that 1 rad of heading error counts as; '
                       'auto balances the noise of position and heading residuals')
    group.add_argument('--loss', choices=ident.LOSSES, default=DEFAULT.loss,
                       help='robust loss against ground-truth glitches')
    group.add_argument('--min-travel', type=bounded(0.0, 100.0, 'm'),
                       default=DEFAULT.min_travel, metavar='M',
                       help='segments whose tracks travel less are stationary and left out')
    group.add_argument('--max-nfev', type=bounded(0, 1_000_000, integer=True),
                       default=DEFAULT.max_nfev, metavar='N',
                       help='evaluation budget of one optimisation round')
    group.add_argument('--accept-uncertain', action='store_true',
                       help='write a fit whose parameters the data determine, but with standard '
                       'errors beyond the limits (noisy ground truth); they are reported')
    ev = parser.add_argument_group('evaluation')
    ev.add_argument('--holdout', type=bounded(0.0, 0.9), default=DEFAULT.holdout,
                    metavar='FRACTION',
                    help='fraction of time blocks held out to compare the models (0: none); '
                    'short data hold every block out in turn')
    ev.add_argument('--holdout-block', type=bounded(1.0, 3600.0, 's'),
                    default=DEFAULT.holdout_block, metavar='SECONDS',
                    help='longest time block, s of driving (shorter on short data)')
    ev.add_argument('--window', type=bounded(0.1, 3600.0, 's'), default=DEFAULT.window,
                    metavar='SECONDS',
                    help='duration of the held-out evaluation windows')
    ev.add_argument('--compare', type=names, default=','.join(DEFAULT.compare),
                    metavar='M1,M2',
                    help='models compared on the held-out blocks')
    add_window_selection_arguments(ev)
    out = parser.add_argument_group('output')
    out.add_argument('--terrain', default=None, metavar='NAME',
                     help='terrain name written to the file')
    add_report_arguments(out, 'JSON report: values, chi, e, cost, error statistics',
                         'paths (ground truth, ideal, fitted) and residual distributions')
    return parser


def options_from_args(args) -> FitOptions:
    """Return the options of the fit from the parsed command line (checked by the parser)."""
    return FitOptions(
        bags=tuple(args.bags), params=args.params, track_width=args.track_width,
        sprocket_radius=args.sprocket_radius, encoders=encoder_settings(args),
        ground_truth=ground_truth_source(args) if args.ground_truth_topic else None,
        imu_topic=args.imu_topic, imu_delay=args.imu_delay, gnss_topic=args.gnss_topic,
        imu_mount=None if args.imu_mount is None else tuple(args.imu_mount),
        gnss_antenna=tuple(args.gnss_antenna), straight_distance=args.straight_distance,
        model=args.model, spin_in_place=args.spin_in_place, terrain=args.terrain,
        identify=IdentifyOptions(
            method=args.method, segment_length=args.segment_length,
            heading_weight=args.heading_weight, loss=args.loss, min_travel=args.min_travel,
            holdout=args.holdout, holdout_block=args.holdout_block, window=args.window,
            compare=tuple(args.compare), max_nfev=args.max_nfev,
            ground_truth_delay=args.ground_truth_delay,
            accept_uncertain=args.accept_uncertain, min_speed=min_speed(args)))


def _outputs(args, options: FitOptions) -> Outputs:
    """Check every output path before any work (docs/output-files.md)."""
    outputs = Outputs(force=args.force)
    outputs.add('--output', args.output)
    outputs.add('--report', args.report)
    if args.plot and (options.spin_in_place or options.uses_references):
        warn(PROG, '--plot is not drawn with --spin-in-place or without a ground-truth pose')
    else:
        add_plot_output(outputs, args.plot)
    outputs.refuse_inputs('BAG', args.bags)
    # --output may update the terrain file it starts from (it exists: with --force).
    outputs.refuse_inputs('--params', [args.params], allow=('--output',))
    return outputs


def _run(args, out) -> int:
    refuse_another_vehicle(args.params, None, args.track_width, args.sprocket_radius)
    options = options_from_args(args)

    def work(outputs):
        found = fit(options)
        print(found.text, file=out)
        write_fit(found, outputs, options)
    return write_together(_outputs(args, options), work, out)


def main(argv=None) -> int:
    """Run identify_icr; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
