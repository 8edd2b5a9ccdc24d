"""
A recording replayed through the gyro-aided odometry, and the gyro's scale fitted to poses.

:func:`replay` feeds :class:`.fusion.GyroOdometry` as odometry_node is fed (evaluate_model
``--fuse-imu``, the demo); :func:`fit_gyro_scale` is identify_icr's fit of ``gyro_scale``.
"""

from __future__ import annotations

import math

import numpy as np

from .fusion import GyroOdometry
from .gyro_config import ENCODERS, GyroConfig
from ..kinematics import IcrParams


def replay(enc_t, left, right, gyro_t, gyro_rate, icr: IcrParams,
           config: GyroConfig | None = None, resets=None, noise=None, terms=None,
           gyro_terms=None, unit=None, slip_share: bool = False, published_at=None):
    """
    Replay a recording through :class:`GyroOdometry` as a node would receive it.

    Messages are taken in the order of their stamps (a gyro sample before an encoder sample
    of the same stamp); after each encoder sample the odometry is published
    (:meth:`GyroOdometry.publish`, as odometry_node at its input rate).

    Parameters
    ----------
    enc_t, left, right : array_like, shape (N,)
        Encoder times, s, and cumulative nominal travel of each track, m.
    gyro_t, gyro_rate : array_like, shape (G,)
        Gyro stamps, s, and yaw rates, rad/s (may be empty: encoders only).
    icr : IcrParams
        The terrain's ICR model.
    config : GyroConfig, optional
        How the gyro is read; default ``GyroConfig()``.
    resets : array_like of bool, shape (N,), optional
        Reset the odometry (odometry_node's ``~/reset``) after publishing at these samples.
    noise, terms, gyro_terms : optional
        The covariance's noise (:meth:`GyroOdometry.set_noise`); ``terms.timing`` (and
        ``gyro_terms``' while the heading is the gyro's) is published
        (:meth:`GyroOdometry.set_timing`).
    unit : NoiseModel, optional
        Also return what this model's timing, scale and drift would add to each published
        covariance (``odometry.unit_published``; :meth:`GyroOdometry.beside_the_steps`).
    slip_share : bool
        Also return what one unit of the gyro-aided slip term adds to each
        (``odometry.slip_published``; :attr:`GyroOdometry.slip_share`).
    published_at : array_like of bool, shape (N,), optional
        The samples whose published covariances are wanted (the ends of the windows scored):
        elsewhere they are NaN, and not computed (``publish(covariance=False)``: the twist is
        taken all the same, so the path and the wanted ones are those of a full replay).
        Default: every sample.

    Returns
    -------
    poses : ndarray, shape (N, 3)
        Pose after each encoder sample (the first: zero), before any reset there.
    sources : ndarray of str, shape (N,)
        The source of each step's heading.
    odometry : GyroOdometry
        The state at the end; ``odometry.published`` (N, 6): the published pose covariance
        after each encoder sample (upper triangle, before any reset there); with ``unit``,
        ``odometry.unit_published`` (N, 6) likewise, and with ``slip_share``
        ``odometry.slip_published``.

    """
    enc_t = np.asarray(enc_t, float)
    gyro_t = np.asarray(gyro_t, float)
    events = np.concatenate([gyro_t, enc_t])
    order = np.argsort(events, kind='stable').tolist()
    n_gyro = len(gyro_t)
    odo = GyroOdometry(icr, config, noise, terms, gyro_terms)
    odo.set_timing(terms, gyro_terms)
    poses = np.zeros((len(enc_t), 3))
    published = np.zeros((len(enc_t), 6))
    unit_published = None if unit is None else np.zeros((len(enc_t), 6))
    slip_published = np.zeros((len(enc_t), 6)) if slip_share else None
    if slip_share:
        odo.track_slip_share()
    sources = np.full(len(enc_t), ENCODERS, dtype=object)
    gt, gr = gyro_t.tolist(), np.asarray(gyro_rate, float).tolist()
    et, el, er = enc_t.tolist(), np.asarray(left, float).tolist(), \
        np.asarray(right, float).tolist()
    reset = [False] * len(et) if resets is None else np.asarray(resets, bool).tolist()
    wanted = [True] * len(et) if published_at is None else \
        np.asarray(published_at, bool).tolist()
    if published_at is not None:
        for out in (published, unit_published, slip_published):
            if out is not None:
                out.fill(np.nan)
    for e in order:
        if e < n_gyro:
            odo.imu(gt[e], gr[e])
            continue
        k = e - n_gyro
        odo.encoders(et[k], el[k], er[k])
        pose, covariance, twist, _ = odo.publish(wanted[k])
        poses[k] = pose
        if wanted[k]:
            published[k] = covariance
            if unit is not None:
                unit_published[k] = odo.beside_the_steps(twist, unit)
            if slip_share:
                slip_published[k] = odo.slip_share
        sources[k] = odo.source
        if reset[k]:
            odo.reset()
    odo.published = published
    odo.unit_published = unit_published
    odo.slip_published = slip_published
    return poses, sources, odo


def fit_gyro_scale(gyro_t, gyro_rate, pose_t, pose_yaw, imu_delay: float = 0.0,
                   segment: float = 1.0) -> tuple[float, float]:
    """
    Fit the gyro's scale (measured over true rate) against a pose reference's heading.

    Over segments of ``segment`` s, the integrated raw rate is regressed on the reference's
    heading change with one bias per recording, ``dH = scale dpsi + b_r dt``; segments
    across a gap of either stream are left out, and those whose residual exceeds three
    robust standard deviations (pose glitches) dropped, twice.

    Parameters
    ----------
    gyro_t, gyro_rate : sequence of array_like
        Per recording: gyro stamps (s) and z rates (rad/s).
    pose_t, pose_yaw : sequence of array_like
        Per recording: reference stamps on the encoders' clock (its delay taken off), s,
        and yaw, rad.
    imu_delay : float
        s, the gyro's stamps behind the encoders.
    segment : float
        s.

    Returns
    -------
    scale, std : float
        The scale and its standard error; ``(1.0, inf)`` when the data cannot tell (fewer
        than ten segments). On the Warthog runs of ../shared/realdata the three runs give
        0.986-1.001 with standard errors of a few 0.001: a scale is worth applying only
        when it differs from 1 by several standard errors and more than the runs disagree.

    """
    rows, targets = [], []
    n = len(gyro_t)
    for r, (tg, wg, tp, yaw) in enumerate(zip(gyro_t, gyro_rate, pose_t, pose_yaw)):
        tg = np.asarray(tg, float) - imu_delay
        wg = np.asarray(wg, float)
        tp = np.asarray(tp, float)
        heading = np.unwrap(np.asarray(yaw, float))
        h = np.r_[0.0, np.cumsum(0.5 * (wg[1:] + wg[:-1]) * np.diff(tg))]
        lo, hi = max(tg[0], tp[0]), min(tg[-1], tp[-1])
        if hi - lo < 2 * segment:
            continue
        edges = lo + segment * np.arange(int((hi - lo) // segment) + 1)
        bad = np.zeros(len(edges) - 1, dtype=bool)
        for t in (tg, tp):
            steps = np.diff(t)
            gap = np.flatnonzero(steps > max(0.5, 5 * np.median(steps)))
            for g in gap:
                bad |= (edges[1:] > t[g]) & (edges[:-1] < t[g + 1])
        d_h = np.diff(np.interp(edges, tg, h))[~bad]
        d_psi = np.diff(np.interp(edges, tp, heading))[~bad]
        a = np.zeros((len(d_h), 1 + n))
        a[:, 0] = d_psi
        a[:, 1 + r] = segment
        rows.append(a)
        targets.append(d_h)
    if not rows or sum(len(t) for t in targets) < 10:
        return 1.0, math.inf
    a, y = np.vstack(rows), np.concatenate(targets)
    keep = np.ones(len(y), dtype=bool)
    for _ in range(3):
        p = np.linalg.lstsq(a[keep], y[keep], rcond=None)[0]
        residual = y - a @ p
        sigma = 1.4826 * np.median(np.abs(residual[keep] - np.median(residual[keep])))
        keep = np.abs(residual) <= 3.0 * max(sigma, 1e-9)
    if not (np.isfinite(p[0]) and p[0] > 0):
        return 1.0, math.inf
    a, residual = a[keep], residual[keep]
    dof = max(len(residual) - a.shape[1], 1)
    cov = np.linalg.pinv(a.T @ a) * float(residual @ residual) / dof
    return float(p[0]), float(np.sqrt(cov[0, 0]))
