"""
The pose's heading and the gyro's in one, each weighted by its measured noise.

A pose reference (lidar ICP, motion capture) measures the heading with a white noise of its
own (``sigma_pose`` rad per sample) and no drift; a gyro integrates to a heading that is
nearly noiseless over a second and drifts as a random walk (``q`` rad/sqrt(s)) plus its bias.
:func:`fuse_heading` keeps the gyro's increments and takes the offset between the two from
the pose, fitted as a local straight line (offset and bias) over a window ``W`` around each
pose sample. The window balances the two noises: the offset of ``n = f W`` pose samples is
known to ``sigma_pose / sqrt(f W)``, the gyro drifts ``q sqrt(W / 2)`` over half of it, and
the sum of the two variances is least at ``W = sqrt(2 sigma_pose^2 / (f q^2))``. This is our
own construction (a fixed-window smoother), in no paper. :func:`check_gyro_against_pose` is
the check before a gyro is fused or its constants written: it must turn the way the pose
turns, at a plausible scale.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from ..segments import stretches
from ...gyro import fit_gyro_scale
from ...recording import Recording

MIN_WINDOW, MAX_WINDOW = 1.0, 30.0
"""Bounds of the smoothing window, s."""
SCALE_RANGE = (0.8, 1.25)
"""Gyro scales (measured over true rate) taken as plausible; outside: the gyro is refused."""
BIAS_SIGMA_FLOOR = 0.002
"""rad/s: least run-to-run uncertainty of a gyro bias written to the terrain file."""


@dataclass(frozen=True)
class HeadingFusion:
    """
    What :func:`fuse_heading` measured.

    Attributes
    ----------
    sigma_pose : float
        White noise of the pose heading, rad (robust, from its differences with the gyro).
    q : float
        Random walk of the gyro heading, rad/sqrt(s) (from the drift of the offset).
    window : float
        Smoothing window used, s.
    biases : list of float
        Gyro bias per recording, rad/s (its heading drift against the pose's).
    bias_errors : list of float
        Their standard errors, rad/s.
    rate : float
        Pose samples per second.

    """

    sigma_pose: float
    q: float
    window: float
    biases: list
    rate: float
    bias_errors: list = ()


def check_gyro_against_pose(scale: float, std: float) -> str:
    """
    Return why a gyro cannot be trusted against the pose ('' when it can).

    ``scale`` is the gyro's fitted scale against the pose's heading increments
    (:func:`tracked_kinematics.core.gyro.fit_gyro_scale`, measured over true).
    """
    if not math.isfinite(std):
        return 'too few segments to compare the gyro with the pose'
    if scale < -0.5:
        return (f'the gyro turns the other way than the pose (scale {scale:.2f}): its sign is '
                'swapped (an IMU mounted upside down, or publishing NED)')
    if abs(scale) < 0.5:
        return (f'the gyro hardly turns with the pose (scale {scale:.2f}): not the yaw axis, '
                'or the pose on another clock')
    if not SCALE_RANGE[0] <= scale <= SCALE_RANGE[1]:
        return (f'the gyro turns {scale:.2f} x as fast as the pose, outside '
                f'{SCALE_RANGE[0]:g}-{SCALE_RANGE[1]:g}: a wrong unit or axis')
    return ''


def signed_gyro_scale(recordings, imu_delay: float) -> tuple[float, float]:
    """
    Return the gyro's scale against the pose's heading, negative for a gyro turning the other way.

    :func:`tracked_kinematics.core.gyro.fit_gyro_scale` on the recordings with a gyro
    rate and a pose (their delay removed), which knows no negative scale: when it finds none,
    the same fit of the negated rate gives it. ``(1.0, inf)``: too few segments.
    """
    recs = [r for r in recordings if r.gyro_t is not None and r.gyro_rate is not None
            and r.gt_t is not None]
    if not recs:
        return 1.0, math.inf
    args = ([r.gyro_t for r in recs], [r.gyro_rate for r in recs], [r.gt_t for r in recs],
            [r.gt_yaw for r in recs], imu_delay)
    scale, std = fit_gyro_scale(*args)
    if math.isfinite(std):
        return scale, std
    args = (args[0], [-r for r in args[1]]) + args[2:]
    scale, std = fit_gyro_scale(*args)
    return (-scale, std) if math.isfinite(std) else (1.0, math.inf)


def _pieces(rec: Recording, gyro_t):
    """Yield index arrays of the pose samples inside gap-free stretches of both streams."""
    starts, ends = stretches(rec.gt_t)
    g_starts, g_ends = stretches(gyro_t)
    for a, b in zip(starts, ends):
        for c, d in zip(g_starts, g_ends):
            lo, hi = max(a, c), min(b, d)
            idx = np.flatnonzero((rec.gt_t >= lo) & (rec.gt_t <= hi))
            if len(idx) >= 3:
                yield idx


def _local_line(t, r, window):
    """Fit ``r`` by a straight line over ``[t - W/2, t + W/2]`` at every ``t``; its value."""
    lo = np.searchsorted(t, t - 0.5 * window)
    hi = np.searchsorted(t, t + 0.5 * window, side='right')
    tc = t - t[0]
    sums = [np.r_[0.0, np.cumsum(v)] for v in (np.ones_like(t), tc, tc * tc, r, tc * r)]
    n, s_t, s_tt, s_r, s_tr = (c[hi] - c[lo] for c in sums)
    det = n * s_tt - s_t ** 2
    ok = det > 1e-12 * np.maximum(n * s_tt, 1e-300)
    slope = np.where(ok, (n * s_tr - s_t * s_r) / np.where(ok, det, 1.0), 0.0)
    mean_t, mean_r = s_t / n, s_r / n
    return mean_r + slope * (tc - mean_t), slope


def _offsets(rec, gyro_t, heading):
    """Return per piece: pose times, offset pose minus gyro heading (unwrapped)."""
    out = []
    for idx in _pieces(rec, gyro_t):
        t = rec.gt_t[idx]
        pose = np.unwrap(rec.gt_yaw[idx])
        out.append((t, pose - np.interp(t, gyro_t, heading)))
    return out


def _noise(pieces, rate):
    """Return the pose's white noise and the gyro's random walk from the offsets' increments."""
    d = np.concatenate([np.diff(r) for _, r in pieces])
    if d.size < 10:
        return math.nan, math.nan
    mad = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    sigma_pose = max(mad / math.sqrt(2.0), 1e-5)
    # The drift over a longer lag L, a bias (a straight line) taken out by second differences:
    # var(r(t + L) - 2 r(t) + r(t - L)) = 6 sigma^2 + 2 q^2 L.
    second = []
    lag = max(1, int(round(5.0 * rate)))
    for t, r in pieces:
        if len(r) > 2 * lag:
            second.append(r[2 * lag:] - 2.0 * r[lag:-lag] + r[:-2 * lag])
    if not second:
        return sigma_pose, 1e-3
    variance = float(np.median(np.concatenate(second) ** 2)) / 0.455   # median of chi2(1)
    q2 = (variance - 6.0 * sigma_pose ** 2) / (2.0 * lag / rate)
    return sigma_pose, math.sqrt(max(q2, 1e-10))


def _drift(pieces, rate_at) -> tuple[float, float]:
    """
    Return the gyro bias from the offsets pose minus gyro of one recording and its error, rad/s.

    ``r(t) = c_k - b (t - t_k) + delta w(t)``: an offset per piece, the bias ``b`` common, and a
    residual misalignment of the two clocks ``delta`` times the rate ``w`` (a pose a few 0.01 s
    off turns a fast turn's start into a slope); least squares, then once more without the
    residuals beyond three robust standard deviations (pose glitches).
    """
    if not pieces:
        return math.nan, math.inf
    n = len(pieces)
    rows, ys = [], []
    for k, (t, r) in enumerate(pieces):
        a = np.zeros((len(t), n + 2))
        a[:, k] = 1.0
        a[:, n] = -(t - t[0])
        a[:, n + 1] = rate_at(t)
        rows.append(a)
        ys.append(r)
    a, y = np.vstack(rows), np.concatenate(ys)
    keep = np.ones(len(y), dtype=bool)
    for _ in range(2):
        p, *_ = np.linalg.lstsq(a[keep], y[keep], rcond=None)
        res = y - a @ p
        mad = 1.4826 * float(np.median(np.abs(res[keep] - np.median(res[keep]))))
        keep = np.abs(res) <= 3.0 * max(mad, 1e-9)
    # Standard error of b with the residuals' spread (their correlation over a few samples
    # ignored: a lower bound, which bias_prior's floor covers).
    cov = np.linalg.pinv(a[keep].T @ a[keep]) * float(np.mean(res[keep] ** 2))
    return float(p[n]), float(math.sqrt(max(cov[n, n], 0.0)))


def fuse_heading(recordings, imu_delay: float, gyro_scale: float = 1.0):
    """
    Return the recordings with the pose's heading replaced by the fused one, and the fusion.

    Parameters
    ----------
    recordings : sequence of Recording
        With a pose (``gt_*``, its own delay already removed) and a gyro rate.
    imu_delay : float
        s of the gyro stamps behind the encoders.
    gyro_scale : float
        The gyro's scale (measured over true), divided out.

    Returns
    -------
    recordings : list of Recording
        Same positions and times; ``gt_yaw`` fused where both streams cover, the pose's
        elsewhere.
    fusion : HeadingFusion

    """
    recs = list(recordings)
    headings, all_pieces = [], []
    for rec in recs:
        gyro_t = rec.gyro_t - imu_delay
        w = rec.gyro_rate / gyro_scale
        heading = np.r_[0.0, np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(gyro_t))]
        headings.append((gyro_t, heading))
        all_pieces.append(_offsets(rec, gyro_t, heading))
    span = sum(float(t[-1] - t[0]) for p in all_pieces for t, _ in p)
    count = sum(len(t) for p in all_pieces for t, _ in p)
    rate = count / span if span > 0 else 1.0
    sigma_pose, q = _noise([x for p in all_pieces for x in p], rate)
    if not math.isfinite(sigma_pose):
        raise ValueError('too few pose samples beside the gyro to fuse the headings')
    window = float(np.clip(math.sqrt(2.0 * sigma_pose ** 2 / (rate * q ** 2)), MIN_WINDOW,
                           MAX_WINDOW))
    fused, biases = [], []
    for rec, (gyro_t, heading), pieces in zip(recs, headings, all_pieces):
        yaw = np.unwrap(rec.gt_yaw).copy()
        for t, r in pieces:
            offset, _ = _local_line(t, r, window)
            idx = np.searchsorted(rec.gt_t, t)
            # Keep each piece's own unwrapping: fused = gyro heading + smoothed offset.
            yaw[idx] = np.interp(t, gyro_t, heading) + offset
        fused.append(replace(rec, gt_yaw=np.angle(np.exp(1j * yaw))))
        w = rec.gyro_rate / gyro_scale
        biases.append(_drift(pieces, lambda t, gt=gyro_t, w=w: np.interp(t, gt, w)))
    return fused, HeadingFusion(sigma_pose, q, window, [b for b, _ in biases], rate,
                                [e for _, e in biases])


def bias_prior(biases, std_error: float = 0.0) -> tuple[float, float]:
    """
    Return the gyro bias to write and its honest uncertainty, rad/s.

    The mean of the per-recording biases; its sigma the spread between recordings (the
    run-to-run change a robot restarted will see), the standard error, and at least
    :data:`BIAS_SIGMA_FLOOR` (one recording cannot show a run-to-run change).
    """
    b = np.asarray([x for x in biases if x is not None and math.isfinite(x)], float)
    if b.size == 0:
        return math.nan, math.nan
    spread = float(np.std(b, ddof=1)) if b.size >= 2 else 0.0
    sigma = math.sqrt(spread ** 2 + std_error ** 2)
    return float(np.mean(b)), max(sigma, BIAS_SIGMA_FLOOR)
