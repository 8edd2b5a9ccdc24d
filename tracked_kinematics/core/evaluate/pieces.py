"""
Gap-free pieces of a recording, and odometry along them.

Scores compare odometry with the ground truth only within a piece (no gap in either stream, no
ground-truth jump, as identify_icr finds them); odometry integrates the travel with constant tread
ICRs (Martinez et al. 2005, eqs. 7-9, 20-21) along exact arcs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .metrics import window_pairs
from ..identify import gap_threshold, Recording
from ..identify.segments import ground_truth_jumps
from ..integration import integrate


@dataclass(frozen=True)
class Piece:
    """
    A gap-free stretch of one recording.

    Attributes
    ----------
    t, truth : ndarray, shape (M,), (M, 3)
        Ground-truth times (s) and ``(x, y, yaw)`` (m, m, rad; yaw unwrapped).
    grid : ndarray, shape (K,)
        Step boundaries: the encoder and ground-truth times of the piece, s.
    left, right : ndarray, shape (K,)
        Cumulative nominal travel of each track at the grid times, m.
    at : ndarray of int, shape (M,)
        Grid index of each ground-truth sample.

    """

    recording: int
    t: np.ndarray
    truth: np.ndarray
    grid: np.ndarray
    left: np.ndarray
    right: np.ndarray
    at: np.ndarray

    @property
    def duration(self) -> float:
        """Return the time the piece covers, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def steps(self):
        """Return the nominal travel of each track over each grid step (m) and its length (s)."""
        return np.diff(self.left), np.diff(self.right), np.diff(self.grid)

    @property
    def path_length(self) -> float:
        """Return the length of the ground-truth path, m (sum of its steps)."""
        return float(np.sum(np.hypot(np.diff(self.truth[:, 0]), np.diff(self.truth[:, 1]))))


@dataclass(frozen=True)
class Cut:
    """How a recording was cut: pieces, intervals left out (gaps, jumps), seconds covered."""

    pieces: list
    gaps: int
    jumps: int
    seconds: float


def cut(recording: Recording, index: int = 0, jumps: bool = True,
        track_width: float | None = None) -> Cut:
    """
    Cut a recording into gap-free, jump-free pieces of at least two ground-truth samples.

    ``jumps`` False scores across jumps; ``track_width`` (m) adds the heading glitches.
    """
    rec = recording
    keep = (rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1])
    t = rec.gt_t[keep]
    empty = Cut([], 0, 0, 0.0)
    if len(t) < 2 or len(rec.enc_t) < 2:
        return empty
    truth = np.column_stack([rec.gt_x[keep], rec.gt_y[keep], np.unwrap(rec.gt_yaw[keep])])
    # Bad intervals between consecutive ground-truth samples: gaps and jumps.
    gap = np.diff(t) > gap_threshold(rec.gt_t)
    enc_gap = gap_threshold(rec.enc_t)
    at_gap = np.flatnonzero(np.diff(rec.enc_t) > enc_gap)
    if len(at_gap):
        g0, g1 = rec.enc_t[at_gap], rec.enc_t[at_gap + 1]
        last = np.searchsorted(g0, t[1:], side='left') - 1
        gap |= (last >= 0) & (g1[np.maximum(last, 0)] > t[:-1])
    jumped = np.zeros_like(gap)
    if jumps:
        starts = ground_truth_jumps(rec, track_width)[:, 0]
        jumped = ~gap & np.isin(t[:-1], starts)
    bad = gap | jumped
    edges = np.flatnonzero(np.diff(np.concatenate([[1], bad.astype(np.int8), [1]])))
    pieces = []
    for a, b in zip(edges[::2], edges[1::2]):
        # Good intervals a..b-1: samples a..b.
        if b - a < 1:
            continue
        ts = t[a:b + 1]
        lo, hi = np.searchsorted(rec.enc_t, [ts[0], ts[-1]])
        grid = np.union1d(rec.enc_t[lo:hi], ts)
        pieces.append(Piece(index, ts, truth[a:b + 1].copy(),
                            grid, np.interp(grid, rec.enc_t, rec.left),
                            np.interp(grid, rec.enc_t, rec.right),
                            np.searchsorted(grid, ts)))
    return Cut(pieces, int(np.count_nonzero(gap)), int(np.count_nonzero(jumped)),
               float(sum(p.duration for p in pieces)))


def mean_track_speeds(piece: Piece, i, j) -> np.ndarray:
    """Mean of ``(|V_l| + |V_r|) / 2`` (m/s) over windows from sample ``i`` to ``j`` of a piece."""
    i, j = np.asarray(i, dtype=np.intp), np.asarray(j, dtype=np.intp)
    d_left, d_right, _ = piece.steps
    moved = np.concatenate([[0.0], np.cumsum(0.5 * (np.abs(d_left) + np.abs(d_right)))])
    return (moved[piece.at[j]] - moved[piece.at[i]]) / (piece.t[j] - piece.t[i])


def moving_windows(piece: Piece, length: float, min_speed: float | None):
    """Windows ``(i, j)`` of ``length`` s moving at >= ``min_speed`` m/s, and the total."""
    i, j = window_pairs(piece.t, length)
    total = len(i)
    if min_speed is not None and total:
        keep = mean_track_speeds(piece, i, j) >= min_speed
        i, j = i[keep], j[keep]
    return i, j, total


def icr_increments(d_left, d_right, y_left, y_right, x, scale_left=1.0, scale_right=1.0):
    """
    Body increments ``dx, dy, dtheta`` (m, m, rad) over steps of nominal travel, constant ICRs.

    Martinez et al. (2005) eqs. (7)-(9) in the ROS frame with the scales of eqs. (20)-(21); every
    argument broadcasts.
    """
    v_left = scale_left * np.asarray(d_left, dtype=float)
    v_right = scale_right * np.asarray(d_right, dtype=float)
    span = np.asarray(y_left, dtype=float) - y_right
    dtheta = (v_right - v_left) / span
    return (v_right * y_left - v_left * y_right) / span, -x * dtheta, dtheta


def odometry(piece: Piece, params) -> np.ndarray:
    """
    Dead-reckon a piece from its first ground-truth pose; ``(x, y, yaw)`` (M, 3) at ``piece.t``.

    ``params`` are ``(y_left, y_right, x, scale_left, scale_right)``, scalars or per grid step.
    """
    d_left, d_right, _ = piece.steps
    dx, dy, dth = icr_increments(d_left, d_right, *params)
    x, y, yaw = integrate(dx, dy, dth, pose0=tuple(piece.truth[0]))
    path = np.column_stack([np.concatenate([[piece.truth[0, 0]], x]),
                            np.concatenate([[piece.truth[0, 1]], y]),
                            np.concatenate([[piece.truth[0, 2]], yaw])])
    return path[piece.at]


def track_path(piece: Piece, t, poses, times=None) -> np.ndarray:
    """
    Return a path computed over a whole recording along a piece, from its first ground truth.

    ``poses`` (N, 3) at times ``t`` (N,; they include the piece's grid) are taken at
    ``times`` (default ``piece.t``; ``piece.grid``: at every step boundary) and moved rigidly
    so that the first is the piece's first ground-truth pose, as :func:`odometry` starts;
    ``(x, y, yaw)``, one row per time.
    """
    times = piece.t if times is None else times
    k = np.clip(np.searchsorted(t, times), 0, len(t) - 1)
    p = np.asarray(poses, float)[k]
    d = p[:, 2] - p[0, 2]
    c, s = np.cos(p[0, 2]), np.sin(p[0, 2])
    ex, ey = p[:, 0] - p[0, 0], p[:, 1] - p[0, 1]
    lx, ly = c * ex + s * ey, -s * ex + c * ey
    x0, y0, h0 = piece.truth[0]
    c0, s0 = np.cos(h0), np.sin(h0)
    return np.column_stack([x0 + c0 * lx - s0 * ly, y0 + s0 * lx + c0 * ly, h0 + d])
