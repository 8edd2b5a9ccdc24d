"""
The gyro-aided odometry's own noise constants, fitted on gyro-aided windows (issue 35).

The gyro-aided odometry (:class:`..gyro.GyroOdometry`) takes its heading from the gyro and its
translation from the tracks; the noise model fitted on the encoders' windows
(:mod:`.noise`) has the wrong shape for it: on the Marmotte's snow run its turns on the spot
were over-covered after 5 s and its straight drives under-covered sideways, and its errors
grow as the square of the window between 5 and 10 s (docs/nodes/odometry_node.md,
"Consistency of the published covariance"). Here the windows are the node's: the recording
replayed as odometry_node with ``~/reset`` every 5 and 10 s (:func:`.consistency.
gyro_reset_windows`), from several reset schedules; the published covariance is affine in the
constants of :data:`GYRO_TERMS` (``slip`` per step, ``timing`` and ``drift`` where published,
:mod:`..noise_model`), so each window's covariance is ``fixed + sum_m c_m A_m``, and the
constants are fitted by maximum likelihood (Student-t, as :func:`.noise.fit_noise`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from .consistency import gyro_reset_windows
from .noise import DOF, negative_log_likelihoods
from ..covariance import TrackNoise
from ..gyro import GyroConfig
from ..kinematics import IcrParams
from ..noise_model import NoiseModel

GYRO_TERMS = ('slip', 'timing', 'drift')
"""The constants fitted on gyro-aided windows, in the order of :attr:`GyroWindows.bases`."""
RESET_OFFSETS = (0.0, 0.5)
"""The reset schedules replayed: the first reset this share of a window into each piece."""
MIN_WINDOWS = 20
"""Fewest gyro-aided windows of each length a fit needs (else :func:`fit_gyro_noise` refuses)."""
START = {'slip': 1e-3, 'timing': 1e-3, 'drift': 1e-4}
"""Where the fit starts a constant the encoders' model has at 0."""


@dataclass(frozen=True)
class GyroWindows:
    """
    Windows of the gyro-aided odometry reset every window: errors and covariance bases.

    Attributes
    ----------
    errors : ndarray, shape (W, 2)
        Final position errors, m.
    fixed : ndarray, shape (W, 2, 2)
        The published position covariance with the constants of :data:`GYRO_TERMS` at 0, m^2.
    bases : ndarray, shape (W, len(GYRO_TERMS), 2, 2)
        What each constant adds per unit.
    length : ndarray, shape (W,)
        Window length, s.
    schedules : int
        Reset schedules replayed (each window of the data appears about this many times).

    """

    errors: np.ndarray
    fixed: np.ndarray
    bases: np.ndarray
    length: np.ndarray
    schedules: int

    def __len__(self):
        return len(self.length)

    def covariances(self, constants) -> np.ndarray:
        """Return the published position covariances for ``constants`` (of GYRO_TERMS)."""
        return self.fixed + np.einsum('wmij,m->wij', self.bases, np.asarray(constants, float))


def gyro_windows(recordings, pieces, icr: IcrParams, config: GyroConfig, noise: TrackNoise,
                 model: NoiseModel, lengths, min_speed: float | None,
                 offsets=RESET_OFFSETS) -> GyroWindows:
    """
    Return the gyro-aided odometry's windows on recordings, with their covariance bases.

    Only the windows at whose end the heading is the gyro's (the node publishes the gyro-aided
    constants there; elsewhere the encoders').

    Parameters
    ----------
    recordings : sequence of Recording
        With a gyro and a pose reference (its delay taken off).
    pieces : sequence of Piece
        Their gap-free stretches (``piece.recording`` indexes ``recordings``).
    icr, config : IcrParams, GyroConfig
        The terrain file as the node reads it.
    noise, model : TrackNoise, NoiseModel
        The tracks' noise and the encoders' noise model (its ``scale`` is kept, a held prior).
    lengths : sequence of float
        Window lengths (reset periods), s.
    min_speed : float or None
        As :func:`.consistency.reset_windows`.
    offsets : sequence of float
        Reset schedules, as shares of a window (:data:`RESET_OFFSETS`).

    """
    terms = model.without_tracks()
    base = replace(terms, **dict.fromkeys(GYRO_TERMS, 0.0))
    # The covariance is affine in the constants, and the path does not depend on them: one
    # replay gives slip's share (propagated beside the covariance: slip_share), and timing's
    # and drift's, what the terms beside the steps add at each window's end.
    unit = NoiseModel(track=0.0, floor=0.0, timing=1.0)
    errors, fixed, bases, length = [], [], [], []
    for r, rec in enumerate(recordings):
        mine = [p for p in pieces if p.recording == r]
        if not mine or rec.gyro_t is None:
            continue
        for w in lengths:
            for offset in offsets:
                args = (rec, mine, icr, config, noise, terms)
                found = gyro_reset_windows(*args, base, w, min_speed, offset * w, unit=unit,
                                           slip_share=True)
                gyro = found.gyro
                if not np.any(gyro):
                    continue
                p0 = found.covariances
                each = [found.slip, found.unit,
                        # drift: |p|^2 I where the heading is the gyro's (published_covariance).
                        np.sum(found.poses[:, :2] ** 2, 1)[:, None, None] * np.eye(2)]
                # The windows that end with the heading the gyro's: what the constants are for.
                errors.append(found.errors[gyro])
                fixed.append(p0[gyro])
                bases.append(np.stack(each, 1)[gyro])
                length.append(np.full(int(np.sum(gyro)), float(w)))
    if not errors:
        return GyroWindows(np.zeros((0, 2)), np.zeros((0, 2, 2)),
                           np.zeros((0, len(GYRO_TERMS), 2, 2)), np.zeros(0), len(offsets))
    return GyroWindows(np.concatenate(errors), np.concatenate(fixed), np.concatenate(bases),
                       np.concatenate(length), len(offsets))


def _cost(log_c, windows: GyroWindows, dof):
    cov = windows.covariances(np.exp(log_c)) + 1e-12 * np.eye(2)
    try:
        return float(np.mean(negative_log_likelihoods(windows.errors, cov, dof)))
    except np.linalg.LinAlgError:
        return math.inf


def fit_gyro_noise(windows: GyroWindows, model: NoiseModel,
                   dof: float | None = DOF) -> NoiseModel:
    """
    Fit the gyro-aided odometry's ``slip``, ``timing`` and ``drift`` to its windows.

    Maximum likelihood of the windows' final position errors, Student-t with ``dof``
    degrees of freedom about the published covariance (:func:`.noise.fit_noise`'s, without a
    prior: every window is one the node publishes).

    Parameters
    ----------
    windows : GyroWindows
        :func:`gyro_windows`'s.
    model : NoiseModel
        The encoders' noise model: the start, and the terms not fitted.
    dof : float or None
        As :func:`.noise.fit_noise`.

    Returns
    -------
    NoiseModel
        ``model`` with the gyro-aided ``slip``, ``timing`` and ``drift``.

    Raises
    ------
    ValueError
        With fewer than :data:`MIN_WINDOWS` windows of a length.

    """
    lengths = np.unique(windows.length)
    counts = [int(np.sum(windows.length == w)) // windows.schedules for w in lengths]
    if not len(lengths) or min(counts) < MIN_WINDOWS:
        raise ValueError(f'too few gyro-aided windows ({", ".join(map(str, counts)) or 0} per '
                         f'length, {MIN_WINDOWS} needed)')
    from scipy.optimize import minimize   # lazily, as every scipy of core
    start = [getattr(model, t) or START[t] for t in GYRO_TERMS]
    best = minimize(_cost, np.log(start), args=(windows, dof), method='Nelder-Mead',
                    options={'xatol': 1e-3, 'fatol': 1e-7, 'maxiter': 3000})
    fitted = np.exp(best.x)
    return replace(model, **{t: float(v) for t, v in zip(GYRO_TERMS, fitted)})
