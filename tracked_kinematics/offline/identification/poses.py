"""
identify_icr from a ground-truth pose: the fit of the segments, or the spin-in-place runs.

:func:`icr_from_poses` runs :func:`tracked_kinematics.core.identify.identify` (or
:func:`~tracked_kinematics.core.identify.spin_in_place`) on recordings already read and
returns the :class:`.report.FitResult`: the terrain values with their ``identification.*``
record, the JSON report and the table (:func:`.api.fit` reads the bags and calls it).
"""

from __future__ import annotations

import math

from tracked_kinematics.core import identify as ident

from .noise_constants import add_extras, pose_extras
from .report import (bag_names, finite_or_none, FitResult, icr_summary, now, TOOL,
                     yaml_values)


def icr_from_poses(recordings, options, track_width: float, sprocket_radius: float, *,
                   base=None, base_values=None, date: str | None = None,
                   tool: str = TOOL) -> FitResult:
    """
    Identify the tread ICRs from encoders and a ground-truth pose; return what to write.

    Parameters
    ----------
    recordings : sequence of Recording
        ``options.bags`` as read (:func:`tracked_kinematics.offline.bags.read_recordings`).
    options : FitOptions
        What to fit (:class:`.api.FitOptions`).
    track_width, sprocket_radius : float
        m.
    base : IcrParams, optional
        Starting point, and the fixed scales of ``model='icr'`` and of the spin runs.
    base_values : mapping, optional
        The base terrain file's values, copied to the output (dotted names).
    date : str, optional
        ISO 8601 time to record; default now.
    tool : str
        The tool's name, in the report and the table.

    Raises
    ------
    ExcitationError, FitError
        As :func:`tracked_kinematics.core.identify.identify`.

    """
    model, terrain = options.model, options.terrain
    segment_length = options.identify.segment_length
    date = date or now()
    recordings = list(recordings)
    bags = bag_names(options.bags)
    report = {'tool': tool, 'date': date, 'bags': bags, 'track_width': track_width,
              'sprocket_radius': sprocket_radius, 'recordings': _recordings_summary(recordings)}
    lines = []
    result = None
    if options.spin_in_place:
        values = _spin(recordings, bags, track_width, sprocket_radius, base, base_values,
                       terrain, options.identify.ground_truth_delay, date, tool, report, lines)
    else:
        result = ident.identify(recordings, model, track_width, base=base,
                                options=options.identify)
        values = yaml_values(base_values, result.icr, sprocket_radius, terrain,
                             _segment_extras(result, bags, date, segment_length))
        report.update({
            'mode': 'segments', 'model': result.fit.model.name, 'icr_source': result.icr_source,
            'icr': icr_summary(result.icr), 'fit': _fit_summary(result.fit),
            'excitation': vars(result.excitation), 'holdout': _holdout_summary(result),
            'windows_selection': _selection(result.min_speed), 'seconds': result.seconds,
            'ground_truth_delay': _delay_summary(result.delay, result.delays),
            'time': _time_summary(result.time),
            'tuned_ddc': _ddc_summary(result, sprocket_radius),
            'ground_truth_jumps': {'jumps': result.jumps, 'segments': result.jump_segments},
            'uncertain': [vars(u) for u in result.uncertain]})
        _table(result, recordings, sprocket_radius, tool, lines)
        add_extras(values, report, lines, pose_extras(result, options, track_width))
    note = ''
    if result is not None and not result.fit.model.constant_icr:
        note = (f'The {model} model has no constant ICRs: icr.* and scale.* are the '
                f'{values["identification.icr_source"]} fit of the same data;\nthe '
                f'{model} parameters are under identification.parameters.')
    return FitResult(values, note, report, tuple(lines), date, result)


def _spin(recordings, bags, track_width, radius, base, base_values, terrain,
          ground_truth_delay, date, tool, report, lines) -> dict:
    """Measure chi on spin-in-place runs; fill the report and the table; return the values."""
    scales = (base.scale_left, base.scale_right) if base else (1.0, 1.0)
    delay, each = (ident.estimate_delays(recordings) if ground_truth_delay == 'auto'
                   else (ident.fixed_delay(ground_truth_delay), []))
    removed = [e.delay for e in each] or [delay.delay] * len(recordings)
    spin = ident.spin_in_place([ident.correct_ground_truth([r], d)[0]
                                for r, d in zip(recordings, removed)], track_width, scales)
    icr = spin.icr(track_width, scales)
    extras = {'model': 'spin_in_place', 'date': date, 'bags': bags,
              'spin_runs': len(spin.runs), 'chi': spin.chi, 'chi_std': spin.chi_std,
              **_delay_extras(delay, each)}
    values = yaml_values(base_values, icr, radius, terrain, extras)
    report.update({'mode': 'spin_in_place', 'chi': spin.chi, 'chi_std': spin.chi_std,
                   'runs': spin.runs, 'icr': icr_summary(icr),
                   'ground_truth_delay': _delay_summary(delay, each)})
    lines.append(_delay_line(delay, each))
    lines.append(f'{tool}: {len(spin.runs)} spin-in-place run(s): chi = {spin.chi:.4f} '
                 f'(std {spin.chi_std:.4f}); ICRs at +-{icr.y_left:.4f} m')
    return values


# The terrain file's record -----------------------------------------------------------------


def _segment_extras(result, bags, date, segment_length) -> dict:
    """Return the ``identification.*`` record of a fit of the segments."""
    fitted, icr = result.fit, result.icr
    extras = {'model': fitted.model.name, 'method': fitted.method, 'date': date,
              'bags': bags, 'segments': fitted.segments,
              'segment_length': float(segment_length),
              'heading_weight': fitted.heading_weight, 'cost': fitted.cost,
              'rms_position': fitted.rms_position, 'rms_heading': fitted.rms_heading,
              'chi': icr.chi, 'eccentricity': icr.eccentricity,
              'icr_source': result.icr_source,
              **_delay_extras(result.delay, result.delays)}
    extras.update({f'parameters.{n}': v for n, v in fitted.params.items()})
    if result.uncertain:
        extras['uncertain'] = [u.name for u in result.uncertain]
    if result.at_bounds:
        extras['at_bounds'] = list(result.at_bounds)
    chosen = result.evaluation(result.icr_source)
    ideal, ddc = result.evaluation('ideal'), result.evaluation('tuned_ddc')
    # Held-out improvements only where there are held-out windows to compare.
    for key, baseline in (('holdout', ideal), ('holdout_vs_tuned_ddc', ddc)):
        if chosen and baseline and chosen.windows and baseline.windows:
            gain = chosen.windows.improvement_over(baseline.windows)
            for kind in ('position', 'heading') if gain is not None else ():
                if gain[kind] is not None:
                    extras[f'{key}_{kind}_improvement_pct'] = gain[kind]
    if any(k.startswith('holdout_') for k in extras):
        # Which windows those figures are over.
        extras['holdout_windows'] = 'all' if result.min_speed is None else 'moving'
        if result.min_speed is not None:
            extras['holdout_min_speed'] = float(result.min_speed)
    return extras


def _delay_extras(delay, each=()) -> dict:
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


# The JSON report ---------------------------------------------------------------------------


def _stats(stats, total=None):
    if stats is None:
        return None
    if stats.n == 0:
        summary = {'n': 0, 'position_mean': None, 'position_p90': None, 'heading_mean': None,
                   'heading_p90': None}
    else:
        summary = {k: finite_or_none(float(getattr(stats, k))) if k != 'n' else stats.n
                   for k in ('n', 'position_mean', 'position_p90', 'heading_mean',
                             'heading_p90')}
    if total is not None:
        summary = {'n': summary.pop('n'), 'n_total': total, **summary}
    return summary


def _fit_summary(result):
    return {
        'model': result.model.name, 'method': result.method,
        'parameters': result.params,
        'standard_errors': {n: finite_or_none(float(s))
                            for n, s in zip(result.model.param_names, result.std)},
        'cost': result.cost, 'loss': result.loss, 'f_scale': result.f_scale,
        'heading_weight': result.heading_weight, 'rms_position': result.rms_position,
        'rms_heading': result.rms_heading, 'residual_sigma': result.sigma,
        'segments': result.segments, 'inliers': result.inliers, 'evaluations': result.nfev,
        'seconds': result.seconds,
    }


def _delay_summary(delay, each=()):
    summary = {'delay': delay.delay, 'std': finite_or_none(float(delay.std)),
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
            'standard_errors': {n: finite_or_none(float(s))
                                for n, s in zip(fit.model.param_names, fit.std)},
            'icr': icr_summary(fit.icr), 'rms_position': fit.rms_position,
            'rms_heading': fit.rms_heading}


def _improvements(e, baseline):
    """Improvements of one evaluation over a baseline's, per kind (None: nothing compared)."""
    if baseline is None or baseline.segments is None or e.segments is None:
        return None
    return {kind: getattr(e, kind).improvement_over(getattr(baseline, kind))
            for kind in ('segments', 'windows')}


def _selection(min_speed) -> dict:
    """Which held-out windows are scored, as evaluate_model's report says it."""
    return {'moving_only': min_speed is not None, 'min_speed_mps': min_speed}


def _holdout_summary(result):
    if result.holdout is None:
        return None
    ideal, ddc = result.evaluation('ideal'), result.evaluation('tuned_ddc')
    models = {}
    for e in result.evaluations:
        entry = {'segments': _stats(e.segments),
                 'windows': _stats(e.windows, result.windows_total)}
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


# The table ---------------------------------------------------------------------------------


def _delay_line(delay, each) -> str:
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
    return f'ground-truth delay behind the encoders: {text}'


def _table(result, recordings, radius, tool, lines) -> None:
    exc = result.excitation
    t = result.time
    pieces = f'in {t.pieces} pieces' if t.pieces != len(recordings) else 'without gaps'
    lines.append(
        f'{tool}: {len(recordings)} bag(s): {t.covered:.0f} s with encoders and ground truth '
        f'({pieces}; {t.span:.0f} s from first to last sample), {t.driving:.0f} s driving, '
        f'{exc.distance:.1f} m driven, {exc.turning:.1f} rad turned; {exc.moving} moving '
        f'segments of {result.segment_length or "ground-truth period"} s')
    lines.append(_delay_line(result.delay, result.delays))
    if result.jumps:
        lines.append(f'ground truth: {result.jumps} jump(s) (re-localisations, glitches: a step '
                     f'the tracks cannot make); the {result.jump_segments} segment(s) and the '
                     'windows over them are left out')
    fitted = result.fit
    params = ', '.join(f'{n} {v:.4f}' for n, v in fitted.params.items())
    icr = result.icr
    lines.append(f'{fitted.model.name} ({fitted.method}): {params}')
    errors = ', '.join(f'{n} {e:.2g}' for n, e in zip(fitted.model.param_names, fitted.std))
    if errors:
        lines.append(f'standard errors: {errors}')
    lines.append(f'written ICR model ({result.icr_source}): y_left {icr.y_left:.4f} m, y_right '
                 f'{icr.y_right:.4f} m, x {icr.x:.4f} m, scales {icr.scale_left:.4f} / '
                 f'{icr.scale_right:.4f}; chi {icr.chi:.3f}, e {icr.eccentricity:.3f}')
    lines.append(f'fit: rms {1000 * fitted.rms_position:.1f} mm, '
                 f'{math.degrees(fitted.rms_heading):.2f} deg over '
                 f'{fitted.inliers}/{fitted.segments} inlier segments (the ground-truth noise, '
                 'and what the model does not capture), heading weight '
                 f'{fitted.heading_weight:.2f} m/rad')
    for u in result.uncertain:
        lines.append(f'accepted (--accept-uncertain): {u.describe()}')
    for bound in result.at_bounds:
        lines.append(f'accepted (--accept-uncertain): {bound}')
    _holdout_table(result, lines)
    _ddc_lines(result, radius, lines)


def _windows_words(result, n_win) -> str:
    """Say how many held-out windows are scored, and which."""
    if not n_win and result.min_speed is not None and result.windows_total:
        return (f'none of {result.windows_total} held-out windows of {result.window:g} s in '
                f'which the tracks move (mean track speed >= {result.min_speed:g} m/s; a lower '
                '--min-speed or --all-windows scores some)')
    if not n_win:
        return (f'no held-out windows of {result.window:g} s (the longest piece with both '
                f'streams is {result.time.longest_piece:.1f} s; a shorter --window gives some)')
    if result.min_speed is None:
        return f'{n_win} windows of {result.window:g} s, idle ones too'
    return (f'{n_win} of {result.windows_total} windows of {result.window:g} s, those in which '
            f'the tracks move (mean track speed >= {result.min_speed:g} m/s; --all-windows for '
            'all)')


def _holdout_table(result, lines) -> None:
    held = result.holdout
    if held is None:
        lines.append('hold-out: none (--holdout 0)')
        return
    n_seg, n_win = _count(result, 'segments'), _count(result, 'windows')
    how = (f'{len(held.folds)}-fold cross-validation over {held.total_blocks} blocks of '
           f'{held.block_length:.0f} s of driving (every block held out once)'
           if held.cross_validated else
           f'{len(held.folds[0])} of {held.total_blocks} blocks of {held.block_length:.0f} s '
           'of driving')
    kind = 'windows' if n_win else 'segments'
    lines.append(f'\nhold-out: {how}, {n_seg} segments, {_windows_words(result, n_win)}; '
                 f'errors mean / p90; "vs" columns: mean {kind[:-1]} position error')
    lines.append(f'{"model":<22}{"segment pos (mm)":>18}{"heading (deg)":>16}'
                 f'{"window pos (m)":>17}{"heading (deg)":>16}{"vs ideal":>10}'
                 f'{"vs tuned DDC":>14}')
    ideal, ddc = result.evaluation('ideal'), result.evaluation('tuned_ddc')
    for e in result.evaluations:
        if e.segments is None:
            lines.append(f'{e.name:<22}  failed: {e.error}')
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
        lines.append(f'{e.name:<22}{seg}{win}{columns[0]:>10}{columns[1]:>14}'.rstrip())


def _ddc_lines(result, radius, lines) -> None:
    if result.ddc is None:
        lines.append(f'\ntuned diff_drive_controller: not fitted ({result.ddc_error})')
        return
    values = ident.ddc_parameters(result.ddc.p, result.ddc.model.track_width, radius)
    lines.append('\ndiff_drive_controller tuned on the same data, for a robot that stays on it '
                 '(controller name yours):')
    lines.append('diff_drive_controller:\n  ros__parameters:')
    lines.extend(f'    {name}: {value:.6g}' for name, value in values.items())
