"""
The recordings a robot without ground truth gives, the result of a calibration, and the checks.

:class:`ReferenceRecording` holds the encoder travel and any of a gyro, a pose and positions;
:class:`ReferenceFit` what :func:`.calibration.fit_recordings` makes of them. The sensor data
are checked before any fit: :func:`check_gyro` refuses a gyro that reads nothing,
:func:`check_saturation` one stuck at its range.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..delay import DelayEstimate, fixed_delay
from ...errors import SensorDataError
from ...kinematics import IcrParams

QUANTITIES = ('chi', 'scale_ratio', 'distance_scale', 'icr.x', 'icr_offset')
"""What a calibration determines or holds (``identification.determined`` / ``held``)."""
SATURATION_SHARE = 0.005
"""Share of gyro readings stuck at the largest magnitude that means saturation."""


@dataclass(frozen=True)
class ReferenceRecording:
    """
    One recording: encoder travel and the references a robot without ground truth has.

    Attributes
    ----------
    enc_t, left, right : ndarray, shape (N,)
        Encoder times (s, increasing) and cumulative nominal travel per track (m).
    gyro_t : ndarray or None
        Gyro stamps, s, on the encoders' clock.
    gyro_rate : ndarray or None
        Yaw rates, rad/s (counter-clockwise positive).
    gyro_yaw : ndarray or None
        Yaw angles of an orientation estimate, rad, instead of ``gyro_rate``.
    pose : tuple of ndarray or None
        ``(t, x, y, yaw)`` of a pose reference.
    positions : tuple of ndarray or None
        ``(t, x, y)``: positions in a local plane (GNSS), m.
    name : str
        Where it came from, for reports.

    """

    enc_t: np.ndarray
    left: np.ndarray
    right: np.ndarray
    gyro_t: np.ndarray | None = None
    gyro_rate: np.ndarray | None = None
    gyro_yaw: np.ndarray | None = None
    pose: tuple | None = None
    positions: tuple | None = None
    name: str = ''

    def __post_init__(self):
        def arrays(group, names):
            out = [np.asarray(a, dtype=float) for a in group]
            if any(a.ndim != 1 or a.shape != out[0].shape for a in out):
                raise ValueError(f'{", ".join(names)} must be 1-D arrays of one length')
            if np.any(np.diff(out[0]) <= 0) or not np.all(np.isfinite(out[0])):
                raise ValueError(f'{names[0]} must be finite and strictly increasing')
            return out

        enc = arrays((self.enc_t, self.left, self.right), ('enc_t', 'left', 'right'))
        for a, n in zip(enc[1:], ('left', 'right')):
            if not np.all(np.isfinite(a)):
                raise ValueError(f'{n} has non-finite values')
        for n, a in zip(('enc_t', 'left', 'right'), enc):
            object.__setattr__(self, n, a)
        if self.gyro_t is not None:
            if (self.gyro_rate is None) == (self.gyro_yaw is None):
                raise ValueError('give gyro_rate or gyro_yaw with gyro_t')
            values = self.gyro_rate if self.gyro_rate is not None else self.gyro_yaw
            t, v = arrays((self.gyro_t, values), ('gyro_t', 'gyro values'))
            object.__setattr__(self, 'gyro_t', t)
            object.__setattr__(self, 'gyro_rate' if self.gyro_rate is not None
                               else 'gyro_yaw', v)
        if self.pose is not None:
            pose = arrays(self.pose, ('pose t', 'x', 'y', 'yaw'))
            if not all(np.all(np.isfinite(a)) for a in pose):
                raise ValueError('the pose has non-finite values')
            object.__setattr__(self, 'pose', tuple(pose))
        if self.positions is not None:
            pos = arrays(self.positions, ('positions t', 'x', 'y'))
            if not all(np.all(np.isfinite(a)) for a in pos):
                raise ValueError('the positions have non-finite values')
            object.__setattr__(self, 'positions', tuple(pos))


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


def clean_gyro(rec: ReferenceRecording) -> ReferenceRecording:
    """Drop non-finite readings (a few; :func:`check_gyro` refuses many)."""
    values = rec.gyro_rate if rec.gyro_rate is not None else rec.gyro_yaw
    ok = np.isfinite(values)
    if np.all(ok):
        return rec
    key = 'gyro_rate' if rec.gyro_rate is not None else 'gyro_yaw'
    return ReferenceRecording(rec.enc_t, rec.left, rec.right, rec.gyro_t[ok],
                              **{key: values[ok]}, pose=rec.pose, positions=rec.positions,
                              name=rec.name)


def calibration_quantities(icr: IcrParams):
    """
    Return the quantities a calibration fits, as a model gives them.

    The distance scale ``s = (s_l + s_r) / 2``, the scale ratio ``rho = s_r / s_l``, the
    ICR spread ``W = y_left - y_right`` and the ICR offset ``c = (y_left + y_right) / 2``
    (module notes of :mod:`tracked_kinematics.core.identify.reference`).
    """
    return (0.5 * (icr.scale_left + icr.scale_right), icr.scale_right / icr.scale_left,
            icr.y_left - icr.y_right, 0.5 * (icr.y_left + icr.y_right))
