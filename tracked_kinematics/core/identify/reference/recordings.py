"""
The result of a calibration from references, and the checks of the sensor data.

:class:`ReferenceFit` is what :func:`.calibration.fit_recordings` makes of recordings with a
gyro, a pose or positions. The sensor data are checked before any fit: :func:`check_gyro`
refuses a gyro that reads nothing, :func:`check_saturation` one stuck at its range.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..delay import DelayEstimate, fixed_delay
from ...errors import SensorDataError
from ...kinematics import IcrParams
from ...recording import Recording

QUANTITIES = ('chi', 'scale_ratio', 'distance_scale', 'icr.x', 'icr_offset')
"""What a calibration determines or holds (``identification.determined`` / ``held``)."""
SATURATION_SHARE = 0.005
"""Share of gyro readings stuck at the largest magnitude that means saturation."""


@dataclass
class ReferenceFit:
    """
    Result of :func:`.calibration.fit_from_reference` / :func:`.calibration.fit_recordings`.

    Attributes
    ----------
    icr : IcrParams
        The terrain model: fitted where determined, the base values where held.
    reference : str
        ``imu``, ``pose``, ``gnss``, ``straight`` joined by ``+``.
    determined, held : list of str
        Quantities of :data:`QUANTITIES` the references determine / that are held.
    distance_scale, scale_ratio, turn_gain : float
        ``(s_l + s_r) / 2``, ``s_r / s_l``, ``u = s / W`` (rad per m of track difference).
    imu_delay, pose_delay : DelayEstimate
        Delays of the gyro / pose stamps behind the encoders (removed).
    biases : list of float
        Gyro bias per recording, rad/s.
    report : dict
        Everything above and the noise and fit statistics, JSON-ready.

    """

    icr: IcrParams
    reference: str
    determined: list
    held: list
    distance_scale: float
    scale_ratio: float
    turn_gain: float
    imu_delay: DelayEstimate = field(default_factory=lambda: fixed_delay(0.0))
    pose_delay: DelayEstimate = field(default_factory=lambda: fixed_delay(0.0))
    biases: list = field(default_factory=list)
    report: dict = field(default_factory=dict)


def check_gyro(rates, what: str = 'the gyro') -> None:
    """
    Refuse yaw rates that cannot be a gyro's: none, or all zero or non-finite.

    Raises
    ------
    SensorDataError
        Naming the problem, one line.

    """
    rates = np.asarray(rates, dtype=float)
    finite = rates[np.isfinite(rates)]
    if rates.size == 0:
        raise SensorDataError(f'{what}: no readings')
    if finite.size < 0.5 * rates.size or not np.any(finite != 0.0):
        raise SensorDataError(f'{what}: no angular velocity (the readings are all zero or '
                              'NaN): is angular_velocity.z filled?')


def check_saturation(gyro_t, rates, enc_t, left, right, track_width: float,
                     what: str = 'the gyro') -> None:
    """
    Refuse a saturated gyro: readings stuck at their top while the tracks turn faster.

    A pile-up of readings at exactly the largest magnitude is a saturation when, at those
    readings, the tracks turn markedly faster (the 90th percentile of the turn rate they
    give, through the gyro-to-track ratio of the other readings, above 1.15 x the limit): a
    robot that merely holds a constant turn rate reads the same ratio.

    Raises
    ------
    SensorDataError
        With the number of readings and the limit, one line.

    """
    rates = np.asarray(rates, dtype=float)
    ok = np.isfinite(rates)
    gyro_t, rates = np.asarray(gyro_t, dtype=float)[ok], rates[ok]
    top = float(np.max(np.abs(rates))) if rates.size else 0.0
    if top <= 0:
        return
    stuck = np.abs(np.abs(rates) - top) <= 1e-9 * max(top, 1.0)
    if np.count_nonzero(stuck) < max(3, SATURATION_SHARE * rates.size):
        return
    half = 0.25
    turn = (np.interp(gyro_t + half, enc_t, right - left)
            - np.interp(gyro_t - half, enc_t, right - left)) / (2 * half * track_width)
    strong = np.abs(turn) > 1e-3
    others = ~stuck & strong & (np.abs(rates) > 0.3 * top)
    at_top = stuck & strong
    if np.count_nonzero(at_top) < 3 or np.count_nonzero(others) < 3:
        return
    gain = float(np.median(np.abs(rates[others]) / np.abs(turn[others])))
    expected = float(np.percentile(gain * np.abs(turn[at_top]), 90))
    if expected > 1.15 * top:
        raise SensorDataError(f'{what}: saturated: {np.count_nonzero(stuck)} readings at '
                              f'{top:.4g} rad/s, its limit, while the tracks turn up to '
                              f'{expected:.3g} rad/s; '
                              'turn slower or set a wider gyro range')


def clean_gyro(rec: Recording) -> Recording:
    """Drop non-finite readings (a few; :func:`check_gyro` refuses many)."""
    values = rec.gyro_rate if rec.gyro_rate is not None else rec.gyro_yaw
    ok = np.isfinite(values)
    if np.all(ok):
        return rec
    gyro = ('gyro_t', 'gyro_rate', 'gyro_yaw', 'gyro_quaternion', 'gyro_quaternion_cov0',
            'gyro_omega')
    return replace(rec, **{n: getattr(rec, n)[ok] for n in gyro if getattr(rec, n) is not None})


def calibration_quantities(icr: IcrParams):
    """
    Return the quantities a calibration fits, as a model gives them.

    The distance scale ``s = (s_l + s_r) / 2``, the scale ratio ``rho = s_r / s_l``, the
    ICR spread ``W = y_left - y_right`` and the ICR offset ``c = (y_left + y_right) / 2``
    (module notes of :mod:`tracked_kinematics.core.identify.reference`).
    """
    return (0.5 * (icr.scale_left + icr.scale_right), icr.scale_right / icr.scale_left,
            icr.y_left - icr.y_right, 0.5 * (icr.y_left + icr.y_right))
