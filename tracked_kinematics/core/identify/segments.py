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

from ..integration import relative_pose, wrap_angle
from ..recording import Recording


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


JUMP_MARGIN = 0.5
"""m beyond the fastest track's travel that makes a ground-truth step a jump."""
MAX_HEADING_STEP = 0.5
"""rad beyond the tracks' ideal-drive turn that makes a ground-truth heading step a glitch."""


def ground_truth_jumps(recording: Recording, track_width: float | None = None) -> np.ndarray:
    """
    Return the intervals between consecutive ground-truth samples over which the pose jumps.

    A jump (a lidar ICP re-localisation, a mapper catching up, a glitch) is a step longer
    than :data:`JUMP_MARGIN` plus the fastest track's travel over the interval, or a heading
    change larger than :data:`MAX_HEADING_STEP` plus the turn of an ideal drive with those
    travels (``|d_right - d_left| / track_width``; without ``track_width``, plus nothing).
    No vehicle moves so; the ground truth over such an interval cannot be trusted. Only
    intervals inside the pieces (:func:`covered_spans`) are judged: over a gap the travel
    is not known.

    Returns
    -------
    ndarray, shape (J, 2)
        ``(t_a, t_b)`` of each jump, s.

    """
    rec = recording
    if len(rec.gt_t) < 2 or len(rec.enc_t) < 2:
        return np.zeros((0, 2))
    d_left = np.abs(np.diff(np.interp(rec.gt_t, rec.enc_t, rec.left)))
    d_right = np.diff(np.interp(rec.gt_t, rec.enc_t, rec.right))
    turn = (np.abs(d_right - np.diff(np.interp(rec.gt_t, rec.enc_t, rec.left))) / track_width
            if track_width else 0.0)
    step = np.hypot(np.diff(rec.gt_x), np.diff(rec.gt_y))
    dyaw = np.abs(wrap_angle(np.diff(rec.gt_yaw)))
    jump = (step > JUMP_MARGIN + np.maximum(d_left, np.abs(d_right))) \
        | (dyaw > MAX_HEADING_STEP + turn)
    start, end = covered_spans(rec)
    piece = np.maximum(np.searchsorted(start, rec.gt_t[:-1], side='right') - 1, 0)
    inside = (len(start) > 0) & (rec.gt_t[:-1] >= start[piece]) & (rec.gt_t[1:] <= end[piece])
    jump &= inside
    return np.column_stack([rec.gt_t[:-1][jump], rec.gt_t[1:][jump]])


def over_jumps(segments: Segments, recordings, track_width: float | None = None) -> np.ndarray:
    """Segments that contain a ground-truth jump (:func:`ground_truth_jumps`)."""
    mask = np.zeros(len(segments), dtype=bool)
    for index, rec in enumerate(recordings):
        mine = np.flatnonzero(segments.recording == index)
        if len(mine) == 0:
            continue
        starts = ground_truth_jumps(rec, track_width)[:, 0]
        count = (np.searchsorted(starts, segments.t1[mine] - 1e-9)
                 - np.searchsorted(starts, segments.t0[mine] - 1e-9))
        mask[mine] = count > 0
    return mask


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


def stretches(times, gap: float | None = None):
    """
    Return the start and end times of the gap-free stretches of sample times.

    Parameters
    ----------
    times : array_like, shape (N,), N >= 1
        Sample times, s, increasing.
    gap : float, optional
        Longest interval that is not a gap, s; default :func:`gap_threshold` of ``times``.

    Returns
    -------
    start, end : ndarray
        s, one entry per stretch.

    """
    t = np.asarray(times, dtype=float)
    breaks = np.flatnonzero(np.diff(t) > (gap or gap_threshold(t)))
    return np.append(t[0], t[breaks + 1]), np.append(t[breaks], t[-1])


def covered_spans(recording: Recording, max_gap: float | None = None):
    """
    Spans where both streams have samples without a gap: the pieces of a recording.

    A recording made of pieces (a logger restarted, a bag split, a sensor that drops out)
    has gaps in one stream or both; a segment or a window must lie inside one piece, where
    the travel and the poses are both known.

    Parameters
    ----------
    recording : Recording
        The log.
    max_gap : float, optional
        Longest interval between two samples of a stream that is not a gap, s; default
        :func:`gap_threshold` of each stream.

    Returns
    -------
    start, end : ndarray, shape (P,)
        Start and end times of each piece, s, increasing (possibly none).

    """
    rec = recording
    if len(rec.enc_t) < 2 or len(rec.gt_t) < 2:
        return np.zeros(0), np.zeros(0)
    enc, gt = stretches(rec.enc_t, max_gap), stretches(rec.gt_t, max_gap)
    # Intersections of two sorted sets of disjoint intervals: each encoder stretch with the
    # ground-truth stretches it overlaps (a merge, linear in the number of pieces).
    first = np.searchsorted(gt[1], enc[0], side='right')
    counts = np.maximum(np.searchsorted(gt[0], enc[1], side='left') - first, 0)
    i = np.repeat(np.arange(len(enc[0])), counts)
    offsets = np.repeat(np.cumsum(counts) - counts, counts)
    j = np.repeat(first, counts) + np.arange(counts.sum()) - offsets
    start = np.maximum(enc[0][i], gt[0][j])
    end = np.minimum(enc[1][i], gt[1][j])
    keep = end > start
    order = np.argsort(start[keep], kind='stable')
    return start[keep][order], end[keep][order]


def _boundaries(t, spans, segment_length, partial):
    """Ground-truth sample indices that start/end segments, anchored in each span."""
    pairs = []
    lo = np.searchsorted(t, spans[0], side='left')
    hi = np.searchsorted(t, spans[1], side='right')
    for a, b in zip(lo, hi):
        if b - a < 2:
            continue
        tb = t[a:b]
        if segment_length:
            targets = tb[0] + segment_length * np.arange(
                int(np.floor((tb[-1] - tb[0]) / segment_length + 1e-9)) + 1)
            idx = np.unique(np.searchsorted(tb, targets - 1e-9))
            idx = idx[idx < len(tb)]
            if partial and len(idx) and tb[-1] - tb[idx[-1]] >= 0.5 * segment_length:
                idx = np.append(idx, len(tb) - 1)   # the rest of the piece, half or more
        else:
            idx = np.arange(len(tb))
        if len(idx) >= 2:
            pairs.append(np.stack([a + idx[:-1], a + idx[1:]], axis=1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.intp)


def build_segments(recordings, segment_length: float | None = 1.0,
                   max_gap: float | None = None, partial: bool = True) -> Segments:
    """
    Cut recordings into segments between ground-truth samples, inside their pieces.

    Parameters
    ----------
    recordings : sequence of Recording
        The logs.
    segment_length : float or None
        Target duration, s: each segment runs from a ground-truth sample to the first one
        at least this much later, anchored at the first ground-truth sample of each piece
        (:func:`covered_spans`: where both streams have samples without a gap), so that
        segments tile the pieces. None or 0: every pair of consecutive ground-truth samples.
        A segment shorter than half the target is dropped.
    max_gap : float, optional
        Longest interval between two encoder samples, or two ground-truth samples, inside a
        segment, s. Default :func:`gap_threshold` of each stream. Segments never span a
        longer interval (the travel over it is known, its timing is not).
    partial : bool
        Also end each piece with the segment from its last full segment to its last
        ground-truth sample, when that is half the target or more (a piece shorter than the
        target then gives one segment). False: full segments only (evaluation windows).

    Returns
    -------
    Segments

    """
    parts = []
    for index, rec in enumerate(recordings):
        spans = covered_spans(rec, max_gap)
        pairs = _boundaries(rec.gt_t, spans, segment_length, partial)
        if len(pairs) == 0:
            continue
        ta, tb = rec.gt_t[pairs[:, 0]], rec.gt_t[pairs[:, 1]]
        if segment_length:
            keep = (tb - ta) >= 0.5 * segment_length
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
        gi = pairs
        truth = np.stack(relative_pose(
            rec.gt_x[gi[:, 0]], rec.gt_y[gi[:, 0]], rec.gt_yaw[gi[:, 0]],
            rec.gt_x[gi[:, 1]], rec.gt_y[gi[:, 1]], rec.gt_yaw[gi[:, 1]]), axis=1)
        parts.append(Segments(
            np.diff(cum_left)[steps], np.diff(cum_right)[steps], np.diff(grid)[steps],
            np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp), truth, ta, tb,
            np.full(len(ta), index, dtype=np.intp)))
    return Segments.concatenate(parts) if parts else _empty_segments()
