"""
identify_icr: fit the tread ICRs of a terrain from recorded rosbags.

Reads the track encoders and a ground-truth pose (motion capture, RTK GPS, scan matching)
from one or more bags, fits a motion model to the ground truth (Martinez et al. 2005,
sec. 4.2, by the least-squares method of Fink & Stump, sec. III-A), compares every model on
held-out time blocks, and writes a terrain parameter file for ``--params-file``.

Exit status: 0 success; 2 bad input (missing bag, topic, joint or transform; unreadable
bag; invalid option; an output path that may not be written); 3 too little motion, turning
or straight driving to identify the model; 4 the fit did not converge or gave an invalid
model; 130 / 143 interrupted (SIGINT / SIGTERM). The outputs (YAML, report, plot) are
written together at the end or not at all (docs/output-files.md).

Documentation: docs/tools/identify_icr.md; the models it fits: docs/model.md; the terrain
file it writes: docs/parameters.md.
"""

from __future__ import annotations

import argparse
from datetime import datetime, timezone
import math
from pathlib import Path
import sys

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bags import GroundTruthSource, read_bags
from tracked_kinematics.offline.cli.common import (
    add_bags_argument, add_encoder_arguments, add_force_argument, add_output_argument,
    add_sprocket_radius_argument, ArgumentParser, bounded, encoder_source, HelpFormatter, names,
    report_json, run_main, TRACK_WIDTH, warn, warn_unknown_terrain_keys)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.terrain_file import terrain_text, terrain_values
from tracked_kinematics.params import (
    check_values, icr_from_values, read_params_file, TERRAIN_DEFAULTS, TERRAIN_PARAMS,
    values_from_icr)

PROG = 'identify_icr'
MODEL_CHOICES = ('symmetric',) + ident.FIT_MODELS

EPILOG = """examples:
  identify_icr run1/ run2/ --ground-truth-topic /mocap/pose --output hard_floor.yaml \\
      --sprocket-radius 0.1 --track-width 0.42 --report fit.json --plot fit.png
  identify_icr calib.bag --ground-truth-topic /tf --ground-truth-parent-frame map \\
      --params base.yaml --model general_slip --output grass.yaml --terrain grass
  identify_icr spins/ --ground-truth-topic /mocap/pose --spin-in-place --output sym.yaml
"""


_HEADING_WEIGHT = bounded(0.001, 1000.0, 'm/rad')


def _heading_weight(text: str):
    return None if text == 'auto' else _HEADING_WEIGHT(text)


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of identify_icr."""
    parser = ArgumentParser(
        prog=PROG, description=__doc__.split('\n\n')[1], epilog=EPILOG,
        formatter_class=HelpFormatter)
    add_bags_argument(parser)
    parser.add_argument('--ground-truth-topic', required=True, metavar='TOPIC',
                        help='ground-truth pose of the vehicle: Odometry, PoseStamped, '
                        'PoseWithCovarianceStamped or TFMessage')
    add_output_argument(parser)
    enc = parser.add_argument_group('encoders')
    add_encoder_arguments(enc)
    veh = parser.add_argument_group('vehicle')
    add_sprocket_radius_argument(veh)
    veh.add_argument('--track-width', type=TRACK_WIDTH, default=None, metavar='L',
                     help=f'm; default from --params, else {TERRAIN_DEFAULTS["track_width"]}')
    veh.add_argument('--params', default=None, metavar='BASE.yaml',
                     help='terrain file to start from: vehicle values, starting point, fixed '
                     'scales of --model icr; its other parameters are copied to the output')
    gt = parser.add_argument_group('ground truth')
    gt.add_argument('--ground-truth-parent-frame', default='', metavar='FRAME',
                    help='TFMessage: fixed frame (default: the only parent of the child)')
    gt.add_argument('--ground-truth-child-frame', default='base_link', metavar='FRAME',
                    help='TFMessage: the tracked frame')
    gt.add_argument('--ground-truth-offset', type=bounded(-10.0, 10.0), nargs=3,
                    default=(0.0, 0.0, 0.0), metavar=('X', 'Y', 'YAW'),
                    help='pose of the tracked body in base_link (m, m, rad; each within '
                    '+-10)')
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
    ev = parser.add_argument_group('evaluation')
    ev.add_argument('--holdout', type=bounded(0.0, 0.9), default=0.2, metavar='FRACTION',
                    help='fraction of time blocks held out to compare the models (0: none)')
    ev.add_argument('--holdout-block', type=bounded(1.0, 3600.0, 's'), default=30.0,
                    metavar='SECONDS',
                    help='duration of a time block')
    ev.add_argument('--window', type=bounded(0.1, 3600.0, 's'), default=10.0, metavar='SECONDS',
                    help='duration of the held-out evaluation windows')
    ev.add_argument('--compare', type=names, default=','.join(ident.COMPARE_MODELS),
                    metavar='M1,M2',
                    help='models compared on the held-out blocks')
    out = parser.add_argument_group('output')
    out.add_argument('--terrain', default=None, metavar='NAME',
                     help='terrain name written to the file')
    out.add_argument('--report', default=None, metavar='OUT.json',
                     help='JSON report: values, chi, e, cost, error statistics')
    out.add_argument('--plot', default=None, metavar='OUT.png',
                     help='paths (ground truth, ideal, fitted) and residual distributions')
    add_force_argument(out)
    return parser


# Inputs ----------------------------------------------------------------------------------


def _vehicle(args):
    """Read the base terrain values and check the vehicle dimensions."""
    base_values = read_params_file(args.params) if args.params else {}
    if args.params:
        warn_unknown_terrain_keys(PROG, args.params, base_values)
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


def _sources(args, radius):
    encoders = encoder_source(args, radius)
    ground_truth = GroundTruthSource(
        topic=args.ground_truth_topic, parent_frame=args.ground_truth_parent_frame,
        child_frame=args.ground_truth_child_frame, offset=tuple(args.ground_truth_offset))
    return encoders, ground_truth


# Outputs ---------------------------------------------------------------------------------


def _finite_or_none(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _stats(stats):
    if stats is None:
        return None
    return {k: _finite_or_none(float(getattr(stats, k))) if k != 'n' else stats.n
            for k in ('n', 'position_mean', 'position_p90', 'heading_mean', 'heading_p90')}


def _fit_summary(result):
    return {
        'model': result.model.name, 'method': result.method,
        'parameters': result.params,
        'standard_errors': {n: _finite_or_none(float(s))
                            for n, s in zip(result.model.param_names, result.std)},
        'cost': result.cost, 'loss': result.loss, 'f_scale': result.f_scale,
        'heading_weight': result.heading_weight, 'rms_position': result.rms_position,
        'rms_heading': result.rms_heading, 'segments': result.segments,
        'inliers': result.inliers, 'evaluations': result.nfev, 'seconds': result.seconds,
    }


def _icr_summary(icr):
    return {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
            'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
            'chi': icr.chi, 'eccentricity': icr.eccentricity}


def _holdout_summary(result):
    if result.holdout is None:
        return None
    ideal = result.evaluation('ideal')
    models = {}
    for e in result.evaluations:
        entry = {'segments': _stats(e.segments), 'windows': _stats(e.windows)}
        if e.fit is not None:
            entry['parameters'] = e.fit.params
        if e.error:
            entry['error'] = e.error
        if ideal is not None and ideal.segments is not None and e.segments is not None:
            entry['improvement_pct'] = {
                'segments': e.segments.improvement_over(ideal.segments),
                'windows': e.windows.improvement_over(ideal.windows)}
        models[e.name] = entry
    return {'blocks': [[int(r), float(a), float(b)] for r, a, b in result.holdout.blocks],
            'total_blocks': result.holdout.total_blocks, 'window': result.window,
            'models': models}


def _recordings_summary(recordings):
    return [{'bag': r.name, 'duration': r.duration, 'encoder_samples': len(r.enc_t),
             'ground_truth_samples': len(r.gt_t)} for r in recordings]


def _yaml_values(base_values, icr, radius, terrain, extras):
    """Merge base values without the old terrain name and record, the ICR model, its record."""
    fitted = values_from_icr(icr, radius)
    if terrain:
        fitted['terrain'] = terrain
    return terrain_values(base_values, fitted, record='identification', extras=extras,
                          check=icr_from_values, drop=('terrain',))


def _print_table(result, recordings, out):
    exc = result.excitation
    duration = sum(r.duration for r in recordings)
    print(f'{PROG}: {len(recordings)} bag(s), {duration:.0f} s, {exc.distance:.1f} m driven, '
          f'{exc.turning:.1f} rad turned; {exc.moving} moving segments of '
          f'{result.segment_length or "ground-truth period"} s', file=out)
    fitted = result.fit
    params = ', '.join(f'{n} {v:.4f}' for n, v in fitted.params.items())
    icr = result.icr
    print(f'{fitted.model.name} ({fitted.method}): {params}', file=out)
    print(f'written ICR model ({result.icr_source}): y_left {icr.y_left:.4f} m, y_right '
          f'{icr.y_right:.4f} m, x {icr.x:.4f} m, scales {icr.scale_left:.4f} / '
          f'{icr.scale_right:.4f}; chi {icr.chi:.3f}, e {icr.eccentricity:.3f}', file=out)
    print(f'fit: rms {1000 * fitted.rms_position:.1f} mm, '
          f'{math.degrees(fitted.rms_heading):.2f} deg over {fitted.inliers}/{fitted.segments} '
          f'inlier segments, heading weight {fitted.heading_weight:.2f} m/rad', file=out)
    if result.holdout is None:
        print('hold-out: too little data to hold any out (need 3 blocks)', file=out)
        return
    ideal = result.evaluation('ideal')
    n_seg = next((e.segments.n for e in result.evaluations if e.segments), 0)
    n_win = next((e.windows.n for e in result.evaluations if e.windows), 0)
    print(f'\nhold-out: {len(result.holdout.blocks)} of {result.holdout.total_blocks} blocks, '
          f'{n_seg} segments, {n_win} windows of {result.window:.0f} s; errors mean / p90',
          file=out)
    head = (f'{"model":<22}{"segment pos (mm)":>18}{"heading (deg)":>16}'
            f'{"window pos (m)":>17}{"heading (deg)":>16}{"vs ideal":>14}')
    print(head, file=out)
    for e in result.evaluations:
        if e.segments is None:
            print(f'{e.name:<22}  failed: {e.error}', file=out)
            continue
        s, w = e.segments, e.windows
        better = ''
        if ideal is not None and ideal.windows is not None and e.name != 'ideal':
            better = f'{e.windows.improvement_over(ideal.windows)["position"]:+.0f} %'
        print(f'{e.name:<22}{1000 * s.position_mean:>8.1f} /{1000 * s.position_p90:>7.1f}'
              f'{math.degrees(s.heading_mean):>8.2f} /{math.degrees(s.heading_p90):>6.2f}'
              f'{w.position_mean:>9.3f} /{w.position_p90:>6.3f}'
              f'{math.degrees(w.heading_mean):>8.2f} /{math.degrees(w.heading_p90):>6.2f}'
              f'{better:>14}', file=out)


# Main ----------------------------------------------------------------------------------


def _outputs(args) -> Outputs:
    """Check every output path before any work (docs/output-files.md)."""
    outputs = Outputs(force=args.force)
    outputs.add('--output', args.output)
    outputs.add('--report', args.report)
    if args.plot and args.spin_in_place:
        warn(PROG, '--plot is not drawn with --spin-in-place')
    elif args.plot:
        from tracked_kinematics.offline.plots import check_format
        outputs.add('--plot', args.plot)
        check_format('--plot', args.plot)
    outputs.refuse_inputs('BAG', args.bags)
    # --output may update the terrain file it starts from (it exists: with --force).
    outputs.refuse_inputs('--params', [args.params], allow=('--output',))
    return outputs


def _run(args, out) -> int:
    with _outputs(args) as outputs:
        _identify(args, out, outputs)
    print(f'wrote {", ".join(str(p) for p in outputs.targets)}', file=out)
    return 0


def _identify(args, out, outputs) -> None:
    unknown = [m for m in args.compare if m not in ident.COMPARE_MODELS]
    if unknown:
        raise UsageError(f'--compare: unknown model {", ".join(unknown)}; choose from '
                         f'{", ".join(ident.COMPARE_MODELS)}')
    base_values, base, track_width, radius = _vehicle(args)
    encoders, ground_truth = _sources(args, radius)
    recordings = read_bags(args.bags, encoders, ground_truth, progress=sys.stderr.isatty())
    date = datetime.now(timezone.utc).isoformat(timespec='seconds')
    bags = [str(Path(b).resolve()) for b in args.bags]
    report = {'tool': PROG, 'date': date, 'bags': bags, 'track_width': track_width,
              'sprocket_radius': radius, 'recordings': _recordings_summary(recordings)}
    if args.spin_in_place:
        scales = (base.scale_left, base.scale_right) if base else (1.0, 1.0)
        spin = ident.spin_in_place(recordings, track_width, scales)
        icr = spin.icr(track_width, scales)
        extras = {'model': 'spin_in_place', 'date': date, 'bags': bags,
                  'spin_runs': len(spin.runs), 'chi': spin.chi, 'chi_std': spin.chi_std}
        values = _yaml_values(base_values, icr, radius, args.terrain, extras)
        report.update({'mode': 'spin_in_place', 'chi': spin.chi, 'chi_std': spin.chi_std,
                       'runs': spin.runs, 'icr': _icr_summary(icr)})
        print(f'{PROG}: {len(spin.runs)} spin-in-place run(s): chi = {spin.chi:.4f} '
              f'(std {spin.chi_std:.4f}); ICRs at +-{icr.y_left:.4f} m', file=out)
    else:
        model = 'effective_wheel_base' if args.model == 'symmetric' else args.model
        if args.method == 'lsq' and args.max_nfev is not None and args.max_nfev < 0:
            # Least squares refuses a negative budget; 0 takes the default one.
            raise UsageError(f'--max-nfev must not be negative, got {args.max_nfev}')
        result = ident.identify(
            recordings, model, track_width, base=base, method=args.method,
            segment_length=args.segment_length or None, heading_weight=args.heading_weight,
            loss=args.loss, min_travel=args.min_travel, holdout=args.holdout,
            holdout_block=args.holdout_block, window=args.window, compare=args.compare,
            max_nfev=args.max_nfev)
        fitted, icr = result.fit, result.icr
        extras = {'model': fitted.model.name, 'method': fitted.method, 'date': date,
                  'bags': bags, 'segments': fitted.segments,
                  'segment_length': float(args.segment_length),
                  'heading_weight': fitted.heading_weight, 'cost': fitted.cost,
                  'rms_position': fitted.rms_position, 'rms_heading': fitted.rms_heading,
                  'chi': icr.chi, 'eccentricity': icr.eccentricity,
                  'icr_source': result.icr_source}
        extras.update({f'parameters.{n}': v for n, v in fitted.params.items()})
        chosen = result.evaluation(result.icr_source)
        ideal = result.evaluation('ideal')
        if chosen and ideal and chosen.windows and ideal.windows:
            gain = chosen.windows.improvement_over(ideal.windows)
            extras['holdout_position_improvement_pct'] = gain['position']
            extras['holdout_heading_improvement_pct'] = gain['heading']
        values = _yaml_values(base_values, icr, radius, args.terrain, extras)
        report.update({
            'mode': 'segments', 'model': fitted.model.name, 'icr_source': result.icr_source,
            'icr': _icr_summary(icr), 'fit': _fit_summary(fitted),
            'excitation': vars(result.excitation), 'holdout': _holdout_summary(result),
            'seconds': result.seconds})
        _print_table(result, recordings, out)
    note = ''
    if args.model in ('general_slip', 'adaptive_icr') and not args.spin_in_place:
        note = (f'The {args.model} model has no constant ICRs: icr.* and scale.* are the '
                f'{values["identification.icr_source"]} fit of the same data;\nthe '
                f'{args.model} parameters are under identification.parameters.')
    outputs.write_text('--output', terrain_text(values, tool=PROG, date=date, note=note))
    if '--report' in outputs:
        outputs.write_text('--report', report_json(report))
    if '--plot' in outputs:
        from tracked_kinematics.offline.plots import plot_identification
        # The moving segments the fit used: those of --min-travel.
        segments = ident.build_segments(recordings, result.segment_length)
        with outputs.path('--plot') as tmp:
            plot_identification(tmp, recordings, result,
                                segments.select(segments.travel >= args.min_travel))


def main(argv=None) -> int:
    """Run identify_icr; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
