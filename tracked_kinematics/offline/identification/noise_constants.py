"""
What identify_icr writes beside the ICRs: the odometry noise model and the gyro's constants.

The noise model's constants (:class:`tracked_kinematics.core.noise_model.NoiseModel`) are fitted
on held-out windows of the same recordings (:func:`tracked_kinematics.core.evaluate.
held_out_windows`: leave one recording out with several, held-out time blocks with one;
:func:`tracked_kinematics.core.evaluate.fit_noise`): against a pose, on the final pose errors;
against the gyro alone, on the heading errors (``track``, ``turn``, ``timing``; ``slip`` held).
They are written as odometry_node reads them (``covariance.k_left``, ``covariance.k_right``: the
track random walk; ``covariance.turn``, ``covariance.slip``, ``covariance.timing``; and
``covariance.scale``, the prior of a distance scale held: :func:`held_priors`), with their
provenance under ``identification.covariance.*``. The gyro's ``imu_delay`` and, with a pose,
its ``gyro_scale`` (:func:`tracked_kinematics.core.gyro.fit_gyro_scale`) are written at
the top level. docs/tools/identify_icr.md, "The noise model and the gyro".
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.errors import IdentificationError
from tracked_kinematics.core.evaluate import cut, fit_noise, held_out_windows, recording_windows
from tracked_kinematics.core.evaluate.gyro_noise import fit_gyro_noise, GYRO_TERMS, gyro_windows
from tracked_kinematics.core.identify.reference.delays import imu_delay_problem, sensor_delays
from tracked_kinematics.core.identify.reference.heading_fusion import (
    bias_prior, BIAS_SIGMA_FLOOR, check_gyro_against_pose, fuse_heading, signed_gyro_scale)
from tracked_kinematics.core.identify.segments import covered_spans, over_jumps
from tracked_kinematics.core.noise_model import FITTED
from tracked_kinematics.params import (gyro_config_from_values, icr_from_values,
                                       noise_model_from_values, track_noise_from_values)

LENGTHS = (5.0, 10.0)
"""Window lengths the noise model is fitted on, s (evaluate_model's defaults)."""
SHORTER = ((2.5, 5.0), (1.0, 2.0), (0.5, 1.0))
"""The window lengths of recordings whose pieces are too short for :data:`LENGTHS`, longest
first: the first pair whose longer window fits in the longest piece (DRIVE's 2-s training
windows: 0.5 / 1 s). Without them the covariance of such a log was not written, and the
node's default was 3-10 times over-confident on the windowed Warthog runs of
../shared/realdata (mean NEES 9-20 after 0.5-1.5 s, held out); fitted on 0.5 / 1-s windows,
1.3-4.5."""


def fit_lengths(recordings) -> tuple[float, float]:
    """Return the window lengths to fit the noise model of ``recordings`` on, s."""
    longest = 0.0
    for rec in recordings:
        start, end = covered_spans(rec)
        if len(start):
            longest = max(longest, float((end - start).max()))
    if longest >= LENGTHS[-1]:
        return LENGTHS
    return next((pair for pair in SHORTER if pair[-1] <= longest), LENGTHS)


SCALE_SPREAD = 0.01
"""A gyro scale is written only when it differs from 1 by more than this and 3 standard errors."""

COVARIANCE_KEYS = {'track': ('covariance.k_left', 'covariance.k_right'),
                   'turn': ('covariance.turn',), 'slip': ('covariance.slip',),
                   'timing': ('covariance.timing',), 'scale': ('covariance.scale',)}
"""The terrain file's (odometry_node's) names of each constant of the noise model."""


@dataclass(frozen=True)
class Extras:
    """
    The noise model and the gyro's constants of one identification.

    ``values`` are top-level terrain values, ``record`` goes under ``identification.``,
    ``report`` into the JSON report, ``lines`` are printed after the table.
    """

    values: dict = field(default_factory=dict)
    record: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict)
    lines: tuple = ()


def noise_values(found, lengths=LENGTHS) -> tuple[dict, dict]:
    """
    Return a :class:`~tracked_kinematics.core.evaluate.NoiseFit` as terrain values and record.

    Returns
    -------
    values : dict
        ``covariance.*`` (odometry_node's names, :data:`COVARIANCE_KEYS`).
    record : dict
        ``covariance.*`` provenance, to go under ``identification.``.

    """
    model = found.model
    values = {key: float(getattr(model, term))
              for term, keys in COVARIANCE_KEYS.items() for key in keys}
    record = {'covariance.fitted': list(found.fitted), 'covariance.held': list(found.held),
              'covariance.errors': found.errors, 'covariance.windows': int(found.windows),
              'covariance.independent_windows': round(float(found.independent), 1),
              'covariance.window_lengths': [float(w) for w in lengths]}
    return values, record


def _noise_lines(found, held_out: str, lengths) -> list[str]:
    m = found.model
    held = (f'; held at the prior: {", ".join(found.held)}' if found.held else '')
    lines = [f'noise model ({found.errors} errors of {found.windows} windows of '
             f'{"/".join(f"{w:g}" for w in lengths)} s, ~{found.independent:.0f} independent, '
             f'{held_out}): track {m.track:.2e} m^2/m, turn {m.turn:.2e} rad^2/rad, slip '
             f'{m.slip:.2e} m^2/rad, timing {m.timing:.2e} s^2{held}']
    if tuple(lengths) != LENGTHS:
        shown = '/'.join(f'{w:g}' for w in lengths)
        lines.append(f'noise model: no piece of the recordings holds a window of '
                     f'{LENGTHS[-1]:g} s: fitted on windows of {shown} s, its growth beyond '
                     f'{lengths[-1]:g} s extrapolated (check it with evaluate_model --window '
                     f'on longer drives)')
    return lines


MAX_WINDOWS = 3000
"""Most windows of one length the noise model is fitted on: evenly spaced starts beyond."""


def _thinned(windows):
    """
    Keep at most :data:`MAX_WINDOWS` windows of each length, their starts evenly spaced.

    Windows start at every reference sample and overlap: on a long log, every few tenths of
    a second is as informative (the fit weighs the windows by how many are independent) and
    the fit is linear in their number.
    """
    import numpy as np
    keep = np.zeros(len(windows), dtype=bool)
    for length in np.unique(windows.length):
        mine = np.flatnonzero(windows.length == length)
        step = max(1, -(-len(mine) // MAX_WINDOWS))
        keep[mine[::step]] = True
    return windows.select(keep)


def _noise(windows, errors, free, held_out, lengths=LENGTHS):
    """Fit the noise model to windows; return (values, record, report, lines) or a reason."""
    windows = _thinned(windows)
    try:
        found = fit_noise(windows, free=free, errors=errors)
    except ValueError as err:
        return None, str(err)
    values, record = noise_values(found, lengths)
    record['covariance.held_out'] = held_out
    report = {'model': {t: getattr(found.model, t) for t in COVARIANCE_KEYS},
              'fitted': list(found.fitted), 'held': list(found.held), 'errors': found.errors,
              'windows': int(found.windows), 'independent_windows': float(found.independent),
              'window_lengths_s': list(lengths), 'held_out': held_out}
    return (values, record, report, _noise_lines(found, held_out, lengths)), ''


def _not_fitted(reason: str) -> Extras:
    return Extras(record={'covariance.not_fitted': reason},
                  report={'covariance': {'not_fitted': reason}},
                  lines=(f'noise model: not fitted ({reason}); covariance.* not written',))


def _held_out_kind(recordings) -> str:
    return ('leave one recording out' if len(recordings) >= 2
            else 'held-out time blocks')


def pose_extras(result, options, track_width: float) -> Extras:
    """
    Fit the noise model on the held-out windows of a segment identification (a pose reference).

    Each fold's ICRs are fitted as the main fit (its model, heading weight, loss, segments),
    without its comparisons; the recordings are ``result``'s, their delay removed.

    Parameters
    ----------
    result : Identification
        :func:`tracked_kinematics.core.identify.identify`'s.
    options : FitOptions
        identify_icr's options.
    track_width : float
        m.

    """
    recordings = list(result.recordings)
    fitted = result.fit
    model = fitted.model if fitted.model.constant_icr else ident.build_model(
        'icr_scales', track_width)
    settings = options.identify
    start = fitted.p if fitted.model.constant_icr else None

    def fit_icr(recs):
        segments = ident.build_segments(recs, result.segment_length)
        if len(segments):
            segments = segments.select(~over_jumps(segments, recs, track_width))
            segments = segments.select(segments.travel >= settings.min_travel)
        try:
            # From the full fit's parameters, one round: a fold differs little from it.
            return ident.fit(model, segments, p0=start, heading_weight=fitted.heading_weight,
                             loss=settings.loss, max_nfev=settings.max_nfev, rounds=1,
                             check=False).icr
        except (IdentificationError, ValueError):
            return result.icr   # too little in this fold: the full fit's ICRs
    lengths = fit_lengths(recordings)
    windows = held_out_windows(recordings, fit_icr, lengths, settings.min_speed,
                               track_width)
    done, reason = _noise(windows, 'pose', FITTED, _held_out_kind(recordings), lengths)
    if done is None:
        return _not_fitted(reason)
    values, record, report, lines = done
    return Extras(values, record, {'covariance': report}, tuple(lines))


def reference_extras(fit, recordings, options, track_width: float, base=None) -> Extras:
    """
    Fit the noise model and the gyro's constants of a reference calibration.

    With a pose among the references, the noise model is fitted to the pose errors (each
    held-out part scored with the ICRs calibrated without it) and the gyro's scale against the
    pose's heading; with the gyro alone, to the heading errors against the gyro (``slip``
    held: a gyro does not see it). ``imu_delay`` is written whenever there is a gyro timed
    (:func:`~tracked_kinematics.core.identify.reference.delays.imu_delay_problem`).

    Parameters
    ----------
    fit : ReferenceFit
        :func:`tracked_kinematics.core.identify.fit_recordings`'s, on ``recordings``.
    recordings : sequence of Recording
        As read.
    options : FitOptions
        identify_icr's options.
    track_width : float
        m.
    base : IcrParams, optional
        The values the calibration held.

    """
    recordings = list(recordings)
    values, record, report, lines = {}, {}, {}, []
    has_gyro = fit.report.get('imu_delay') is not None
    has_pose = fit.report.get('pose_delay') is not None
    segment_length = float(options.identify.segment_length or 1.0)
    min_speed = options.identify.min_speed
    if has_gyro and not imu_delay_problem(fit.imu_delay):
        values['imu_delay'] = float(fit.imu_delay.delay)
    if has_pose:
        shifted = _per_bag_delay(recordings, float(fit.pose_delay.delay))
        imu_delay = float(fit.imu_delay.delay) if has_gyro else 0.0

        def fit_icr(recs):
            try:
                return ident.fit_recordings(
                    recs, track_width, base=base, imu_delay=imu_delay, pose_delay=0.0,
                    segment_length=segment_length,
                    gnss_antenna=tuple(options.gnss_antenna)).icr
            except (IdentificationError, ValueError):
                return fit.icr
        lengths = fit_lengths(shifted)
        windows = held_out_windows(shifted, fit_icr, lengths, min_speed, track_width)
        done, reason = _noise(windows, 'pose', FITTED, _held_out_kind(recordings), lengths)
        if has_gyro:
            scale_lines, scale_values, scale_record = _gyro_scale(shifted, imu_delay)
            values.update(scale_values)
            record.update(scale_record)
            report['gyro_scale'] = {k.replace('gyro_scale', 'fitted'): v
                                    for k, v in scale_record.items()}
            report['gyro_scale']['written'] = scale_values['gyro_scale']
            lines += scale_lines
    elif has_gyro:
        heading = [ident.heading_reference(r, fit.imu_delay.delay, b)
                   for r, b in zip(recordings, fit.biases)]
        raw = {id(h): r for h, r in zip(heading, recordings)}
        delay = float(fit.imu_delay.delay)

        def fit_icr(recs):
            try:
                return ident.fit_recordings([raw[id(h)] for h in recs], track_width,
                                            base=base, imu_delay=delay,
                                            segment_length=segment_length).icr
            except (IdentificationError, ValueError, KeyError):
                return fit.icr
        lengths = fit_lengths(heading)
        if len(heading) >= 2:
            windows = held_out_windows(heading, fit_icr, lengths, min_speed, track_width)
            kind = 'leave one recording out'
        else:
            # One recording: a time block of it has no gyro to calibrate on; the calibration
            # (chi and the scale ratio, from the whole drive) scores it.
            windows = recording_windows(heading, fit.icr, lengths, min_speed, track_width)
            kind = 'in sample: one recording'
        done, reason = _noise(windows, 'heading', ('track', 'turn', 'timing'), kind, lengths)
    else:
        done, reason = None, 'no pose and no gyro: positions alone do not time the errors'
    if done is None:
        extra = _not_fitted(reason)
        return Extras({**values, **extra.values}, {**record, **extra.record},
                      {**report, **extra.report}, tuple(lines) + extra.lines)
    n_values, n_record, n_report, n_lines = done
    n_lines = n_lines + held_priors(fit, track_width, n_values, n_record, n_report)
    return Extras({**values, **n_values}, {**record, **n_record},
                  {**report, 'covariance': n_report}, tuple(n_lines + lines))


DISTANCE_SCALE_PRIOR = 0.05
"""Relative uncertainty of a distance scale held at the nominal one (tyres under load, wear,
longitudinal slip): the Warthog's runs of ../shared/realdata are 4 % short of nominal."""
ICR_X_PRIOR = 0.1
"""Uncertainty of an ``icr.x`` held at the base's, in track widths (the fits of
../shared/realdata: 0.08 m on the Warthog, 0.06 m on the Marmotte)."""
PRIOR_WINDOW = max(LENGTHS)
"""s: the window length at which the ``icr.x`` prior's error enters the noise model exactly,
the longer of the windows the model was fitted on (shorter windows get more than theirs). The
distance scale's enters every window exactly (``covariance.scale``); through the ``timing``
term, constant in the length and exact at 10 s, it gave 5-s windows 4 times theirs: 99-100 %
of the held-out Warthog grass runs' 5-s windows inside the 95 % ellipse."""


def held_priors(fit, track_width: float, values: dict, record: dict, report: dict) -> list:
    """
    Add the uncertainty of what a reference calibration held to the noise model; its lines.

    A distance scale held (no pose, GNSS or straight) is off by ``sigma_s`` = :data:`DISTANCE_
    SCALE_PRIOR`: the path keeps its shape and its displacement ``p`` is off by ``sigma_s p``,
    fully correlated over a window: ``covariance.scale += sigma_s^2`` (the noise model's
    ``scale`` term, exact for a window of any length). An ``icr.x`` held (no positions) moves
    the path sideways by about ``sigma_x`` per radian turned: ``slip += sigma_x^2 theta_T``,
    ``theta_T`` the mean angle turned in ``T``. The record says which constants were held and
    at what uncertainty.
    """
    held = list(fit.held)
    lines, priors = [], {}
    window = max(record.get('covariance.window_lengths', (PRIOR_WINDOW,)))
    data = fit.report.get('data') or {}
    moving_time = data.get('moving_segments', 0) * float(fit.report.get('segment_length', 1.0))
    if 'distance_scale' in held:
        sigma = DISTANCE_SCALE_PRIOR
        values['covariance.scale'] = values.get('covariance.scale', 0.0) + sigma ** 2
        priors['distance_scale'] = sigma
    if 'icr.x' in held and moving_time > 0:
        sigma = ICR_X_PRIOR * track_width
        turned = float(data.get('turned_rad', 0.0)) / moving_time * window
        values['covariance.slip'] += sigma ** 2 * turned
        priors['icr.x'] = sigma
    if priors:
        record['covariance.held_prior'] = [f'{k} +- {v:.3g}' for k, v in priors.items()]
        report['held_prior'] = priors
        lines.append('noise model: the uncertainty of what was held added (' + ', '.join(
            f'{k} +- {v:.3g}' + (' (relative)' if k == 'distance_scale' else ' m')
            for k, v in priors.items()) + f', icr.x exact for windows of {window:.1f} s): '
            f'scale {values.get("covariance.scale", 0.0):.2e}, slip '
            f'{values["covariance.slip"]:.2e} m^2/rad written')
    return lines


def gyro_extras(recordings, topic: str, imu_delay='auto'):
    """
    Return the gyro's constants of a pose identification whose bags also carry a gyro.

    ``recordings`` (as read with the gyro on ``topic`` and the pose): ``imu_delay`` (the
    gyro's stamps against the encoders, model-free, as ``--imu-topic`` estimates it, or as
    given), ``gyro_scale`` (against the pose's heading), ``gyro_bias`` and ``gyro_bias_sigma``
    (its drift against the pose's heading, :func:`~tracked_kinematics.core.identify.reference.
    fusion.bias_prior`), so that odometry_node's ``imu_topic`` and evaluate_model's
    ``--fuse-imu`` use the gyro at the right time. A gyro that does not turn as the pose does
    (:func:`~tracked_kinematics.core.identify.reference.heading_fusion.check_gyro_against_pose`:
    sign, axis, clock) is refused: none of its constants are written, and the line says why.

    Returns
    -------
    extras : Extras
    gyro : tuple or None
        ``(recordings with the pose's delay removed, imu_delay, gyro scale to divide out)``
        for a gyro to fuse; None for a refused or untimed one.

    """
    try:
        imu, pose = sensor_delays(list(recordings), imu_delay, 'auto')
    except (IdentificationError, ValueError) as err:
        return Extras(record={'gyro_topic': topic, 'imu_delay_method': f'not determined: {err}'},
                      lines=(f'gyro {topic}: delay not determined ({err}); imu_delay not '
                             'written',)), None
    problem = imu_delay_problem(imu)
    if problem:
        return Extras(record={'gyro_topic': topic,
                              'imu_delay_method': f'not used: {problem}'},
                      lines=(f'gyro {topic}: imu_delay {problem}; give --imu-delay, measured '
                             'on firm ground; no gyro constant written',)), None
    imu_delay = float(imu.delay)
    shifted = _per_bag_delay(list(recordings), float(pose.delay))
    scale, std = _fitted_scale(shifted, imu_delay)
    refused = check_gyro_against_pose(scale, std)
    if refused:
        return Extras(record={'gyro_topic': topic, 'gyro_refused': refused},
                      report={'gyro': {'topic': topic, 'refused': refused}},
                      lines=(f'gyro {topic}: left out ({refused}); imu_delay, gyro_scale and '
                             'gyro_bias not written',)), None
    scale_lines, scale_values, scale_record = _gyro_scale(shifted, imu_delay)
    record = {'gyro_topic': topic, 'imu_delay': imu_delay,
              'imu_delay_method': imu.uncertainty or 'not determined', **scale_record}
    if math.isfinite(imu.std):
        record['imu_delay_std'] = float(imu.std)
    written = scale_values['gyro_scale']
    bias_values, bias_line = _bias(shifted, imu_delay, written)
    report = {'gyro': {'topic': topic, 'imu_delay': imu_delay, 'gyro_scale': written,
                       **bias_values}}
    lines = (f'gyro {topic}: imu_delay {imu_delay:+.3f} s', *scale_lines, bias_line)
    return (Extras({'imu_delay': imu_delay, **scale_values, **bias_values}, record, report,
                   lines), (shifted, imu_delay, written))


GYRO_AIDED_KEYS = {t: f'covariance.gyro_aided.{t}' for t in GYRO_TERMS}
"""The terrain file's names of the gyro-aided odometry's own constants (odometry_node's)."""


def gyro_aided_extras(values: dict, recordings, track_width: float,
                      min_speed: float | None) -> Extras:
    """
    Fit the gyro-aided odometry's own noise constants on its windows of the recordings.

    ``values`` are the terrain file's so far (ICRs, noise model, gyro constants), read as
    odometry_node reads them; ``recordings`` those of :func:`gyro_extras` (the pose's delay
    taken off). The odometry is replayed as the node runs with ``imu_topic``, reset every 5
    and 10 s from two schedules (:func:`tracked_kinematics.core.evaluate.gyro_noise.
    gyro_windows`), and ``slip``, ``timing`` and ``drift`` fitted to the windows' final
    position errors (:func:`~tracked_kinematics.core.evaluate.gyro_noise.fit_gyro_noise`):
    written as ``covariance.gyro_aided.*``. In sample: the ICRs are the ones fitted on the
    same recordings (the gyro gives the heading, which held-out ICRs would change most).
    """
    recordings = list(recordings)
    lengths = fit_lengths(recordings)
    try:
        pieces = [p for k, rec in enumerate(recordings)
                  for p in cut(rec, k, True, track_width).pieces]
        windows = gyro_windows(recordings, pieces, icr_from_values(values),
                               gyro_config_from_values(values),
                               track_noise_from_values(values),
                               noise_model_from_values(values), lengths, min_speed)
        model = fit_gyro_noise(windows, noise_model_from_values(values))
    except (KeyError, ValueError) as err:
        return Extras(record={'covariance.gyro_aided.not_fitted': str(err)},
                      lines=(f'gyro-aided noise model: not fitted ({err}); '
                             'covariance.gyro_aided.* not written',))
    found = {key: float(getattr(model, t)) for t, key in GYRO_AIDED_KEYS.items()}
    shown = '/'.join(f'{w:g}' for w in lengths)
    n = len(windows) // windows.schedules
    return Extras(found, {'covariance.gyro_aided.windows': n,
                          'covariance.gyro_aided.window_lengths': [float(w) for w in lengths],
                          'covariance.gyro_aided.held_out': 'in sample'},
                  {'covariance_gyro_aided': {**{t: getattr(model, t) for t in GYRO_TERMS},
                                             'windows': n, 'window_lengths_s': list(lengths)}},
                  (f'gyro-aided noise model (position errors of ~{n} windows of {shown} s, '
                   f'the node reset every window, in sample): slip {model.slip:.2e} m^2/rad, '
                   f'timing {model.timing:.2e} s^2, drift {model.drift:.2e}',))


def _bias(recordings, imu_delay: float, scale: float):
    """Return the gyro bias prior (terrain values) and its line, from the drift on the pose."""
    try:
        _, fusion = fuse_heading(recordings, imu_delay, scale)
    except ValueError as err:
        return {}, f'gyro bias: not measured ({err}); gyro_bias not written'
    errors = [e for e in fusion.bias_errors if math.isfinite(e)]
    # The error of the mean of the bags' biases.
    error = math.sqrt(sum(e * e for e in errors)) / len(errors) if errors else 0.0
    bias, sigma = bias_prior(fusion.biases, error)
    if not math.isfinite(bias):
        return {}, 'gyro bias: not measured; gyro_bias not written'
    per = ', '.join(f'{b:+.5f}' for b in fusion.biases)
    return ({'gyro_bias': bias, 'gyro_bias_sigma': sigma},
            f'gyro bias {bias:+.5f} +- {sigma:.4f} rad/s (per bag {per}; the sigma is the '
            'spread between bags, at least '
            f'{BIAS_SIGMA_FLOOR:g} rad/s: the run-to-run change a restart sees)')


def _fitted_scale(recordings, imu_delay: float):
    """Return the gyro's scale against the pose's heading (negative: turns the other way)."""
    return signed_gyro_scale(recordings, imu_delay)


def _per_bag_delay(recordings, pooled: float):
    """
    Return the recordings with the pose's delay taken off, each bag's own where determined.

    The pose delay of lidar ICP varies from bag to bag (0.19-0.26 s on the Warthog runs);
    a delay off by a few 0.01 s lowers the gyro scale fitted against the pose's heading by
    about 1 % (the regression on a time-shifted heading is attenuated).
    """
    try:
        each = ident.estimate_delays(recordings)[1]
    except (IdentificationError, ValueError):
        each = []
    delays = [e.delay if e.determined else pooled for e in each] if each else \
        [pooled] * len(recordings)
    return [ident.correct_ground_truth([r], float(d))[0] for r, d in zip(recordings, delays)]


def _gyro_scale(recordings, imu_delay: float):
    """Return the printed lines, terrain values and record of the gyro scale fit."""
    scale, std = _fitted_scale(recordings, imu_delay)
    determined = (math.isfinite(std)
                  and abs(scale - 1.0) > max(3.0 * std, SCALE_SPREAD))
    record = {'gyro_scale_fitted': float(scale)}
    if math.isfinite(std):
        record['gyro_scale_std'] = float(std)
    record['gyro_scale_method'] = ('fitted against the pose' if determined else
                                   'not determined: 1.0 written (the fit is within 3 standard '
                                   'errors or 1 % of 1)')
    written = float(scale) if determined else 1.0
    std_text = f' +- {std:.4f}' if math.isfinite(std) else ' (too few segments)'
    line = (f'gyro scale (measured / true): fitted {scale:.4f}{std_text}; written '
            f'{written:.4f}' + ('' if determined else ' (not determined: within 3 standard '
                                                      'errors or 1 % of 1)'))
    return [line], {'gyro_scale': written}, record


def add_extras(values: dict, report: dict, lines: list, extras: Extras) -> None:
    """Add :class:`Extras` to an identification's terrain values, report and printed lines."""
    values.update(extras.values)
    values.update({f'identification.{k}': v for k, v in extras.record.items()
                   if not (isinstance(v, float) and not math.isfinite(v))})
    report.update(extras.report)
    lines.extend(extras.lines)
