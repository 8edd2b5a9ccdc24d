"""
How well a model predicts: final-pose errors over segments, held-out blocks, dead reckoning.

A model is judged by the odometry it gives on data it was not fitted to, as Martinez et
al. (2005) judge theirs on validation paths other than the training ones (sec. 6, Figs.
9-12), and by the final pose error of Fink & Stump (sec. IV-B, Fig. 6, Table III):
:class:`HoldOut` sets aside time blocks, :func:`prediction_errors` measures each held-out
segment's final pose error, and :func:`dead_reckoning` integrates a whole recording for
the pictures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import SegmentProblem
from .segments import Recording, Segments
from ..integration import wrap_angle
from ..models import MotionModel


@dataclass(frozen=True)
class ErrorStats:
    """
    Final-pose errors of a model over segments (or windows).

    Attributes
    ----------
    n : int
        Number of segments.
    position_mean, position_p90 : float
        Mean and 90th percentile of the final position error, m.
    heading_mean, heading_p90 : float
        Mean and 90th percentile of the absolute final heading error, rad.

    """

    n: int
    position_mean: float
    position_p90: float
    heading_mean: float
    heading_p90: float

    @classmethod
    def of(cls, position, heading):
        """Statistics of per-segment errors."""
        position = np.asarray(position, float)
        heading = np.abs(np.asarray(heading, float))
        if len(position) == 0:
            return cls(0, float('nan'), float('nan'), float('nan'), float('nan'))
        return cls(len(position), float(position.mean()), float(np.percentile(position, 90)),
                   float(heading.mean()), float(np.percentile(heading, 90)))

    def improvement_over(self, baseline: ErrorStats) -> dict[str, float]:
        """Percent reduction of the mean errors relative to ``baseline``."""
        def pct(ours, theirs):
            return float(100.0 * (1.0 - ours / theirs)) if theirs > 0 else 0.0
        return {'position': pct(self.position_mean, baseline.position_mean),
                'heading': pct(self.heading_mean, baseline.heading_mean)}


def prediction_errors(model: MotionModel, p, segments: Segments):
    """
    Compute the final position (m) and heading (rad, absolute) error of each prediction.

    Returns
    -------
    position, heading : ndarray, shape (S,)

    """
    if len(segments) == 0:
        return np.zeros(0), np.zeros(0)
    diff = segments.truth - SegmentProblem(model, segments).predict(p)
    return np.hypot(diff[:, 0], diff[:, 1]), np.abs(wrap_angle(diff[:, 2]))


@dataclass(frozen=True)
class HoldOut:
    """
    Time blocks held out of the fit, to measure how well a model predicts unseen data.

    Attributes
    ----------
    blocks : ndarray, shape (B, 3)
        ``(recording, t_start, t_end)`` of each held-out block.
    total_blocks : int
        Blocks the data were cut into.

    """

    blocks: np.ndarray
    total_blocks: int

    @classmethod
    def choose(cls, segments: Segments, fraction: float = 0.2, block_length: float = 30.0):
        """
        Cut the data into blocks of about ``block_length`` s and hold out evenly spaced ones.

        Returns None when there are fewer than 3 blocks (too little data to spare any).
        """
        if len(segments) == 0 or fraction <= 0.0:
            return None
        spans = []
        for rec in np.unique(segments.recording):
            mine = segments.recording == rec
            t0, t1 = float(segments.t0[mine].min()), float(segments.t1[mine].max())
            n = max(1, int(round((t1 - t0) / block_length)))
            edges = np.linspace(t0, t1, n + 1)
            spans += [(rec, edges[i], edges[i + 1]) for i in range(n)]
        if len(spans) < 3:
            return None
        k = min(len(spans) - 1, max(1, int(round(fraction * len(spans)))))
        chosen = np.floor((np.arange(k) + 0.5) * len(spans) / k).astype(int)
        return cls(np.array([spans[i] for i in chosen], dtype=float), len(spans))

    def inside(self, segments: Segments) -> np.ndarray:
        """Segments entirely within a held-out block."""
        mask = np.zeros(len(segments), dtype=bool)
        for rec, t0, t1 in self.blocks:
            mask |= (segments.recording == rec) & (segments.t0 >= t0 - 1e-9) \
                & (segments.t1 <= t1 + 1e-9)
        return mask

    def outside(self, segments: Segments) -> np.ndarray:
        """Segments that do not overlap any held-out block."""
        mask = np.ones(len(segments), dtype=bool)
        for rec, t0, t1 in self.blocks:
            mask &= ~((segments.recording == rec) & (segments.t1 > t0 + 1e-9)
                      & (segments.t0 < t1 - 1e-9))
        return mask


def dead_reckoning(model: MotionModel, p, recording: Recording):
    """
    Odometry of a whole recording from its first ground-truth pose, at the ground-truth times.

    The encoder travel is interpolated linearly at the ground-truth times (constant speed
    between encoder samples) and integrated along arcs, through gaps too.

    Returns
    -------
    t, x, y, yaw : ndarray
        Ground-truth times covered by the encoders and the odometry pose at each.

    """
    rec = recording
    inside = np.flatnonzero((rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1]))
    if len(inside) == 0:
        empty = np.zeros(0)
        return empty, empty, empty, empty
    t = rec.gt_t[inside]
    lo, hi = np.searchsorted(rec.enc_t, [t[0], t[-1]])
    grid = np.union1d(rec.enc_t[lo:hi], t)
    d_left = np.diff(np.interp(grid, rec.enc_t, rec.left))
    d_right = np.diff(np.interp(grid, rec.enc_t, rec.right))
    g0 = inside[0]
    x, y, yaw = model.integrate(p, d_left, d_right, np.diff(grid),
                                pose0=(rec.gt_x[g0], rec.gt_y[g0], rec.gt_yaw[g0]))
    x = np.concatenate([[rec.gt_x[g0]], x])
    y = np.concatenate([[rec.gt_y[g0]], y])
    yaw = np.concatenate([[rec.gt_yaw[g0]], yaw])
    at = np.searchsorted(grid, t)
    return t, x[at], y[at], yaw[at]
