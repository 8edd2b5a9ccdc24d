"""
identify_icr without a ground-truth pose: the gyro as the reference, GNSS or a straight drive.

Used by :mod:`.identify_icr` when ``--imu-topic``, ``--gnss-topic`` or ``--straight-distance``
is given: reads the encoders and the references of each bag
(:func:`tracked_kinematics.offline.bags.references.read_reference_bag`), calibrates with
:func:`tracked_kinematics.core.identify.fit_recordings`, and writes the terrain file with
``identification.reference``, ``identification.determined`` and ``identification.held``
(docs/tools/identify_icr.md), ``identification.imu_delay`` and the report.
"""

from __future__ import annotations

from datetime import datetime, timezone
import math
from pathlib import Path
import sys

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.offline.bags.references import read_reference_bag
from tracked_kinematics.offline.cli.common import (encoder_source, ground_truth_source,
                                                   report_json)
from tracked_kinematics.offline.cli.identify_icr import (_icr_summary, _vehicle, _yaml_values,
                                                         PROG)
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.offline.terrain_file import terrain_text

WHY_HELD = {
    'chi': 'the references do not turn enough',
    'scale_ratio': 'too little straight driving and turning to see a veer',
    'distance_scale': 'a gyro does not see how far the robot went: give --gnss-topic or '
                      '--straight-distance',
    'icr.x': 'a gyro does not see sideways slip; GNSS only with cm noise and many turns',
    'icr_offset': 'a gyro does not see it; a pose reference does',
}


def check_options(args) -> None:
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


def run(args, out, outputs) -> None:
    """Calibrate from the references and write the outputs (identify_icr's ``_identify``)."""
    check_options(args)
    base_values, base, track_width, radius = _vehicle(args)
    encoders = encoder_source(args, radius)
    pose = ground_truth_source(args) if args.ground_truth_topic else None
    recordings = [read_reference_bag(b, encoders, args.imu_topic, args.gnss_topic, pose,
                                     progress=sys.stderr.isatty()) for b in args.bags]
    fit = ident.fit_recordings(
        recordings, track_width, base=_held_base(base, track_width, args.model),
        imu_delay=_delay_option(args.imu_delay), pose_delay=_delay_option(
            args.ground_truth_delay), segment_length=args.segment_length or 1.0,
        straight_distance=args.straight_distance, gnss_antenna=tuple(args.gnss_antenna))
    date = datetime.now(timezone.utc).isoformat(timespec='seconds')
    bags = [str(Path(b).resolve()) for b in args.bags]
    icr = fit.icr
    extras = {'model': 'icr_scales', 'method': 'reference', 'date': date, 'bags': bags,
              'reference': fit.reference, 'determined': list(fit.determined),
              'held': list(fit.held), 'segment_length': float(args.segment_length or 1.0),
              'chi': icr.chi, 'eccentricity': icr.eccentricity + 0.0,   # not -0.0
              'distance_scale': fit.distance_scale, 'scale_ratio': fit.scale_ratio}
    if args.imu_topic:
        extras['imu_delay'] = float(fit.imu_delay.delay)
        extras['imu_delay_method'] = (fit.imu_delay.uncertainty or 'not determined') \
            if fit.imu_delay.uncertainty != 'given' else 'given'
        if math.isfinite(fit.imu_delay.std) and fit.imu_delay.uncertainty != 'given':
            extras['imu_delay_std'] = float(fit.imu_delay.std)
        extras['gyro_bias_per_bag'] = [float(b) for b in fit.biases]
    if pose is not None:
        extras['ground_truth_delay'] = float(fit.pose_delay.delay)
    values = _yaml_values(base_values, icr, radius, args.terrain, extras)
    report = {'tool': PROG, 'date': date, 'bags': bags, 'track_width': track_width,
              'sprocket_radius': radius, 'mode': 'reference', **fit.report,
              'icr': _icr_summary(icr),
              'recordings': [{'bag': r.name, 'encoder_samples': len(r.enc_t),
                              'gyro_samples': 0 if r.gyro_t is None else len(r.gyro_t),
                              'positions': 0 if r.positions is None else len(r.positions[0]),
                              'pose_samples': 0 if r.pose is None else len(r.pose[0])}
                             for r in recordings]}
    _print(fit, recordings, out)
    note = (f'Calibrated without ground truth ({fit.reference}): held, not fitted: '
            f'{", ".join(fit.held)}.' if fit.held else '')
    outputs.write_text('--output', terrain_text(values, tool=PROG, date=date, note=note))
    if '--report' in outputs:
        outputs.write_text('--report', report_json(report))


def _held_base(base, track_width, model):
    """Return the values to hold: --params' (ICR offset 0 with --model symmetric), or None."""
    if base is None:
        return None
    if model == 'symmetric':
        half = 0.5 * (base.y_left - base.y_right)
        return IcrParams(base.track_width, half, -half, base.x, base.scale_left,
                         base.scale_right)
    return base


def _print(fit, recordings, out) -> None:
    r = fit.report
    data = r['data']
    print(f'{PROG}: {len(recordings)} bag(s), reference {fit.reference}: '
          f'{data["moving_segments"]} moving segments of {r["segment_length"]:g} s, '
          f'{data["driven_m"]:.1f} m driven (encoders), {data["turned_rad"]:.1f} rad turned',
          file=out)
    if r['imu_delay'] is not None:
        d = fit.imu_delay
        if d.uncertainty == 'given':
            text = f'{d.delay:+.3f} s as given'
        elif d.determined:
            text = f'{d.describe()}; removed from the gyro stamps'
        else:
            text = f'not determined ({d.problem}); none removed'
        print(f'gyro delay behind the encoders (imu_delay): {text}', file=out)
        gyro = r['gyro']
        biases = ', '.join(f'{b:+.5f}' for b in gyro['bias_rad_s'])
        print(f'gyro: bias {biases} rad/s (per bag), noise {gyro["noise_rad_per_sqrt_s"]:.2g} '
              f'rad/sqrt(s) from the data; heading residual '
              f'{math.degrees(r["heading"]["imu"]["residual_std_rad"]):.3f} deg per segment',
              file=out)
    if r['pose_delay'] is not None:
        print(f'pose delay behind the encoders: {fit.pose_delay.describe()}', file=out)
    for source, stats in r['positions'].items():
        print(f'{source}: {stats["samples"]} positions, residual {stats["residual_std_m"]:.3f} m',
              file=out)
    if r['straight']:
        s = r['straight']
        print(f'straight drive: {s["distance_m"]:.3f} m measured, {s["encoder_chord_m"]:.3f} m '
              f'from the encoders, heading within '
              f'{math.degrees(s["max_heading_excursion_rad"]):.1f} deg', file=out)
    icr = fit.icr
    std = r['standard_errors']
    print(f'determined: {", ".join(fit.determined) or "nothing"}: chi {icr.chi:.4f} '
          f'(turn gain {fit.turn_gain:.4f} +- {std["turn_gain"]:.2g} rad/m), scale ratio '
          f'{fit.scale_ratio:.4f}, distance scale {fit.distance_scale:.4f}', file=out)
    for q in fit.held:
        print(f'held (--params or ideal drive): {q}: {WHY_HELD[q]}', file=out)
    print(f'written ICR model: y_left {icr.y_left:.4f} m, y_right {icr.y_right:.4f} m, x '
          f'{icr.x:.4f} m, scales {icr.scale_left:.4f} / {icr.scale_right:.4f}; chi '
          f'{icr.chi:.3f}, e {icr.eccentricity:.3f}', file=out)
