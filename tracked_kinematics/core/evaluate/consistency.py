"""
The gyro-aided odometry replayed over a recording, and the consistency of published covariances.

:func:`gyro_track` runs :class:`..gyro_odometry.GyroOdometry` (odometry_node's gyro-aided
odometry) over a recording as the node receives it; :func:`window_consistency` measures, on
evaluate_model's windows, how often the final position errors fall inside the 50 % and 95 %
ellipses of the covariance the odometry publishes (the terrain file's noise model,
:mod:`..noise_model`, propagated along the window) and returns the normalised errors for the
plot. docs/tools/evaluate_model.md, "Consistency".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pieces import moving_windows
from .verdict import covariance_verdict, disjoint_windows
from ..gyro_odometry import GyroConfig, replay
from ..identify import Recording
from ..kinematics import IcrParams
from ..noise_model import consistency, covariances, NoiseModel, window_bases


def gyro_track(recording: Recording, icr: IcrParams, config: GyroConfig):
    """
    Replay the gyro-aided odometry over a recording with a gyro.

    The messages are taken in the order of their stamps (:func:`replay`), the steps at the
    encoder stamps as the node takes them; the poses are interpolated at the ground-truth
    times too (the grid the pieces are scored on).

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
                               icr, config)
    if rec.gt_t is not None and len(rec.gt_t):
        inside = rec.gt_t[(rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1])]
        grid = np.union1d(rec.enc_t, inside)
    else:
        grid = np.asarray(rec.enc_t, float)
    poses = np.column_stack([np.interp(grid, rec.enc_t, enc_poses[:, k]) for k in range(3)])
    return grid, poses, odo


@dataclass(frozen=True)
class GyroHeading:
    """
    The heading noise of the gyro-aided odometry: per step ``noise^2 dt + (scale_std dtheta)^2``.

    ``noise`` rad/s/sqrt(Hz) (the gyro's rate noise density), ``scale_std`` relative.
    """

    noise: float
    scale_std: float


def _motion(path, i, j):
    """Motion from samples ``i`` to ``j`` of a path in the frame of ``i``: (W, 3)."""
    c, s = np.cos(path[i, 2]), np.sin(path[i, 2])
    ex, ey = path[j, 0] - path[i, 0], path[j, 1] - path[i, 1]
    return np.column_stack([c * ex + s * ey, -s * ex + c * ey, path[j, 2] - path[i, 2]])


def _prefix(values):
    return np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(values, axis=0)])


def heading_noise_covariances(grid_path, variances, start, end) -> np.ndarray:
    """
    Position covariances (W, 2, 2) of windows from independent heading errors of each step.

    A heading error of variance ``v_k`` at step ``k`` (acting at its middle) moves the end of
    the window by ``dtheta (q_end - q_k)``, ``q = (-y, x)`` (:func:`..noise_model.window_bases`
    does the same for its terms); in the frame of the heading at ``start``.

    Parameters
    ----------
    grid_path : ndarray, shape (K, 3)
        The path at the step boundaries.
    variances : ndarray, shape (K - 1,)
        Heading variance of each step, rad^2.
    start, end : ndarray of int, shape (W,)
        Step boundaries of each window.

    """
    p = np.asarray(grid_path, float)
    v = np.asarray(variances, float)
    q = np.column_stack([-0.5 * (p[:-1, 1] + p[1:, 1]), 0.5 * (p[:-1, 0] + p[1:, 0])])
    qe = np.column_stack([-p[end, 1], p[end, 0]])

    def over(values):
        prefix = _prefix(values)
        return prefix[end] - prefix[start]

    sum_v = over(v)
    sum_vq = over(v[:, None] * q)
    sum_vqq = over(v[:, None, None] * q[:, :, None] * q[:, None, :])
    cov = (sum_v[:, None, None] * qe[:, :, None] * qe[:, None, :]
           - qe[:, :, None] * sum_vq[:, None, :] - sum_vq[:, :, None] * qe[:, None, :]
           + sum_vqq)
    h0 = p[start, 2]
    c0, s0 = np.cos(h0), np.sin(h0)
    r0 = np.stack([np.stack([c0, s0], -1), np.stack([-s0, c0], -1)], -2)
    cov = r0 @ cov @ np.swapaxes(r0, 1, 2)
    return 0.5 * (cov + np.swapaxes(cov, 1, 2))


def normalised_errors(errors_xy, covariances_xy) -> np.ndarray:
    """Return ``L^-1 e`` (W, 2) for ``P = L L^T``: standard normal when ``P`` is right."""
    chol = np.linalg.cholesky(np.asarray(covariances_xy, float))
    return np.linalg.solve(chol, np.asarray(errors_xy, float)[..., None])[..., 0]


def window_consistency(pieces, paths, icr: IcrParams, model: NoiseModel, lengths,
                       min_speed: float | None, gyro: GyroHeading | None = None,
                       grid_paths=None) -> dict:
    """
    Consistency of the published position covariance on evaluate_model's windows.

    The covariance of each window's final position relative to its start is the noise model's
    propagated along the encoders' steps (:func:`..noise_model.window_bases`); with ``gyro``,
    the heading comes from the gyro: ``turn`` is dropped and the gyro's heading noise
    (:class:`GyroHeading`) propagated along ``grid_paths`` instead.

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
    gyro : GyroHeading, optional
        The heading from the gyro.
    grid_paths : sequence of ndarray, shape (K, 3), optional
        With ``gyro``: the odometry at each piece's grid.

    Returns
    -------
    dict
        Per length (float): ``consistency`` (:func:`..noise_model.consistency` with
        :func:`.verdict.covariance_verdict`), ``nees``
        (W,) and ``normalised`` (W, 2) (:func:`normalised_errors`).

    """
    used = model
    if gyro is not None:
        used = NoiseModel(model.track, 0.0, model.slip, model.timing, model.floor)
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
            cov = covariances(bases, used)
            if gyro is not None:
                grid_path = grid_paths[k]
                dth = np.diff(grid_path[:, 2])
                v = gyro.noise ** 2 * dt + (gyro.scale_std * dth) ** 2
                cov = cov + heading_noise_covariances(grid_path, v, start, end)
            errors.append(_motion(path, i, j)[:, :2] - _motion(piece.truth, i, j)[:, :2])
            covs.append(cov)
        e = np.concatenate(errors) if errors else np.zeros((0, 2))
        p = np.concatenate(covs) if covs else np.zeros((0, 2, 2))
        c = consistency(e, p)
        c.update(covariance_verdict(c['inside_50'], c['inside_95'], c['mean_nees'],
                                    independent))
        z = normalised_errors(e, p) if len(e) else np.zeros((0, 2))
        out[float(length)] = {'consistency': c, 'nees': np.sum(z * z, 1), 'normalised': z}
    return out
