"""
How well a model predicts: final-pose errors over segments, held-out blocks, dead reckoning.

Judged on data it was not fitted to, as Martinez et al. (2005, sec. 6) judge theirs, by the final
pose error of Fink & Stump (sec. IV-B, Table III).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from .problem import SegmentProblem
from .segments import build_segments, Recording, Segments
from ..integration import wrap_angle
from ..models import MotionModel


@dataclass(frozen=True)
class ErrorStats:
    """Final-pose errors over ``n`` segments: mean and p90 of position (m) and |heading| (rad)."""

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

    def improvement_over(self, baseline: ErrorStats) -> dict[str, float | None] | None:
        """
        Return the percent reduction of the mean errors relative to ``baseline``, or None.

        None when either has no segments, or against a zero baseline error that is exceeded.
        """
        if self.n == 0 or baseline.n == 0:
            return None

        def pct(ours, theirs):
            if theirs > 0:
                return float(100.0 * (1.0 - ours / theirs))
            return 0.0 if ours <= theirs else None
        return {'position': pct(self.position_mean, baseline.position_mean),
                'heading': pct(self.heading_mean, baseline.heading_mean)}


def prediction_errors(model: MotionModel, p, segments: Segments):
    """Compute the final position (m) and absolute heading (rad) error of each prediction."""
    if len(segments) == 0:
        return np.zeros(0), np.zeros(0)
    diff = segments.truth - SegmentProblem(model, segments).predict(p)
    return np.hypot(diff[:, 0], diff[:, 1]), np.abs(wrap_angle(diff[:, 2]))


MIN_BLOCKS = 10
"""Blocks the driving time is cut into at least, when the block length allows."""
MIN_WINDOWS = 20
"""Fewer held-out windows than this in one fold (and too few segments, :data:`MIN_SEGMENTS`):
every block is held out once, in turn."""
MIN_SEGMENTS = 200
"""As many held-out segments in one fold are enough for a comparison, windows or not."""


@dataclass(frozen=True)
class HoldOut:
    """
    Time blocks held out of the fit, to measure how well a model predicts unseen data.

    The driving time is cut into blocks; a fold holds out ``fraction`` of them, evenly spaced, or,
    when that leaves too few windows, the blocks in turn over ``round(1 / fraction)`` folds.
    ``spans`` rows are ``(block, recording, t_start, t_end)``.
    """

    spans: np.ndarray
    folds: tuple
    total_blocks: int
    block_length: float

    @property
    def blocks(self) -> np.ndarray:
        """Return ``(recording, t_start, t_end)`` of every span any fold holds out: (B, 3)."""
        held = np.isin(self.spans[:, 0], np.concatenate(self.folds))
        return self.spans[held, 1:]

    @property
    def cross_validated(self) -> bool:
        """Whether every block is held out in turn (more than one fold)."""
        return len(self.folds) > 1

    def held_spans(self, fold: int = 0) -> np.ndarray:
        """Return ``(recording, t_start, t_end)`` of the spans one fold holds out."""
        return self.spans[np.isin(self.spans[:, 0], self.folds[fold]), 1:]

    @classmethod
    def choose(cls, segments: Segments, fraction: float = 0.2, block_length: float = 30.0,
               window: float = 0.0, folds: int | None = None):
        """
        Cut the driving time into blocks and choose the blocks each fold holds out.

        ``block_length`` (s) is the longest block, shortened on short data to give
        :data:`MIN_BLOCKS` but not below two ``window`` lengths (s). Returns None without segments
        or with ``fraction <= 0``.
        """
        if len(segments) == 0 or fraction <= 0.0:
            return None
        order = np.lexsort((segments.t0, segments.recording))
        duration = (segments.t1 - segments.t0)[order]
        driving = float(duration.sum())
        length = min(block_length, max(2.0 * window, driving / MIN_BLOCKS))
        # As many blocks as fit, each at least `length` (two windows) long; three at least.
        n_blocks = max(3, int(math.floor(driving / length + 1e-9)))
        # Block of each segment by the driving time before its middle.
        elapsed = np.cumsum(duration) - 0.5 * duration
        block = np.minimum((elapsed / driving * n_blocks).astype(np.intp), n_blocks - 1)
        rec = segments.recording[order]
        t0, t1 = segments.t0[order], segments.t1[order]
        # One span per run of segments of one block in one recording.
        change = np.flatnonzero((np.diff(block) != 0) | (np.diff(rec) != 0)) + 1
        first = np.concatenate([[0], change])
        last = np.concatenate([change, [len(block)]]) - 1
        spans = np.column_stack([block[first], rec[first], t0[first], t1[last]]).astype(float)
        if folds is None or folds <= 1:
            k = min(n_blocks - 1, max(1, int(round(fraction * n_blocks))))
            chosen = (np.floor((np.arange(k) + 0.5) * n_blocks / k).astype(np.intp),)
        else:
            folds = min(int(folds), n_blocks)
            chosen = tuple(np.arange(f, n_blocks, folds) for f in range(folds))
        return cls(spans, chosen, n_blocks, driving / n_blocks)

    def _overlap(self, segments, fold, entirely):
        if fold is None:
            spans = self.blocks
        else:
            spans = self.held_spans(fold)
        mask = np.zeros(len(segments), dtype=bool)
        for rec, t0, t1 in spans:
            mine = segments.recording == rec
            if entirely:
                mask |= mine & (segments.t0 >= t0 - 1e-9) & (segments.t1 <= t1 + 1e-9)
            else:
                mask |= mine & (segments.t1 > t0 + 1e-9) & (segments.t0 < t1 - 1e-9)
        return mask

    def inside(self, segments: Segments, fold: int | None = None) -> np.ndarray:
        """Segments entirely within a block held out by ``fold`` (None: by any fold)."""
        return self._overlap(segments, fold, True)

    def outside(self, segments: Segments, fold: int | None = None) -> np.ndarray:
        """Segments that overlap no block held out by ``fold`` (None: by any fold)."""
        return ~self._overlap(segments, fold, False)

    def windows(self, recordings, length: float, fold: int = 0,
                stride: float | None = None) -> Segments:
        """Windows of ``length`` s in held-out blocks, every ``stride`` s, never over gaps."""
        stride = 0.5 * length if stride is None else float(stride)
        phases = max(1, int(math.ceil(length / stride - 1e-9)))
        recordings = list(recordings)
        crops, origin = [], []
        for rec, t0, t1 in self.held_spans(fold):
            full = recordings[int(rec)]
            for k in range(phases):
                start = t0 + k * stride
                if t1 - start < length:
                    break
                crops.append(crop_recording(full, start, t1))
                origin.append(int(rec))
        windows = build_segments(crops, length, partial=False)
        windows = replace(windows, recording=np.asarray(origin, np.intp)[windows.recording])
        # Whole windows: ground-truth samples fall where they fall, a window's end is the
        # first sample at least `length` after its start, unless the piece ends first.
        return windows.select(windows.t1 - windows.t0 >= 0.9 * length)


def crop_recording(recording: Recording, start: float, end: float) -> Recording:
    """Cut a recording to ``start``-``end`` s (and one encoder sample more each side)."""
    rec = recording
    e0 = max(0, int(np.searchsorted(rec.enc_t, start, side='right')) - 1)
    e1 = int(np.searchsorted(rec.enc_t, end, side='left')) + 1
    g0, g1 = np.searchsorted(rec.gt_t, [start - 1e-9, end + 1e-9])
    return Recording(rec.enc_t[e0:e1], rec.left[e0:e1], rec.right[e0:e1], rec.gt_t[g0:g1],
                     rec.gt_x[g0:g1], rec.gt_y[g0:g1], rec.gt_yaw[g0:g1], name=rec.name)


def dead_reckoning(model: MotionModel, p, recording: Recording):
    """Odometry ``t, x, y, yaw`` of a recording from its first ground-truth pose, at its times."""
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
