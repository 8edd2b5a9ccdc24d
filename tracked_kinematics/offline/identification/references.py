"""
identify_icr without a ground-truth pose: the gyro as the reference, GNSS or a straight drive.

:func:`icr_from_references` calibrates with :func:`tracked_kinematics.core.identify.
fit_recordings` on recordings read by :func:`tracked_kinematics.offline.bags.read_recording`
and returns the :class:`.report.FitResult`, with ``identification.
reference``, ``identification.determined`` and ``identification.held`` (docs/tools/identify_icr.md,
"What it writes") and ``identification.imu_delay`` in the terrain values.
"""

from __future__ import annotations

import math

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.kinematics import IcrParams

from .noise_constants import add_extras, reference_extras
from .report import bag_names, FitResult, icr_summary, now, TOOL, yaml_values

WHY_HELD = {
    'chi': 'the references do not turn enough',
    'scale_ratio': 'too little straight driving and turning to see a veer',
    'distance_scale': 'a gyro does not see how far the robot went: give --gnss-topic or '
                      '--straight-distance',
    'icr.x': 'a gyro does not see sideways slip; GNSS only with cm noise and many turns',
    'icr_offset': 'a gyro does not see it; a pose reference does',
}
"""Why each quantity the references cannot determine is held, as the table says it."""


def icr_from_references(recordings, options, track_width: float, sprocket_radius: float, *,
                        base: IcrParams | None = None, base_values=None,
                        date: str | None = None, tool: str = TOOL) -> FitResult:
    """
    Calibrate from a gyro, GNSS positions, a pose or a measured straight; return what to write.

    Parameters
    ----------
    recordings : sequence of Recording
        ``options.bags`` as read, one each.
    options : FitOptions
        What to fit (:class:`.api.FitOptions`): the constant-ICR model is fitted; with
        ``model='symmetric'`` the ICRs of ``base`` are held symmetric (offset 0).
    track_width, sprocket_radius, base, base_values, date, tool
        As :func:`.poses.icr_from_poses`; ``base`` holds what the references cannot
        determine.

    Returns
    -------
    FitResult
        Its ``identification`` is None (nothing to plot).

    Raises
    ------
    SensorDataError, ExcitationError, FitError
        As :func:`tracked_kinematics.core.identify.fit_recordings`.

    """
    date = date or now()
    recordings = list(recordings)
    bags = bag_names(options.bags)
    segment_length = float(options.identify.segment_length or 1.0)
    fit = ident.fit_recordings(
        recordings, track_width, base=_held_base(base, options.model),
        imu_delay=options.imu_delay, pose_delay=options.identify.ground_truth_delay,
        segment_length=segment_length, straight_distance=options.straight_distance,
        gnss_antenna=tuple(options.gnss_antenna), strict_imu_delay=True)
    icr = fit.icr
    extras = {'model': 'icr_scales', 'method': 'reference', 'date': date, 'bags': bags,
              'reference': fit.reference, 'determined': list(fit.determined),
              'held': list(fit.held), 'segment_length': segment_length,
              'chi': icr.chi, 'eccentricity': icr.eccentricity + 0.0,   # not -0.0
              'distance_scale': fit.distance_scale, 'scale_ratio': fit.scale_ratio}
    if fit.report['imu_delay'] is not None:
        extras['imu_delay'] = float(fit.imu_delay.delay)
        extras['imu_delay_method'] = (fit.imu_delay.uncertainty or 'not determined') \
            if fit.imu_delay.uncertainty != 'given' else 'given'
        if math.isfinite(fit.imu_delay.std) and fit.imu_delay.uncertainty != 'given':
            extras['imu_delay_std'] = float(fit.imu_delay.std)
        extras['gyro_bias_per_bag'] = [float(b) for b in fit.biases]
    if fit.report['pose_delay'] is not None:
        extras['ground_truth_delay'] = float(fit.pose_delay.delay)
    values = yaml_values(base_values, icr, sprocket_radius, options.terrain, extras)
    report = {'tool': tool, 'date': date, 'bags': bags, 'track_width': track_width,
              'sprocket_radius': sprocket_radius, 'mode': 'reference', **fit.report,
              'icr': icr_summary(icr),
              'recordings': [{'bag': r.name, 'encoder_samples': len(r.enc_t),
                              'gyro_samples': 0 if r.gyro_t is None else len(r.gyro_t),
                              'positions': 0 if r.positions is None else len(r.positions[0]),
                              'pose_samples': 0 if r.pose is None else len(r.pose[0])}
                             for r in recordings]}
    lines = _table(fit, recordings, tool) + ddc_lines(icr, sprocket_radius)
    report['tuned_ddc'] = {'parameters': _ddc_values(icr, sprocket_radius)}
    add_extras(values, report, lines,
               reference_extras(fit, recordings, options, track_width,
                                _held_base(base, options.model)))
    note = (f'Calibrated without ground truth ({fit.reference}): held, not fitted: '
            f'{", ".join(fit.held)}.' if fit.held else '')
    return FitResult(values, note, report, tuple(lines), date)


def _held_base(base, model):
    """Return the values to hold: ``base`` (ICR offset 0 with ``model='symmetric'``), or None."""
    if base is None:
        return None
    if model == 'symmetric':
        half = 0.5 * (base.y_left - base.y_right)
        return IcrParams(base.track_width, half, -half, base.x, base.scale_left,
                         base.scale_right)
    return base


def _table(fit, recordings, tool) -> list[str]:
    r = fit.report
    data = r['data']
    lines = [f'{tool}: {len(recordings)} bag(s), reference {fit.reference}: '
             f'{data["moving_segments"]} moving segments of {r["segment_length"]:g} s, '
             f'{data["driven_m"]:.1f} m driven (encoders), {data["turned_rad"]:.1f} rad turned']
    if r['imu_delay'] is not None:
        d = fit.imu_delay
        if d.uncertainty == 'given':
            text = f'{d.delay:+.3f} s as given'
        elif d.determined:
            text = f'{d.describe()}; removed from the gyro stamps'
        else:
            text = f'not determined ({d.problem}); none removed'
        lines.append(f'gyro delay behind the encoders (imu_delay): {text}')
        gyro = r['gyro']
        biases = ', '.join(f'{b:+.5f}' for b in gyro['bias_rad_s'])
        lines.append(f'gyro: bias {biases} rad/s (per bag), noise '
                     f'{gyro["noise_rad_per_sqrt_s"]:.2g} rad/sqrt(s) from the data; heading '
                     f'residual {math.degrees(r["heading"]["imu"]["residual_std_rad"]):.3f} deg '
                     'per segment')
    if r['pose_delay'] is not None:
        lines.append(f'pose delay behind the encoders: {fit.pose_delay.describe()}')
    for source, stats in r['positions'].items():
        lines.append(f'{source}: {stats["samples"]} positions, residual '
                     f'{stats["residual_std_m"]:.3f} m')
    if r['straight']:
        s = r['straight']
        lines.append(f'straight drive: {s["distance_m"]:.3f} m measured, '
                     f'{s["encoder_chord_m"]:.3f} m from the encoders, heading within '
                     f'{math.degrees(s["max_heading_excursion_rad"]):.1f} deg')
    icr = fit.icr
    std = r['standard_errors']
    lines.append(f'determined: {", ".join(fit.determined) or "nothing"}: chi {icr.chi:.4f} '
                 f'(turn gain {fit.turn_gain:.4f} +- {std["turn_gain"]:.2g} rad/m), scale ratio '
                 f'{fit.scale_ratio:.4f}, distance scale {fit.distance_scale:.4f}')
    lines.extend(f'held (--params or ideal drive): {q}: {WHY_HELD[q]}' for q in fit.held)
    lines.append(f'written ICR model: y_left {icr.y_left:.4f} m, y_right {icr.y_right:.4f} m, x '
                 f'{icr.x:.4f} m, scales {icr.scale_left:.4f} / {icr.scale_right:.4f}; chi '
                 f'{icr.chi:.3f}, e {icr.eccentricity:.3f}')
    return lines


def _ddc_values(icr, radius) -> dict:
    """diff_drive_controller's parameters of an ICR model: separation from the ICRs, scales."""
    return ident.ddc_parameters(
        [(icr.y_left - icr.y_right) / icr.track_width, icr.scale_left, icr.scale_right],
        icr.track_width, radius)


def ddc_lines(icr, radius) -> list[str]:
    """
    Return the diff_drive_controller snippet of a reference calibration, as the pose fit prints.

    Its wheel separation is the ICRs' spread, its radius multipliers the scales; ``icr.x`` and
    the ICR offset, which it cannot express, are dropped (the pose fit fits its own instead).
    """
    values = _ddc_values(icr, radius)
    return (['', 'diff_drive_controller of the same calibration (the ICR spread as the wheel '
             'separation, the scales as radius multipliers; controller name yours):',
             'diff_drive_controller:', '  ros__parameters:']
            + [f'    {name}: {value:.6g}' for name, value in values.items()])
