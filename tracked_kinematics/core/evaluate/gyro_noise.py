"""
The gyro-aided odometry's noise model, fitted to its own held-out windows.

The encoders' noise model (:mod:`.noise`) is fitted on windows of encoder-only odometry, whose
position errors are mostly those of its heading: its ``timing`` term (the time error at the
start of a window turns the whole displacement since, its lever arm) and its ``slip`` take
them up. The gyro-aided odometry makes far smaller heading errors, and published with those
constants its covariance is too large (on the held-out Warthog grass runs the ``timing`` term
alone is 57-95 % of the trace of its final position covariance; 65-82 % of the windows fall
inside the 50 % ellipse, 93-94 % on the Marmotte's snow run). Here ``track``, ``slip`` and
``timing`` (:data:`GYRO_TERMS`) are fitted on windows of the gyro-aided odometry itself,
replayed as odometry_node runs it (:func:`..gyro.replay`: reset every window, the heading the
gyro's at every step), with the kinematic model fitted without the window's data (as
:func:`.noise.held_out_windows`).

Given a path, the covariance the node publishes is linear in the three constants: the track
random walk and the slip term add per step, the time error at both ends; the heading's share
(the gyro's noise and bias, the model's share in the fusion) does not depend on them. So a
window's covariance is ``F + sum_m c_m A_m``: ``F`` the replay with the three constants 0,
``A_m`` the replay with ``c_m = 1`` less ``F`` (:attr:`.noise.ErrorWindows.fixed` and
``bases``), and :func:`.noise.fit_noise` fits them as it does the encoders'.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .consistency import reset_windows
from .noise import ErrorWindows
from .pieces import cut
from ..gyro import GYRO, GyroConfig, replay
from ..identify.holdout import crop_recording
from ..kinematics import IcrParams
from ..noise_model import TERMS

GYRO_TERMS = ('track', 'slip', 'timing')
"""The constants of the gyro-aided odometry's noise model (GyroConfig's ``covariance_*``)."""

PHASES = 4
"""Reset schedules per window length (shifted by ``length / PHASES``): more windows to fit on."""


def _full(upper) -> np.ndarray:
    """Return (W, 3, 3) covariances from upper triangles ``(xx, xy, xt, yy, yt, tt)``."""
    u = np.asarray(upper, float)
    return np.stack([np.stack([u[:, 0], u[:, 1], u[:, 2]], -1),
                     np.stack([u[:, 1], u[:, 3], u[:, 4]], -1),
                     np.stack([u[:, 2], u[:, 4], u[:, 5]], -1)], -2)


def _truth_at(piece, times) -> np.ndarray:
    return np.column_stack([np.interp(times, piece.t, piece.truth[:, k]) for k in range(3)])


def _relative(a, b) -> np.ndarray:
    """Return the motion from poses ``a`` to ``b`` (W, 3) in the frame of ``a``."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, b[:, 2] - a[:, 2]])


def gyro_windows(recording, pieces, icr: IcrParams, config: GyroConfig, lengths,
                 min_speed: float | None = 0.1, noise=None, terms=None, phases: int = PHASES,
                 span=None) -> ErrorWindows:
    """
    Return windows of the gyro-aided odometry on one recording: errors, bases, fixed share.

    The odometry is replayed as odometry_node runs it, reset every ``length`` s
    (:func:`.consistency.reset_windows`, ``phases`` schedules shifted by ``length /
    phases``); a window is kept when the heading was the gyro's at every step of it.

    Parameters
    ----------
    recording : Recording
        With a gyro (``gyro_t``, ``gyro_rate``), its reference's delay taken off.
    pieces : sequence of Piece
        Its gap-free stretches (:func:`.pieces.cut`).
    icr, config : IcrParams, GyroConfig
        The kinematic model (fitted without this data) and how the gyro is read.
    lengths : sequence of float
        Window lengths, s.
    min_speed : float or None
        As :func:`.pieces.moving_windows`.
    noise, terms : optional
        The encoders' noise (:meth:`..gyro.GyroOdometry.set_noise`): used on the steps whose
        heading is the encoders', which no window kept has.
    phases : int
        Reset schedules per length (>= 1).
    span : tuple of float, optional
        Keep only the windows within ``(start, end)`` s.

    Returns
    -------
    ErrorWindows
        ``bases`` of :data:`..noise_model.TERMS` (``turn`` 0: the gyro's heading has none),
        ``fixed`` the heading's share; one group per piece.

    """
    rec = recording
    if rec.gyro_t is None or len(rec.gyro_t) == 0:
        return ErrorWindows.concatenate([])
    zero = replace(config, **{f'covariance_{t}': 0.0 for t in GYRO_TERMS})
    configs = [zero] + [replace(zero, **{f'covariance_{t}': 1.0}) for t in GYRO_TERMS]
    found = {k: [] for k in ('errors', 'bases', 'fixed', 'length', 't0', 'group')}
    for length in lengths:
        for phase in range(phases):
            start, end, resets = reset_windows(rec.enc_t, rec.left, rec.right, pieces,
                                               float(length), min_speed,
                                               offset=phase * float(length) / phases)
            if len(start) == 0:
                continue
            runs = [replay(rec.enc_t, rec.left, rec.right, rec.gyro_t, rec.gyro_rate, icr,
                           c, resets=resets, noise=noise, terms=terms) for c in configs]
            poses, sources, _ = runs[0]
            off = np.concatenate([[0], np.cumsum(sources[1:] != GYRO)])
            keep = off[end] == off[start]
            if span is not None:
                keep &= (rec.enc_t[start] >= span[0]) & (rec.enc_t[end] <= span[1])
            _collect(found, rec, pieces, start[keep], end[keep], poses,
                     [r[2].published for r in runs], float(length))
    if not found['errors']:
        return ErrorWindows.concatenate([])
    return ErrorWindows(*(np.concatenate(found[k]) for k in
                          ('errors', 'bases', 'length', 't0', 'group')),
                        fixed=np.concatenate(found['fixed']))


def _collect(found, rec, pieces, start, end, poses, published, length) -> None:
    """Add the windows ``start -> end`` to ``found``, piece by piece."""
    for g, piece in enumerate(pieces):
        inside = (rec.enc_t[start] >= piece.t[0]) & (rec.enc_t[end] <= piece.t[-1])
        if not np.any(inside):
            continue
        a, b = start[inside], end[inside]
        truth = _relative(_truth_at(piece, rec.enc_t[a]), _truth_at(piece, rec.enc_t[b]))
        error = poses[b] - truth
        error[:, 2] = np.remainder(error[:, 2] + np.pi, 2.0 * np.pi) - np.pi
        fixed = _full(published[0][b])
        bases = np.zeros((len(a), len(TERMS), 3, 3))
        for term, p in zip(GYRO_TERMS, published[1:]):
            bases[:, TERMS.index(term)] = _full(p[b]) - fixed
        found['errors'].append(error)
        found['bases'].append(bases)
        found['fixed'].append(fixed)
        found['length'].append(np.full(len(a), length))
        found['t0'].append(rec.enc_t[a])
        found['group'].append(np.full(len(a), g, np.intp))


def gyro_held_out_windows(recordings, fit_icr, config: GyroConfig, lengths,
                          min_speed: float | None = 0.1, track_width: float | None = None,
                          blocks: int = 5, noise=None, terms=None,
                          phases: int = PHASES) -> ErrorWindows:
    """
    Return windows of the gyro-aided odometry whose kinematic model was fitted without them.

    As :func:`.noise.held_out_windows`: with two recordings or more, each is replayed with
    the ICRs fitted on the others; with one, its time is cut into ``blocks`` blocks and the
    windows of each scored with the ICRs fitted on the rest (the replay runs over the whole
    recording, as a node that was running; only the block's windows are kept).

    Parameters
    ----------
    recordings : sequence of Recording
        With a gyro; their reference's delay taken off.
    fit_icr : callable
        ``fit_icr(recordings) -> IcrParams``.
    config : GyroConfig
        How the gyro is read (the terrain file's ``imu_delay``, ``gyro_scale``, bias).
    lengths, min_speed, noise, terms, phases
        As :func:`gyro_windows`.
    track_width : float, optional
        m, for the reference's heading glitches (:func:`.pieces.cut`).
    blocks : int
        Blocks of a single recording (>= 2).

    """
    recordings = list(recordings)

    def windows(rec, icr, span=None):
        pieces = cut(rec, 0, True, track_width).pieces
        return gyro_windows(rec, pieces, icr, config, lengths, min_speed, noise, terms,
                            phases, span)
    if len(recordings) >= 2:
        return ErrorWindows.concatenate(
            windows(rec, fit_icr(recordings[:k] + recordings[k + 1:]))
            for k, rec in enumerate(recordings))
    (rec,) = recordings
    t0, t1 = float(rec.enc_t[0]), float(rec.enc_t[-1])
    edges = np.linspace(t0, t1, blocks + 1)
    parts = []
    for a, b in zip(edges[:-1], edges[1:]):
        rest = (([crop_recording(rec, t0, a)] if a > t0 else [])
                + ([crop_recording(rec, b, t1)] if b < t1 else []))
        parts.append(windows(rec, fit_icr(rest), (a, b)))
    return ErrorWindows.concatenate(parts)
