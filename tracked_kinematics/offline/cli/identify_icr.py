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
from datetime import datetime, timezone
import math
from pathlib import Path
import sys

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bags import read_bags
from tracked_kinematics.offline.cli.common import (
    add_bags_argument, add_encoder_arguments, add_force_argument, add_ground_truth_arguments,
    add_ground_truth_topic_argument, add_output_argument, add_sprocket_radius_argument,
    ArgumentParser, bounded, encoder_source, ground_truth_source, HelpFormatter, names,
    read_base_file, report_json, require_vehicle, run_main, TRACK_WIDTH, warn)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.offline.terrain_file import terrain_text, terrain_values
from tracked_kinematics.params import (
    check_values, icr_from_values, TERRAIN_DEFAULTS, TERRAIN_PARAMS, values_from_icr)

PROG = 'identify_icr'
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
    parser = ArgumentParser(
        prog=PROG, description=__doc__.split('\n\n')[1], epilog=EPILOG,
        formatter_class=HelpFormatter)
    add_bags_argument(parser)
    add_ground_truth_topic_argument(parser, required=False,
                                    extra=' (required unless --imu-topic is given)')
    add_output_argument(parser)
    enc = parser.add_argument_group('encoders')
    add_encoder_arguments(enc)
    veh = parser.add_argument_group('vehicle')
    add_sprocket_radius_argument(veh)
    veh.add_argument('--track-width', type=TRACK_WIDTH, default=None, metavar='L',
                     help='m; default from --params (required without it: there is no '
                     'default vehicle)')
    veh.add_argument('--params', default=None, metavar='BASE.yaml',
                     help='terrain file to start from: vehicle values, starting point, fixed '
                     'scales of --model icr; its other parameters are copied to the output')
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


def _sources(args, radius):
    return encoder_source(args, radius), ground_truth_source(args)


# Outputs ---------------------------------------------------------------------------------


def _finite_or_none(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _stats(stats):
    if stats is None:
        return None
    if stats.n == 0:
        return {'n': 0, 'position_mean': None, 'position_p90': None, 'heading_mean': None,
                'heading_p90': None}
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
        'rms_heading': result.rms_heading, 'residual_sigma': result.sigma,
        'segments': result.segments, 'inliers': result.inliers, 'evaluations': result.nfev,
        'seconds': result.seconds,
    }


def _icr_summary(icr):
    return {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
            'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
            'chi': icr.chi, 'eccentricity': icr.eccentricity}


def _delay_summary(delay, each=()):
    summary = {'delay': delay.delay, 'std': _finite_or_none(float(delay.std)),
               'uncertainty': delay.uncertainty, 'determined': delay.determined,
               'problem': delay.problem, 'correlation': delay.correlation,
               'intervals': delay.intervals, 'excluded': delay.excluded,
               'windows': delay.windows, 'search': list(delay.search)}
    if each:
        summary['per_bag'] = [{'delay': e.delay, 'std': e.std, 'uncertainty': e.uncertainty}
                              for e in each]
    return summary


def _ddc_summary(result, radius):
    if result.ddc is None:
        return {'error': result.ddc_error}
    fit = result.ddc
    return {'parameters': ident.ddc_parameters(fit.p, fit.model.track_width, radius),
            'standard_errors': {n: _finite_or_none(float(s))
                                for n, s in zip(fit.model.param_names, fit.std)},
            'icr': _icr_summary(fit.icr), 'rms_position': fit.rms_position,
            'rms_heading': fit.rms_heading}


def _improvements(e, baseline):
    """Improvements of one evaluation over a baseline's, per kind (None: nothing compared)."""
    if baseline is None or baseline.segments is None or e.segments is None:
        return None
    return {kind: getattr(e, kind).improvement_over(getattr(baseline, kind))
            for kind in ('segments', 'windows')}


def _holdout_summary(result):
    if result.holdout is None:
        return None
    ideal, ddc = result.evaluation('ideal'), result.evaluation('tuned_ddc')
    models = {}
    for e in result.evaluations:
        entry = {'segments': _stats(e.segments), 'windows': _stats(e.windows)}
        if e.fit is not None:
            entry['parameters'] = e.fit.params
        if e.error:
            entry['error'] = e.error
        better = _improvements(e, ideal)
        if better is not None:
            entry['improvement_pct'] = better
        if e.name != 'tuned_ddc':
            better = _improvements(e, ddc)
            if better is not None:
                entry['improvement_vs_tuned_ddc_pct'] = better
        models[e.name] = entry
    held = result.holdout
    return {'blocks': [[int(r), float(a), float(b)] for r, a, b in held.blocks],
            'total_blocks': held.total_blocks, 'block_length': held.block_length,
            'folds': len(held.folds), 'cross_validated': held.cross_validated,
            'window': result.window, 'segments': _count(result, 'segments'),
            'windows': _count(result, 'windows'), 'models': models}


def _count(result, kind):
    return next((getattr(e, kind).n for e in result.evaluations if getattr(e, kind)), 0)


def _recordings_summary(recordings):
    return [{'bag': r.name, 'duration': r.duration, 'encoder_samples': len(r.enc_t),
             'ground_truth_samples': len(r.gt_t)} for r in recordings]


def _time_summary(time):
    return {'span': time.span, 'covered': time.covered, 'driving': time.driving,
            'pieces': time.pieces, 'longest_piece': time.longest_piece}


def _yaml_values(base_values, icr, radius, terrain, extras):
    """Merge base values without the old terrain name and record, the ICR model, its record."""
    fitted = values_from_icr(icr, radius)
    if terrain:
        fitted['terrain'] = terrain
    return terrain_values(base_values, fitted, record='identification', extras=extras,
                          check=icr_from_values, drop=('terrain',))


def _delay_extras(delay, each=()):
    """Return the ``identification.ground_truth_delay*`` keys of the YAML."""
    method = 'given' if delay.delay else 'off'
    extras = {'ground_truth_delay': float(delay.delay),
              'ground_truth_delay_method': method if delay.uncertainty == 'given'
              else delay.uncertainty}
    if delay.uncertainty in ('jackknife', 'curvature'):
        extras['ground_truth_delay_std'] = float(delay.std)
    elif not delay.determined:
        extras['ground_truth_delay_method'] = 'not determined'
    if each:
        extras['ground_truth_delay_per_bag'] = [float(e.delay) for e in each]
    return extras


def _print_delay(delay, each, out):
    if delay.uncertainty == 'given':
        text = (f'{delay.delay:.3f} s as given, removed from the ground-truth stamps'
                if delay.delay else 'off (--ground-truth-delay 0)')
    elif delay.determined and each:
        per = ', '.join(f'{e.delay:.3f}' for e in each)
        text = (f'{delay.describe()}; per bag {per} s, each removed from the ground-truth '
                'stamps of its bag')
    elif delay.determined:
        text = f'{delay.describe()}; removed from the ground-truth stamps'
    else:
        text = (f'{delay.describe()}; none removed: give it with --ground-truth-delay '
                'SECONDS if the ground truth is stamped late')
    print(f'ground-truth delay behind the encoders: {text}', file=out)


def _print_table(result, recordings, radius, out):
    exc = result.excitation
    t = result.time
    pieces = f'in {t.pieces} pieces' if t.pieces != len(recordings) else 'without gaps'
    print(f'{PROG}: {len(recordings)} bag(s): {t.covered:.0f} s with encoders and ground truth '
          f'({pieces}; {t.span:.0f} s from first to last sample), {t.driving:.0f} s driving, '
          f'{exc.distance:.1f} m driven, {exc.turning:.1f} rad turned; {exc.moving} moving '
          f'segments of {result.segment_length or "ground-truth period"} s', file=out)
    _print_delay(result.delay, result.delays, out)
    if result.jumps:
        print(f'ground truth: {result.jumps} jump(s) (re-localisations, glitches: a step the '
              f'tracks cannot make); the {result.jump_segments} segment(s) and the windows '
              'over them are left out', file=out)
    fitted = result.fit
    params = ', '.join(f'{n} {v:.4f}' for n, v in fitted.params.items())
    icr = result.icr
    print(f'{fitted.model.name} ({fitted.method}): {params}', file=out)
    errors = ', '.join(f'{n} {e:.2g}' for n, e in zip(fitted.model.param_names, fitted.std))
    if errors:
        print(f'standard errors: {errors}', file=out)
    print(f'written ICR model ({result.icr_source}): y_left {icr.y_left:.4f} m, y_right '
          f'{icr.y_right:.4f} m, x {icr.x:.4f} m, scales {icr.scale_left:.4f} / '
          f'{icr.scale_right:.4f}; chi {icr.chi:.3f}, e {icr.eccentricity:.3f}', file=out)
    print(f'fit: rms {1000 * fitted.rms_position:.1f} mm, '
          f'{math.degrees(fitted.rms_heading):.2f} deg over {fitted.inliers}/{fitted.segments} '
          f'inlier segments (the ground-truth noise, and what the model does not capture), '
          f'heading weight {fitted.heading_weight:.2f} m/rad', file=out)
    for u in result.uncertain:
        print(f'accepted (--accept-uncertain): {u.describe()}', file=out)
    _print_holdout(result, out)
    _print_ddc(result, radius, out)


def _print_holdout(result, out):
    held = result.holdout
    if held is None:
        print('hold-out: none (--holdout 0)', file=out)
        return
    n_seg, n_win = _count(result, 'segments'), _count(result, 'windows')
    how = (f'{len(held.folds)}-fold cross-validation over {held.total_blocks} blocks of '
           f'{held.block_length:.0f} s of driving (every block held out once)'
           if held.cross_validated else
           f'{len(held.folds[0])} of {held.total_blocks} blocks of {held.block_length:.0f} s '
           'of driving')
    wins = (f'{n_win} windows of {result.window:g} s' if n_win else
            f'no held-out windows of {result.window:g} s (the longest piece with both streams '
            f'is {result.time.longest_piece:.1f} s; a shorter --window gives some)')
    kind = 'windows' if n_win else 'segments'
    print(f'\nhold-out: {how}, {n_seg} segments, {wins}; errors mean / p90; '
          f'"vs" columns: mean {kind[:-1]} position error', file=out)
    head = (f'{"model":<22}{"segment pos (mm)":>18}{"heading (deg)":>16}'
            f'{"window pos (m)":>17}{"heading (deg)":>16}{"vs ideal":>10}{"vs tuned DDC":>14}')
    print(head, file=out)
    ideal, ddc = result.evaluation('ideal'), result.evaluation('tuned_ddc')
    for e in result.evaluations:
        if e.segments is None:
            print(f'{e.name:<22}  failed: {e.error}', file=out)
            continue
        s, w = e.segments, e.windows
        if s.n:
            seg = (f'{1000 * s.position_mean:>8.1f} /{1000 * s.position_p90:>7.1f}'
                   f'{math.degrees(s.heading_mean):>8.2f} /{math.degrees(s.heading_p90):>6.2f}')
        else:
            seg = f'{"none":>18}{"":>16}'
        if w.n:
            win = (f'{w.position_mean:>9.3f} /{w.position_p90:>6.3f}'
                   f'{math.degrees(w.heading_mean):>8.2f} /{math.degrees(w.heading_p90):>6.2f}')
        else:
            win = f'{"none":>17}{"":>16}'
        columns = []
        for baseline in (ideal, ddc):
            if baseline is None or baseline is e:
                columns.append('')
                continue
            gain = getattr(e, kind).improvement_over(getattr(baseline, kind)) \
                if baseline.segments is not None else None
            columns.append('' if gain is None or gain['position'] is None
                           else f'{gain["position"]:+.0f} %')
        print(f'{e.name:<22}{seg}{win}{columns[0]:>10}{columns[1]:>14}'.rstrip(), file=out)


def _print_ddc(result, radius, out):
    if result.ddc is None:
        print(f'\ntuned diff_drive_controller: not fitted ({result.ddc_error})', file=out)
        return
    values = ident.ddc_parameters(result.ddc.p, result.ddc.model.track_width, radius)
    print('\ndiff_drive_controller tuned on the same data, for a robot that stays on it '
          '(controller name yours):', file=out)
    print('diff_drive_controller:\n  ros__parameters:', file=out)
    for name, value in values.items():
        print(f'    {name}: {value:.6g}', file=out)


# Main ----------------------------------------------------------------------------------


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


def _run(args, out) -> int:
    with _outputs(args) as outputs:
        _identify(args, out, outputs)
    print(f'wrote {", ".join(str(p) for p in outputs.targets)}', file=out)
    return 0


def _uses_references(args) -> bool:
    return bool(args.imu_topic or args.gnss_topic or args.straight_distance is not None)


def _identify(args, out, outputs) -> None:
    if _uses_references(args):
        from tracked_kinematics.offline.cli import identify_reference
        identify_reference.run(args, out, outputs)
        return
    if not args.ground_truth_topic:
        raise UsageError('give --ground-truth-topic (a pose) or --imu-topic (a gyro)')
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
        delay, each = (ident.estimate_delays(recordings) if args.ground_truth_delay == 'auto'
                       else (ident.fixed_delay(args.ground_truth_delay), []))
        removed = [e.delay for e in each] or [delay.delay] * len(recordings)
        spin = ident.spin_in_place([ident.correct_ground_truth([r], d)[0]
                                    for r, d in zip(recordings, removed)], track_width, scales)
        icr = spin.icr(track_width, scales)
        extras = {'model': 'spin_in_place', 'date': date, 'bags': bags,
                  'spin_runs': len(spin.runs), 'chi': spin.chi, 'chi_std': spin.chi_std,
                  **_delay_extras(delay, each)}
        values = _yaml_values(base_values, icr, radius, args.terrain, extras)
        report.update({'mode': 'spin_in_place', 'chi': spin.chi, 'chi_std': spin.chi_std,
                       'runs': spin.runs, 'icr': _icr_summary(icr),
                       'ground_truth_delay': _delay_summary(delay, each)})
        _print_delay(delay, each, out)
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
            max_nfev=args.max_nfev, ground_truth_delay=args.ground_truth_delay,
            accept_uncertain=args.accept_uncertain)
        fitted, icr = result.fit, result.icr
        extras = {'model': fitted.model.name, 'method': fitted.method, 'date': date,
                  'bags': bags, 'segments': fitted.segments,
                  'segment_length': float(args.segment_length),
                  'heading_weight': fitted.heading_weight, 'cost': fitted.cost,
                  'rms_position': fitted.rms_position, 'rms_heading': fitted.rms_heading,
                  'chi': icr.chi, 'eccentricity': icr.eccentricity,
                  'icr_source': result.icr_source,
                  **_delay_extras(result.delay, result.delays)}
        extras.update({f'parameters.{n}': v for n, v in fitted.params.items()})
        if result.uncertain:
            extras['uncertain'] = [u.name for u in result.uncertain]
        chosen = result.evaluation(result.icr_source)
        ideal, ddc = result.evaluation('ideal'), result.evaluation('tuned_ddc')
        # Held-out improvements only where there are held-out windows to compare.
        for key, baseline in (('holdout', ideal), ('holdout_vs_tuned_ddc', ddc)):
            if chosen and baseline and chosen.windows and baseline.windows:
                gain = chosen.windows.improvement_over(baseline.windows)
                for kind in ('position', 'heading') if gain is not None else ():
                    if gain[kind] is not None:
                        extras[f'{key}_{kind}_improvement_pct'] = gain[kind]
        values = _yaml_values(base_values, icr, radius, args.terrain, extras)
        report.update({
            'mode': 'segments', 'model': fitted.model.name, 'icr_source': result.icr_source,
            'icr': _icr_summary(icr), 'fit': _fit_summary(fitted),
            'excitation': vars(result.excitation), 'holdout': _holdout_summary(result),
            'seconds': result.seconds,
            'ground_truth_delay': _delay_summary(result.delay, result.delays),
            'time': _time_summary(result.time), 'tuned_ddc': _ddc_summary(result, radius),
            'ground_truth_jumps': {'jumps': result.jumps, 'segments': result.jump_segments},
            'uncertain': [vars(u) for u in result.uncertain]})
        _print_table(result, recordings, radius, out)
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
        # The moving segments the fit used: those of --min-travel, delay removed.
        segments = ident.build_segments(result.recordings, result.segment_length)
        with outputs.path('--plot') as tmp:
            plot_identification(tmp, result.recordings, result,
                                segments.select(segments.travel >= args.min_travel))


def main(argv=None) -> int:
    """Run identify_icr; return the exit status (see the module docstring)."""
    return run_main(PROG, _run, build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
