"""
The gyro-aided odometry replayed over a recording, and the consistency of published covariances.

:func:`gyro_track` runs :class:`..gyro.GyroOdometry` (odometry_node's gyro-aided
odometry) over a recording as the node receives it; :func:`window_consistency` measures, on
evaluate_model's windows, how often the final position errors fall inside the 50 % and 95 %
ellipses of the covariance the odometry publishes (the terrain file's noise model,
:mod:`..noise_model`, propagated along the window) and returns the normalised errors for the
plot; :func:`gyro_window_consistency` does the same for the gyro-aided odometry with the
covariance it publishes, computed by the same code as the node's (reset every window).
docs/tools/evaluate_model.md, "Consistency".
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from .pieces import moving_windows
from .verdict import covariance_verdict, disjoint_windows
from ..covariance import TrackNoise
from ..gyro import GYRO, GyroConfig, replay
from ..identify import Recording
from ..kinematics import IcrParams
from ..noise_model import consistency, covariances, NoiseModel, window_bases


def gyro_track(recording: Recording, icr: IcrParams, config: GyroConfig,
               terms: NoiseModel | None = None):
    """
    Replay the gyro-aided odometry over a recording with a gyro.

    The messages are taken in the order of their stamps (:func:`replay`), the steps at the
    encoder stamps as the node takes them; the poses are interpolated at the ground-truth
    times too (the grid the pieces are scored on). ``terms``: the terrain file's noise
    model, whose turn term is the model's heading error in the fusion, as the node's.

    Returns
    -------
    t : ndarray, shape (N,)
        Grid times, s.
    poses : ndarray, shape (N, 3)
        Pose at each, ``(x, y, theta)`` from the origin.
    odometry : GyroOdometry
        Its state at the end (bias, noise, switches).

    """
    rec = recording
    # The steps are the encoders' (as odometry_node takes them); the poses in between are
    # interpolated, not integrated: an extra short step would move the fusion's thresholds.
    enc_poses, _, odo = replay(rec.enc_t, rec.left, rec.right, rec.gyro_t, rec.gyro_rate,
                               icr, config,
                               terms=None if terms is None else terms.without_tracks(),
                               published_at=np.zeros(len(rec.enc_t), dtype=bool))
    if rec.gt_t is not None and len(rec.gt_t):
        inside = rec.gt_t[(rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1])]
        grid = np.union1d(rec.enc_t, inside)
    else:
        grid = np.asarray(rec.enc_t, float)
    poses = np.column_stack([np.interp(grid, rec.enc_t, enc_poses[:, k]) for k in range(3)])
    return grid, poses, odo


def _motion(path, i, j):
    """Motion from samples ``i`` to ``j`` of a path in the frame of ``i``: (W, 3)."""
    c, s = np.cos(path[i, 2]), np.sin(path[i, 2])
    ex, ey = path[j, 0] - path[i, 0], path[j, 1] - path[i, 1]
    return np.column_stack([c * ex + s * ey, -s * ex + c * ey, path[j, 2] - path[i, 2]])


def _prefix(values):
    return np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(values, axis=0)])


def normalised_errors(errors_xy, covariances_xy) -> np.ndarray:
    """Return ``L^-1 e`` (W, 2) for ``P = L L^T``: standard normal when ``P`` is right."""
    chol = np.linalg.cholesky(np.asarray(covariances_xy, float))
    return np.linalg.solve(chol, np.asarray(errors_xy, float)[..., None])[..., 0]


def _scored(errors, covs, independent: int) -> dict:
    """Return a window length's entry: consistency with its verdict, NEES, normalised errors."""
    e = np.concatenate(errors) if errors else np.zeros((0, 2))
    p = np.concatenate(covs) if covs else np.zeros((0, 2, 2))
    c = consistency(e, p)
    c.update(covariance_verdict(c['inside_50'], c['inside_95'], c['mean_nees'], independent))
    z = normalised_errors(e, p) if len(e) else np.zeros((0, 2))
    return {'consistency': c, 'nees': np.sum(z * z, 1), 'normalised': z}


def window_consistency(pieces, paths, icr: IcrParams, model: NoiseModel, lengths,
                       min_speed: float | None) -> dict:
    """
    Consistency of the published position covariance on evaluate_model's windows.

    The covariance of each window's final position relative to its start is the noise model's
    propagated along the encoders' steps (:func:`..noise_model.window_bases`). The gyro-aided
    odometry's is :func:`gyro_window_consistency`'s.

    Parameters
    ----------
    pieces : sequence of Piece
        The pieces scored.
    paths : sequence of ndarray, shape (M, 3)
        The odometry along each piece at its ground-truth times.
    icr : IcrParams
        The kinematic model of the odometry.
    model : NoiseModel
        The published noise model.
    lengths : sequence of float
        Window lengths, s.
    min_speed : float or None
        As :func:`.pieces.moving_windows`.

    Returns
    -------
    dict
        Per length (float): ``consistency`` (:func:`..noise_model.consistency` with
        :func:`.verdict.covariance_verdict`), ``nees``
        (W,) and ``normalised`` (W, 2) (:func:`normalised_errors`).

    """
    out = {}
    for length in lengths:
        errors, covs, independent = [], [], 0
        for k, (piece, path) in enumerate(zip(pieces, paths)):
            i, j, _ = moving_windows(piece, float(length), min_speed)
            if len(i) == 0:
                continue
            independent += disjoint_windows(piece.t[i], piece.t[j])
            d_left, d_right, dt = piece.steps
            start, end = piece.at[i], piece.at[j]
            bases, _ = window_bases(icr, d_left, d_right, dt, start, end)
            cov = covariances(bases, model)
            errors.append(_motion(path, i, j)[:, :2] - _motion(piece.truth, i, j)[:, :2])
            covs.append(cov)
        out[float(length)] = _scored(errors, covs, independent)
    return out


def reset_windows(enc_t, left, right, pieces, length: float, min_speed: float | None):
    """
    Back-to-back windows of ``length`` s inside the pieces, on the encoder samples.

    As odometry_node reset every ``length`` s by ``~/reset`` scores itself: a window runs
    from an encoder sample to the first one ``length`` s later, within one piece (never
    across a gap), kept when its tracks' mean speed is at least ``min_speed`` m/s.

    Returns
    -------
    start, end : ndarray of int
        Encoder sample indices of each window.
    resets : ndarray of bool, shape (N,)
        Where to reset (each piece's first sample and each window's end).

    """
    enc_t = np.asarray(enc_t, float)
    resets = np.zeros(len(enc_t), dtype=bool)
    starts, ends = [], []
    for piece in pieces:
        first = int(np.searchsorted(enc_t, piece.t[0]))
        last = int(np.searchsorted(enc_t, piece.t[-1], side='right')) - 1
        if last <= first:
            continue
        resets[first] = True
        k = first
        while True:
            e = int(np.searchsorted(enc_t, enc_t[k] + length - 1e-9))
            if e > last:
                break
            resets[e] = True
            travel = 0.5 * (np.sum(np.abs(np.diff(left[k:e + 1])))
                            + np.sum(np.abs(np.diff(right[k:e + 1]))))
            if min_speed is None or travel >= min_speed * (enc_t[e] - enc_t[k]):
                starts.append(k)
                ends.append(e)
            k = e
    return np.asarray(starts, int), np.asarray(ends, int), resets


def _truth_at(piece, times):
    """Return the piece's ground truth interpolated at ``times`` (inside it): (T, 3)."""
    return np.column_stack([np.interp(times, piece.t, piece.truth[:, k]) for k in range(3)])


class ResetWindows(NamedTuple):
    """
    The windows of :func:`gyro_reset_windows`.

    Attributes
    ----------
    errors : ndarray, shape (W, 2)
        Final position error of each window against the ground truth's motion, m, in the
        frame of its start.
    covariances : ndarray, shape (W, 2, 2)
        The position covariance published at each window's end, m^2.
    poses : ndarray, shape (W, 3)
        The odometry's pose at each window's end, since its start.
    gyro : ndarray of bool, shape (W,)
        Whether the heading at each window's end is the gyro's.
    unit : ndarray, shape (W, 2, 2), or None
        With ``unit`` given: what its timing, scale and drift add to each covariance.
    slip : ndarray, shape (W, 2, 2), or None
        With ``slip_share``: what one unit of the gyro-aided slip term adds to each.

    """

    errors: np.ndarray
    covariances: np.ndarray
    poses: np.ndarray
    gyro: np.ndarray
    unit: np.ndarray | None = None
    slip: np.ndarray | None = None


def gyro_reset_windows(recording: Recording, pieces, icr: IcrParams, config: GyroConfig,
                       noise: TrackNoise, terms: NoiseModel, gyro_terms: NoiseModel | None,
                       length: float, min_speed: float | None, offset: float = 0.0,
                       unit: NoiseModel | None = None,
                       slip_share: bool = False) -> ResetWindows:
    """
    Replay a recording through the gyro-aided odometry reset every ``length`` s; its windows.

    As odometry_node with ``~/reset`` every ``length`` s (:func:`reset_windows`, the first
    reset ``offset`` s into each piece), fed as :func:`..gyro.replay` feeds it, with the
    covariance's ``noise``, ``terms`` (the encoders') and ``gyro_terms`` (while the heading is
    the gyro's; None: ``terms``). ``unit``: also what this model's terms beside the steps
    (timing, scale, drift) would add at each window's end, from the same replay;
    ``slip_share``: also what one unit of ``gyro_terms.slip`` adds
    (:attr:`..gyro.GyroOdometry.slip_share`).
    """
    rec = recording
    late = [SimpleNamespace(t=p.t[p.t >= p.t[0] + offset]) for p in pieces]
    start, end, resets = reset_windows(rec.enc_t, rec.left, rec.right,
                                       [p for p in late if len(p.t) > 1], float(length),
                                       min_speed)
    if len(start) == 0:
        return _no_windows(unit, slip_share)
    scored = np.zeros(len(rec.enc_t), dtype=bool)
    scored[end] = True
    poses, sources, odo = replay(rec.enc_t, rec.left, rec.right, rec.gyro_t, rec.gyro_rate,
                                 icr, config, resets=resets, noise=noise, terms=terms,
                                 gyro_terms=gyro_terms, unit=unit, slip_share=slip_share,
                                 published_at=scored)
    errors, covs, units, slips, ends, gyro = [], [], [], [], [], []
    for piece in pieces:
        inside = (rec.enc_t[start] >= piece.t[0]) & (rec.enc_t[end] <= piece.t[-1])
        if not np.any(inside):
            continue
        a, b = start[inside], end[inside]
        truth = _motion(np.vstack([_truth_at(piece, rec.enc_t[a]),
                                   _truth_at(piece, rec.enc_t[b])]),
                        np.arange(len(a)), len(a) + np.arange(len(a)))
        errors.append(poses[b, :2] - truth[:, :2])
        covs.append(_position(odo.published[b]))
        if unit is not None:
            units.append(_position(odo.unit_published[b]))
        if slip_share:
            slips.append(_position(odo.slip_published[b]))
        ends.append(poses[b])
        gyro.append(sources[b] == GYRO)
    if not errors:
        return _no_windows(unit, slip_share)
    return ResetWindows(np.concatenate(errors), np.concatenate(covs), np.concatenate(ends),
                        np.concatenate(gyro), np.concatenate(units) if units else None,
                        np.concatenate(slips) if slips else None)


def _position(upper):
    """Return the position blocks (W, 2, 2) of upper triangles (W, 6)."""
    return np.stack([np.stack([upper[:, 0], upper[:, 1]], -1),
                     np.stack([upper[:, 1], upper[:, 3]], -1)], -2)


def _no_windows(unit=None, slip_share=False):
    return ResetWindows(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 3)),
                        np.zeros(0, dtype=bool), None if unit is None else np.zeros((0, 2, 2)),
                        np.zeros((0, 2, 2)) if slip_share else None)


def gyro_window_consistency(recordings, pieces, icr: IcrParams, config: GyroConfig,
                            noise: TrackNoise, model: NoiseModel, lengths,
                            min_speed: float | None,
                            gyro_model: NoiseModel | None = None) -> dict:
    """
    Consistency of the covariance the gyro-aided odometry_node publishes, reset every window.

    Each recording is replayed through :class:`..gyro.GyroOdometry` as the node is fed, with
    a reset at the start of each window (:func:`gyro_reset_windows`); the covariance scored is
    the one the node publishes at the window's end (:meth:`..gyro.GyroOdometry.publish`: the
    propagated covariance with the bias's share, and the time error at both ends), the error
    that of its pose against the ground truth's motion over the window.

    Parameters
    ----------
    recordings : sequence of Recording
        With a gyro (``gyro_t``, ``gyro_rate``).
    pieces : sequence of Piece
        The gap-free stretches scored (``piece.recording`` indexes ``recordings``).
    icr, config : IcrParams, GyroConfig
        The terrain file, as the node reads it.
    noise, model : TrackNoise, NoiseModel
        The tracks' noise and the turn, slip and timing terms, as the node publishes them.
    lengths : sequence of float
        Window lengths, s.
    min_speed : float or None
        As :func:`.pieces.moving_windows`.
    gyro_model : NoiseModel, optional
        The terms while the heading is the gyro's (the terrain file's ``covariance.gyro_aided.*``:
        :func:`tracked_kinematics.params.gyro_noise_model_from_values`); None: ``model``'s.

    Returns
    -------
    dict
        As :func:`window_consistency`.

    """
    terms = model.without_tracks()
    gyro_terms = None if gyro_model is None else gyro_model.without_tracks()
    out = {}
    for length in lengths:
        errors, covs = [], []
        for r, rec in enumerate(recordings):
            mine = [p for p in pieces if p.recording == r]
            if not mine or rec.gyro_t is None:
                continue
            found = gyro_reset_windows(rec, mine, icr, config, noise, terms, gyro_terms,
                                       float(length), min_speed)
            if len(found.errors):
                errors.append(found.errors)
                covs.append(found.covariances)
        # Back-to-back windows: each one independent of the others.
        out[float(length)] = _scored(errors, covs, sum(len(e) for e in errors))
    return out
