"""
The whole calibration without ground truth: :func:`fit_recordings`, step by step.

:func:`fit_recordings` checks the data (:mod:`.recordings`), removes the delays
(:mod:`.delays`), fits the heading (:mod:`.headings`, :mod:`.heading_fit`), then the
distance (:mod:`.positions`), and builds the ICR model and its report here;
:func:`fit_from_reference` is the same for one recording of plain arrays (nodes).
"""

from __future__ import annotations

import math

import numpy as np

from .delays import delay_report, imu_delay_problem, sensor_delays
from .heading_fit import fit_heading, HeadingFit
from .headings import heading_data, HeadingData
from .positions import DistanceFit, fit_distance
from .recordings import (calibration_quantities, check_gyro, check_saturation, clean_gyro,
                         QUANTITIES, ReferenceFit)
from ...errors import ExcitationError, FitError, SensorDataError
from ...kinematics import IcrParams
from ...recording import Recording


def _checked_recordings(recordings, track_width: float, hold, gnss_antenna,
                        segment_length: float, straight_distance):
    """
    Check the arguments and sensor data; return the recordings with gyros cleaned, hold, antenna.

    Raises ValueError for an invalid argument or a recording without heading reference, and
    SensorDataError for a gyro that reads nothing or saturates, or an orientation without yaw.
    """
    recs = list(recordings)
    if not recs:
        raise ValueError('no recordings')
    hold = tuple(hold)
    if any(q not in QUANTITIES for q in hold):
        raise ValueError(f'hold must name some of {", ".join(QUANTITIES)}, got {hold!r}')
    if not (math.isfinite(track_width) and track_width > 0):
        raise ValueError(f'track_width must be > 0, got {track_width!r}')
    gnss_antenna = tuple(float(a) for a in gnss_antenna)
    if len(gnss_antenna) != 2 or not all(math.isfinite(a) for a in gnss_antenna):
        raise ValueError(f'gnss_antenna must be two finite numbers (m), got {gnss_antenna!r}')
    if not segment_length > 0:
        raise ValueError(f'segment_length must be > 0, got {segment_length!r}')
    if not all(r.gyro_t is not None or r.pose is not None for r in recs):
        raise ValueError('every recording needs a heading reference: a gyro or a pose')
    for r in recs:
        if r.gyro_t is None:
            continue
        if r.gyro_rate is not None:
            what = f'{r.name or "recording"}: the gyro'
            check_gyro(r.gyro_rate, what)
            check_saturation(r.gyro_t, r.gyro_rate, r.enc_t, r.left, r.right, track_width,
                             what)
        elif not np.any(np.isfinite(r.gyro_yaw)):
            raise SensorDataError(f'{r.name or "recording"}: the orientation has no yaw')
    recs = [clean_gyro(r) if r.gyro_t is not None else r for r in recs]
    if straight_distance is not None and not (math.isfinite(straight_distance)
                                              and straight_distance > 0):
        raise ValueError(f'straight_distance must be > 0 m, got {straight_distance!r}')
    return recs, hold, gnss_antenna


def _model(track_width: float, heading: HeadingFit, distance: DistanceFit, determined,
           base: IcrParams) -> IcrParams:
    """
    Return the ICR model of the fitted quantities (the base's where held); FitError if invalid.

    ``W = s / u``, treads at ``c +- W / 2``, scales ``2 s / (1 + rho)`` and ``2 s rho / (1 +
    rho)``.
    """
    s, u, rho, c = distance.s, heading.u, heading.rho, distance.c
    width = s / u if 'chi' in determined else calibration_quantities(base)[2]
    s_left, s_right = 2.0 * s / (1.0 + rho), 2.0 * s * rho / (1.0 + rho)
    try:
        return IcrParams(track_width, c + 0.5 * width, c - 0.5 * width, distance.x, s_left,
                         s_right)
    except ValueError as err:
        raise FitError(f'the calibration gives an invalid ICR model: {err}') from None


def _reference_name(recs, straight_distance) -> str:
    """Return the references used, ``imu``, ``pose``, ``gnss``, ``straight`` joined by ``+``."""
    names = ['imu'] if any(r.gyro_t is not None for r in recs) else []
    names += ['pose'] if any(r.pose is not None for r in recs) else []
    names += ['gnss'] if any(r.positions is not None for r in recs) else []
    names += ['straight'] if straight_distance is not None else []
    return '+'.join(names)


def _report(icr: IcrParams, reference: str, determined, held, heading: HeadingFit,
            distance: DistanceFit, headings: HeadingData, delays, segment_length: float,
            n_rec: int) -> dict:
    """Return the JSON-ready report: model, what is determined, errors (None where held), stats."""
    imu, pose_delay = delays
    std_rho = heading.std_rho if 'scale_ratio' in determined else None
    gyro = any(g is not None for g in headings.gyro)
    pose = any(p is not None for p in headings.pose)
    return {
        'reference': reference, 'determined': determined, 'held': held,
        'icr': {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
                'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
                'chi': icr.chi, 'eccentricity': icr.eccentricity + 0.0},
        'distance_scale': distance.s, 'scale_ratio': heading.rho, 'turn_gain': heading.u,
        'icr_offset': distance.c,
        'standard_errors': {'turn_gain': heading.std_u, 'scale_ratio': std_rho,
                            'distance_scale': distance.std_s,
                            'icr.x': distance.std_x if 'icr.x' in determined else None,
                            'icr_offset': distance.std_c if 'icr_offset' in determined
                            else None},
        'segment_length': segment_length,
        'heading': heading.stats, 'positions': distance.stats,
        'gyro': None if not gyro else {
            'bias_rad_s': [b for b in heading.biases if b is not None],
            'noise_rad_per_sqrt_s': heading.stats['imu']['residual_std_rad']
            / math.sqrt(segment_length),
        },
        'imu_delay': delay_report(imu) if gyro else None,
        'pose_delay': delay_report(pose_delay) if pose else None,
        'straight': distance.straight,
        'data': {'recordings': n_rec, 'moving_segments': int(np.count_nonzero(headings.moving)),
                 'turned_rad': headings.turned, 'driven_m': headings.driven},
    }


def fit_recordings(recordings, track_width: float, *, base: IcrParams | None = None,
                   imu_delay='auto', pose_delay='auto', segment_length: float = 1.0,
                   straight_distance: float | None = None,
                   position_window: float | None = None, hold=(),
                   gnss_antenna=(0.0, 0.0), strict_imu_delay: bool = False) -> ReferenceFit:
    """
    Calibrate from gyro, pose and/or positions over several recordings.

    Checks the sensor data, removes the gyro and pose delays, fits the turn gain, veer and gyro
    biases to heading increments (Martinez et al. 2005 eqs. (9) and (16) with the scales of eqs.
    (20)-(21)), then the distance scale (eqs. (7)-(8)) from a straight or from positions.

    Parameters
    ----------
    recordings : sequence of Recording
        One vehicle and terrain; each needs a gyro or a pose.
    track_width : float
        m.
    base : IcrParams, optional
        Values of what is held (default: ideal drive of ``track_width``).
    imu_delay, pose_delay : float or 'auto'
        s of gyro / pose stamps behind the encoders to remove, or 'auto' to estimate.
    segment_length : float
        Heading segments, s.
    straight_distance : float, optional
        The recordings are one straight drive of this many metres.
    position_window : float, optional
        s; default :data:`.positions.POSITION_WINDOW` per source.
    hold : sequence of str
        Quantities of :data:`QUANTITIES` to hold at ``base`` even where determined.
    gnss_antenna : pair of float
        Antenna in base_link, m (unknown, its lever arm would be fitted as ``icr.x``).
    strict_imu_delay : bool
        Refuse a gyro delay estimated but not known to :data:`.delays.IMU_DELAY_STD_LIMIT`
        (:func:`.delays.imu_delay_problem`) instead of fitting with it; one not determined
        (no timing in the data: a straight) is taken as 0, as without it.

    Raises
    ------
    SensorDataError, ExcitationError, FitError
        Unusable sensor data, too little excitation (with ``strict_imu_delay``, a gyro not
        timed), an invalid result.

    """
    # 1. The data, checked.
    recs, hold, gnss_antenna = _checked_recordings(recordings, track_width, hold, gnss_antenna,
                                                   segment_length, straight_distance)
    base = base or IcrParams.ideal(track_width)
    straight = straight_distance is not None
    # 2. The delays.
    imu, pose = sensor_delays(recs, imu_delay, pose_delay)
    problem = imu_delay_problem(imu) if strict_imu_delay and imu.determined else ''
    if problem:
        raise ExcitationError(f'the gyro cannot be timed: imu_delay {problem}; give '
                              '--imu-delay, measured on firm ground')
    # 3. The heading segments.
    headings = heading_data(recs, imu.delay, pose.delay, segment_length, straight)
    # 4. The heading: u, v and the biases.
    heading = fit_heading(headings, len(recs), hold, base, straight)
    # 5. The distance: positions, a straight drive, or held.
    distance = fit_distance(recs, headings, heading, base, hold, straight_distance,
                            pose.delay, position_window, gnss_antenna)
    # 6. The model and its report.
    determined = heading.determined + distance.determined
    held = heading.held + [q for q in ('distance_scale', 'icr.x', 'icr_offset')
                           if q not in determined]
    icr = _model(track_width, heading, distance, determined, base)
    order = {q: i for i, q in enumerate(QUANTITIES)}
    determined.sort(key=order.get)
    held.sort(key=order.get)
    reference = _reference_name(recs, straight_distance)
    report = _report(icr, reference, determined, held, heading, distance, headings,
                     (imu, pose), segment_length, len(recs))
    return ReferenceFit(icr, reference, determined, held, distance.s, heading.rho, heading.u,
                        imu, pose, [b for b in heading.biases if b is not None], report)


def fit_from_reference(enc_t, left, right, *, track_width: float, gyro_t=None, gyro_rate=None,
                       gyro_yaw=None, pose=None, positions=None,
                       straight_distance: float | None = None, base: IcrParams | None = None,
                       imu_delay='auto', pose_delay='auto', segment_length: float = 1.0,
                       position_window: float | None = None, hold=(),
                       gnss_antenna=(0.0, 0.0)) -> ReferenceFit:
    """
    Calibrate one recording from plain arrays: the entry point of nodes.

    Parameters
    ----------
    enc_t, left, right : array_like, shape (N,)
        Encoder times (s, increasing) and cumulative nominal track travel (m).
    track_width : float
        m.
    gyro_t, gyro_rate, gyro_yaw : array_like, optional
        Gyro stamps (s) and yaw rates (rad/s, REP-103), or yaw angles (rad) instead.
    pose : tuple of array_like, optional
        ``(t, x, y, yaw)`` of a pose reference (s, m, m, rad).
    positions : tuple of array_like, optional
        ``(t, x, y)`` in a local plane (GNSS), s, m, m.
    straight_distance, base, imu_delay, pose_delay, segment_length
        As :func:`fit_recordings`.
    position_window, hold, gnss_antenna
        As :func:`fit_recordings`.

    """
    pose = (None,) * 4 if pose is None else pose
    gnss = {} if positions is None else dict(zip(('gnss_t', 'gnss_x', 'gnss_y'), positions))
    rec = Recording(enc_t, left, right, *pose, gyro_t=gyro_t, gyro_rate=gyro_rate,
                    gyro_yaw=gyro_yaw, **gnss)
    return fit_recordings([rec], track_width, base=base, imu_delay=imu_delay,
                          pose_delay=pose_delay, segment_length=segment_length,
                          straight_distance=straight_distance,
                          position_window=position_window, hold=hold,
                          gnss_antenna=gnss_antenna)
