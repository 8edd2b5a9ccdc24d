"""
Segments of a log: encoder steps between ground-truth samples, Martinez et al. (2005) sec. 4.2.

The identification cuts each log into short segments between ground-truth samples and
compares, for every segment, the pose increment the model predicts from the encoder travel
with the measured one (the cost of eq. 17, :mod:`.problem`). A segment is a run of *steps*,
intervals of constant track speed (the cumulative travel is interpolated linearly between
encoder samples), split at the ground-truth times; segments over a gap in either stream are
skipped, since the travel over a gap is known but its timing is not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..integration import relative_pose


@dataclass(frozen=True)
class Recording:
    """
    One continuous log: cumulative encoder travel and ground-truth poses.

    Attributes
    ----------
    enc_t : ndarray, shape (N,)
        Encoder sample times, s, strictly increasing.
    left, right : ndarray, shape (N,)
        Cumulative nominal travel of each track at those times, m (any offset).
    gt_t : ndarray, shape (M,)
        Ground-truth sample times, s, strictly increasing, on the same clock.
    gt_x, gt_y, gt_yaw : ndarray, shape (M,)
        Pose of base_link in a fixed frame: m, m, rad.
    name : str
        Where it came from (a bag path), for reports.

    """

    enc_t: np.ndarray
    left: np.ndarray
    right: np.ndarray
    gt_t: np.ndarray
    gt_x: np.ndarray
    gt_y: np.ndarray
    gt_yaw: np.ndarray
    name: str = ''

    def __post_init__(self):
        for group in (('enc_t', 'left', 'right'), ('gt_t', 'gt_x', 'gt_y', 'gt_yaw')):
            arrays = [np.asarray(getattr(self, n), dtype=float) for n in group]
            if any(a.ndim != 1 or a.shape != arrays[0].shape for a in arrays):
                raise ValueError(f'{", ".join(group)} must be 1-D arrays of one length')
            for n, a in zip(group, arrays):
                if not np.all(np.isfinite(a)):
                    raise ValueError(f'{n} has non-finite values')
                object.__setattr__(self, n, a)
        for n in ('enc_t', 'gt_t'):
            if np.any(np.diff(getattr(self, n)) <= 0.0):
                raise ValueError(f'{n} must be strictly increasing')

    @property
    def duration(self) -> float:
        """Time covered by both encoders and ground truth, s."""
        start = max(self.enc_t[0], self.gt_t[0]) if len(self.enc_t) and len(self.gt_t) else 0
        end = min(self.enc_t[-1], self.gt_t[-1]) if len(self.enc_t) and len(self.gt_t) else 0
        return float(max(0.0, end - start))


@dataclass(frozen=True)
class Segments:
    """
    Segments of encoder steps with the measured pose increment of each.

    The steps of all segments are stored end to end: segment ``i`` is the steps
    ``start[i]:stop[i]``, every segment has at least one step, and a step belongs to one
    segment. Steps are intervals of constant track speed (linear interpolation of the
    cumulative travel between encoder samples), split at the ground-truth times.

    Attributes
    ----------
    d_left, d_right : ndarray, shape (K,)
        Nominal track travel over each step, m.
    dt : ndarray, shape (K,)
        Step durations, s (> 0).
    start : ndarray of int, shape (S,)
        First step of each segment.
    truth : ndarray, shape (S, 3)
        Measured pose increment ``(dx, dy, dphi)`` of each segment in the frame of its start
        pose: m, m, rad in [-pi, pi).
    t0, t1 : ndarray, shape (S,)
        Segment start and end times, s.
    recording : ndarray of int, shape (S,)
        Index of the recording each segment comes from.

    """

    d_left: np.ndarray
    d_right: np.ndarray
    dt: np.ndarray
    start: np.ndarray
    truth: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    recording: np.ndarray

    def __len__(self):
        return len(self.start)

    @property
    def stop(self) -> np.ndarray:
        """One past the last step of each segment."""
        return np.append(self.start[1:], len(self.dt)).astype(np.intp)

    def per_segment(self, values) -> np.ndarray:
        """Sum per-step ``values`` (shape (K, ...)) over each segment."""
        if len(self) == 0:
            return np.zeros((0,) + np.shape(values)[1:])
        return np.add.reduceat(values, self.start, axis=0)

    @property
    def travel(self) -> np.ndarray:
        """Mean absolute nominal travel of the two tracks over each segment, m."""
        return self.per_segment(0.5 * (np.abs(self.d_left) + np.abs(self.d_right)))

    @property
    def ideal_turn(self) -> np.ndarray:
        """Heading change each segment would have as an ideal drive, in track-width units."""
        return self.per_segment(self.d_right - self.d_left)

    def select(self, mask) -> Segments:
        """Return the segments where ``mask`` is true, their steps kept end to end."""
        mask = np.asarray(mask, dtype=bool)
        lengths = self.stop - self.start
        step_mask = np.repeat(mask, lengths)
        kept_lengths = lengths[mask]
        start = np.concatenate([[0], np.cumsum(kept_lengths)[:-1]]).astype(np.intp)
        return Segments(self.d_left[step_mask], self.d_right[step_mask], self.dt[step_mask],
                        start[:len(kept_lengths)], self.truth[mask], self.t0[mask],
                        self.t1[mask], self.recording[mask])

    @classmethod
    def concatenate(cls, parts) -> Segments:
        """Join segment sets end to end."""
        parts = list(parts)
        offsets = np.cumsum([0] + [len(p.dt) for p in parts[:-1]])
        return cls(
            np.concatenate([p.d_left for p in parts]), np.concatenate([p.d_right for p in parts]),
            np.concatenate([p.dt for p in parts]),
            np.concatenate([p.start + o for p, o in zip(parts, offsets)]).astype(np.intp),
            np.concatenate([p.truth for p in parts]).reshape(-1, 3),
            np.concatenate([p.t0 for p in parts]), np.concatenate([p.t1 for p in parts]),
            np.concatenate([p.recording for p in parts]).astype(np.intp))


def _empty_segments() -> Segments:
    empty = np.zeros(0)
    return Segments(empty, empty, empty, np.zeros(0, np.intp), np.zeros((0, 3)), empty, empty,
                    np.zeros(0, np.intp))


def gap_threshold(times, factor: float = 5.0, floor: float = 0.2) -> float:
    """
    Longest interval between samples that is not a gap: ``max(factor x median, floor)`` s.

    Parameters
    ----------
    times : array_like
        Sample times, s, increasing.
    factor : float
        Multiple of the median sample interval.
    floor : float
        Lower bound, s, so that a fast and regular stream does not call jitter a gap.

    """
    intervals = np.diff(np.asarray(times, dtype=float))
    if len(intervals) == 0:
        return floor
    return float(max(factor * np.median(intervals), floor))


def _boundaries(t, segment_length, gap):
    """Ground-truth sample indices that start/end segments, per gap-free block."""
    breaks = np.flatnonzero(np.diff(t) > gap) + 1
    pairs = []
    for block in np.split(np.arange(len(t)), breaks):
        if len(block) < 2:
            continue
        tb = t[block]
        if segment_length:
            targets = tb[0] + segment_length * np.arange(
                int(np.floor((tb[-1] - tb[0]) / segment_length + 1e-9)) + 1)
            idx = np.unique(np.searchsorted(tb, targets - 1e-9))
            idx = idx[idx < len(tb)]
        else:
            idx = np.arange(len(tb))
        if len(idx) >= 2:
            pairs.append(np.stack([block[idx[:-1]], block[idx[1:]]], axis=1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.intp)


def build_segments(recordings, segment_length: float | None = 1.0,
                   max_gap: float | None = None) -> Segments:
    """
    Cut recordings into segments between ground-truth samples, skipping gaps.

    Parameters
    ----------
    recordings : sequence of Recording
        The logs.
    segment_length : float or None
        Target duration, s: each segment runs from a ground-truth sample to the first one
        at least this much later (measured from the start of its gap-free stretch, so
        segments tile it). None or 0: every pair of consecutive ground-truth samples. A
        last segment shorter than half the target is dropped.
    max_gap : float, optional
        Longest interval between two encoder samples, or two ground-truth samples, inside a
        segment, s. Default :func:`gap_threshold` of each stream. Segments over a longer
        interval are skipped (the travel over it is known, its timing is not).

    Returns
    -------
    Segments

    """
    parts = []
    for index, rec in enumerate(recordings):
        if len(rec.enc_t) < 2 or len(rec.gt_t) < 2:
            continue
        inside = np.flatnonzero((rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1]))
        if len(inside) < 2:
            continue
        t = rec.gt_t[inside]
        pairs = _boundaries(t, segment_length, max_gap or gap_threshold(t))
        if len(pairs) == 0:
            continue
        ta, tb = t[pairs[:, 0]], t[pairs[:, 1]]
        keep = np.ones(len(pairs), dtype=bool)
        if segment_length:
            keep &= (tb - ta) >= 0.5 * segment_length
        # Skip segments that contain an encoder gap.
        enc_gap = max_gap or gap_threshold(rec.enc_t)
        gap_at = np.flatnonzero(np.diff(rec.enc_t) > enc_gap)
        if len(gap_at):
            g0, g1 = rec.enc_t[gap_at], rec.enc_t[gap_at + 1]
            last = np.searchsorted(g0, tb, side='left') - 1
            keep &= ~((last >= 0) & (g1[np.maximum(last, 0)] > ta))
        pairs, ta, tb = pairs[keep], ta[keep], tb[keep]
        if len(pairs) == 0:
            continue
        # Steps: encoder times and segment boundaries, one grid.
        lo, hi = np.searchsorted(rec.enc_t, [ta[0], tb[-1]])
        grid = np.union1d(rec.enc_t[lo:hi], np.concatenate([ta, tb]))
        cum_left = np.interp(grid, rec.enc_t, rec.left)
        cum_right = np.interp(grid, rec.enc_t, rec.right)
        first = np.searchsorted(grid, ta)
        last = np.searchsorted(grid, tb)
        lengths = last - first
        steps = np.repeat(first - np.cumsum(np.concatenate([[0], lengths[:-1]])), lengths) \
            + np.arange(lengths.sum())
        gi = inside[pairs]
        truth = np.stack(relative_pose(
            rec.gt_x[gi[:, 0]], rec.gt_y[gi[:, 0]], rec.gt_yaw[gi[:, 0]],
            rec.gt_x[gi[:, 1]], rec.gt_y[gi[:, 1]], rec.gt_yaw[gi[:, 1]]), axis=1)
        parts.append(Segments(
            np.diff(cum_left)[steps], np.diff(cum_right)[steps], np.diff(grid)[steps],
            np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp), truth, ta, tb,
            np.full(len(ta), index, dtype=np.intp)))
    return Segments.concatenate(parts) if parts else _empty_segments()
