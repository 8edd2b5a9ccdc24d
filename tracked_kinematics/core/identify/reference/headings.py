"""
The heading references of a calibration: the gyro's heading, cut into segments with the pose's.

Step 3 of :func:`.calibration.fit_recordings`; :func:`heading_reference` makes the gyro a
heading-only ground truth for scoring.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .recordings import clean_gyro
from ..segments import gap_threshold
from ...errors import ExcitationError
from ...integration import wrap_angle
from ...recording import Recording

MAX_STRAIGHT_TURN = math.radians(15.0)
"""Largest heading excursion, rad, of a drive that counts as straight."""
MIN_MOVING_SEGMENTS = 10
"""Fewest moving segments for a heading fit."""
_MIN_TRAVEL = 0.01


def gyro_heading(rec: Recording, delay: float):
    """
    Return the gyro's stamps (``delay`` removed) and its continuous heading, rad.

    The orientation's heading where the recording has one (no bias to integrate), else the
    rate integrated.
    """
    t = rec.gyro_t - delay
    if rec.gyro_yaw is not None:
        return t, np.unwrap(rec.gyro_yaw)
    w = rec.gyro_rate
    return t, np.r_[0.0, np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))]


def _bad_spans(t, lo, hi):
    """Mask of intervals ``[lo, hi]`` that straddle a gap of the stream ``t``."""
    gap = gap_threshold(t)
    steps = np.diff(t)
    starts, ends = t[:-1][steps > gap], t[1:][steps > gap]
    bad = np.zeros(len(lo), dtype=bool)
    for a, b in zip(starts, ends):
        bad |= (hi > a) & (lo < b)
    return bad | (lo < t[0]) | (hi > t[-1])


@dataclass
class _Segments:
    """Heading segments of all recordings, one source."""

    d_left: np.ndarray
    d_right: np.ndarray
    dt: np.ndarray
    dpsi: np.ndarray
    recording: np.ndarray
    t0: np.ndarray


def _segments(recordings, series, length):
    """Cut the encoders and a heading series per recording into segments of ``length`` s."""
    parts = []
    for r, (rec, s) in enumerate(zip(recordings, series)):
        if s is None:
            continue
        ht, heading = s
        start = max(rec.enc_t[0], ht[0])
        stop = min(rec.enc_t[-1], ht[-1])
        if stop - start < length:
            continue
        edges = start + length * np.arange(int((stop - start) // length) + 1)
        lo, hi = edges[:-1], edges[1:]
        bad = _bad_spans(rec.enc_t, lo, hi) | _bad_spans(ht, lo, hi)
        left, right, psi = (np.interp(edges, x, y) for x, y in
                            ((rec.enc_t, rec.left), (rec.enc_t, rec.right), (ht, heading)))
        keep = ~bad
        parts.append((np.diff(left)[keep], np.diff(right)[keep], (hi - lo)[keep],
                      np.diff(psi)[keep], np.full(int(keep.sum()), r), lo[keep]))
    if not parts:
        empty = np.zeros(0)
        return _Segments(empty, empty, empty, empty, np.zeros(0, dtype=int), empty)
    cols = [np.concatenate(c) for c in zip(*parts)]
    return _Segments(*cols[:4], cols[4].astype(int), cols[5])


def _check_straight(seg: _Segments) -> None:
    """Refuse a 'straight' drive whose heading (bias from the standstill) turns too much."""
    travel = 0.5 * (np.abs(seg.d_left) + np.abs(seg.d_right))
    still = travel < 1e-3
    bias = float(np.sum(seg.dpsi[still]) / np.sum(seg.dt[still])) \
        if np.sum(seg.dt[still]) >= 2.0 else 0.0
    for r in np.unique(seg.recording):
        mine = seg.recording == r
        moving = np.flatnonzero(mine & ~still)
        if moving.size == 0:
            continue
        span = slice(moving[0], moving[-1] + 1)
        heading = np.cumsum(seg.dpsi[span] - bias * seg.dt[span])
        turn = float(np.max(np.abs(heading)))
        if turn > MAX_STRAIGHT_TURN:
            raise ExcitationError(f'not a straight drive: the heading turns by '
                                  f'{math.degrees(turn):.1f} deg (at most '
                                  f'{math.degrees(MAX_STRAIGHT_TURN):.0f} for a straight drive '
                                  'of measured length)')


@dataclass
class HeadingData:
    """
    The heading references of all recordings, cut into segments (step 3 of the calibration).

    ``sources`` are ``(name, _Segments, has_bias)``, ``imu`` first; ``moving`` flags segments with
    travel; ``turned`` (rad) and ``driven`` (m) are totals of the first source.
    """

    gyro: list
    pose: list
    sources: list
    moving: np.ndarray
    turned: float
    driven: float


def _moving(seg: _Segments) -> np.ndarray:
    """Return which segments move: mean track travel of at least ``_MIN_TRAVEL``."""
    return 0.5 * (np.abs(seg.d_left) + np.abs(seg.d_right)) >= _MIN_TRAVEL


def heading_data(recs, imu_delay: float, pose_delay: float, segment_length: float,
                 straight: bool) -> HeadingData:
    """
    Cut the gyro and pose headings of every recording into segments of ``segment_length`` s.

    The delays (s) are removed here. Raises ExcitationError for fewer than
    :data:`MIN_MOVING_SEGMENTS` moving segments or a ``straight`` that turns.
    """
    gyro = [gyro_heading(r, imu_delay) if r.gyro_t is not None else None for r in recs]
    pose = [(r.pose[0] - pose_delay, np.unwrap(r.pose[3])) if r.pose is not None else None
            for r in recs]
    sources = []
    if any(g is not None for g in gyro):
        sources.append(('imu', _segments(recs, gyro, segment_length), True))
    if any(p is not None for p in pose):
        sources.append(('pose', _segments(recs, pose, segment_length), False))
    moving = np.concatenate([_moving(s) for _, s, _ in sources])
    if np.count_nonzero(moving) < MIN_MOVING_SEGMENTS:
        raise ExcitationError(f'{np.count_nonzero(moving)} moving segments of '
                              f'{segment_length:g} s with a heading reference (need '
                              f'{MIN_MOVING_SEGMENTS}): drive more')
    first = sources[0][1]
    turned = float(np.sum(np.abs(first.dpsi[_moving(first)])))
    driven = float(np.sum(0.5 * np.abs(first.d_left + first.d_right)))
    if straight:
        _check_straight(first)
    return HeadingData(gyro, pose, sources, moving, turned, driven)


def heading_reference(rec: Recording, delay: float, bias: float,
                      rate: float = 10.0) -> Recording:
    """
    Return a Recording whose ground truth is the gyro's heading: to score heading only.

    The gyro heading at ``rate`` Hz, ``delay`` s taken off its stamps and ``bias`` rad/s off its
    rates; positions all zero (not measured).
    """
    if rec.gyro_t is None:
        raise ValueError('the recording has no gyro')
    rec = clean_gyro(rec)
    t, heading = gyro_heading(rec, delay)
    heading = heading - bias * (t - t[0])
    grid = np.arange(t[0], t[-1], 1.0 / rate)
    # Only inside gap-free gyro stretches: a gap leaves the heading unknown.
    gap = gap_threshold(t)
    k = np.clip(np.searchsorted(t, grid, side='right'), 1, len(t) - 1)
    ok = (t[k] - t[k - 1]) <= gap
    grid = grid[ok]
    zeros = np.zeros(grid.size)
    return Recording(rec.enc_t, rec.left, rec.right, grid, zeros, zeros,
                     wrap_angle(np.interp(grid, t, heading)), name=rec.name)
