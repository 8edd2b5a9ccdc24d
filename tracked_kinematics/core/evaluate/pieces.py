"""
Gap-free pieces of a recording, and odometry along them.

Every score of :mod:`.metrics` compares an odometry path with the ground truth between two
ground-truth samples of one *piece*: a stretch where both streams run without a gap
(:func:`~tracked_kinematics.core.identify.gap_threshold` of each: five median intervals, at
least 0.2 s) and the ground truth does not jump. Jumps are identify_icr's
(:func:`~tracked_kinematics.core.identify.segments.ground_truth_jumps`): a step longer than
0.5 m plus the travel of the faster track over it (the count of
../shared/realdata/README.md: a re-localising mapper, or one that falls behind and catches
up), or a heading step 0.5 rad beyond the ideal drive's turn (a glitch). Nothing is scored
across a gap or a jump; the odometry of a piece starts at its first ground-truth pose.

Odometry integrates the encoder travel with constant tread ICRs (Martinez et al. 2005,
eqs. 7-9, with the scales of eqs. 20-21) along exact arcs
(:func:`~tracked_kinematics.core.integration.integrate`), on a grid of the encoder times
and the ground-truth times (linear interpolation of the travel in between, as
identify_icr), with parameters that may change from step to step (the online estimator's).
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
    recording : int
        Index of the recording it comes from.
    t : ndarray, shape (M,)
        Ground-truth times, s.
    truth : ndarray, shape (M, 3)
        Ground-truth ``(x, y, yaw)``: m, m, rad (yaw unwrapped).
    grid : ndarray, shape (K,)
        Step boundaries: the encoder times and the ground-truth times of the piece, s.
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
    """
    How a recording was cut into pieces.

    Attributes
    ----------
    pieces : list of Piece
    gaps : int
        Ground-truth intervals left out for a gap in either stream.
    jumps : int
        Ground-truth steps left out as jumps.
    seconds : float
        Time covered by the pieces, s.

    """

    pieces: list
    gaps: int
    jumps: int
    seconds: float


def cut(recording: Recording, index: int = 0, jumps: bool = True,
        track_width: float | None = None) -> Cut:
    """
    Cut a recording into gap-free, jump-free pieces of at least two ground-truth samples.

    Parameters
    ----------
    recording : Recording
        Encoders and ground truth on one clock (the ground-truth delay already taken off).
    index : int
        Its index, stored in the pieces.
    jumps : bool
        Cut at ground-truth jumps too (False: score across them).
    track_width : float, optional
        m, for the heading glitches of the jumps (without it, position jumps only).

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
    """
    Mean track speed over windows of a piece: the nominal track travel, m/s.

    The mean over the window from sample ``i`` to sample ``j`` of ``(|V_l| + |V_r|) / 2``:
    half the summed absolute travel of both tracks over the grid steps of the window, divided
    by its duration (a turn on the spot moves; a standstill does not).

    Parameters
    ----------
    piece : Piece
        The piece.
    i, j : ndarray of int
        First and last ground-truth sample of each window (``j > i``).

    Returns
    -------
    ndarray
        m/s, one per window.

    """
    i, j = np.asarray(i, dtype=np.intp), np.asarray(j, dtype=np.intp)
    d_left, d_right, _ = piece.steps
    moved = np.concatenate([[0.0], np.cumsum(0.5 * (np.abs(d_left) + np.abs(d_right)))])
    return (moved[piece.at[j]] - moved[piece.at[i]]) / (piece.t[j] - piece.t[i])


def moving_windows(piece: Piece, length: float, min_speed: float | None):
    """
    Windows of ``length`` s of a piece (:func:`.metrics.window_pairs`) in which it moves.

    Parameters
    ----------
    piece : Piece
        The piece.
    length : float
        Window length, s.
    min_speed : float or None
        Keep the windows whose :func:`mean_track_speeds` is at least this, m/s; None: every
        window.

    Returns
    -------
    i, j : ndarray of int
        The windows kept.
    total : int
        Windows of that length before the selection.

    """
    i, j = window_pairs(piece.t, length)
    total = len(i)
    if min_speed is not None and total:
        keep = mean_track_speeds(piece, i, j) >= min_speed
        i, j = i[keep], j[keep]
    return i, j, total


def icr_increments(d_left, d_right, y_left, y_right, x, scale_left=1.0, scale_right=1.0):
    """
    Body increments over steps of nominal track travel, constant tread ICRs per step.

    Martinez et al. (2005) eqs. (7)-(9) in the ROS frame (docs/model.md), with the encoder
    scales of eqs. (20)-(21); every argument broadcasts (per-step or per-column parameters).

    Returns
    -------
    dx, dy, dtheta : ndarray
        Body-frame increments: m, m, rad.

    """
    v_left = scale_left * np.asarray(d_left, dtype=float)
    v_right = scale_right * np.asarray(d_right, dtype=float)
    span = np.asarray(y_left, dtype=float) - y_right
    dtheta = (v_right - v_left) / span
    return (v_right * y_left - v_left * y_right) / span, -x * dtheta, dtheta


def odometry(piece: Piece, params) -> np.ndarray:
    """
    Dead-reckon a piece from its first ground-truth pose; poses at its ground-truth times.

    Parameters
    ----------
    piece : Piece
        The piece.
    params : tuple
        ``(y_left, y_right, x, scale_left, scale_right)``, scalars or arrays over the grid
        steps (``len(piece.grid) - 1``).

    Returns
    -------
    ndarray, shape (M, 3)
        ``(x, y, yaw)`` at ``piece.t`` (yaw unwrapped).

    """
    d_left, d_right, _ = piece.steps
    dx, dy, dth = icr_increments(d_left, d_right, *params)
    x, y, yaw = integrate(dx, dy, dth, pose0=tuple(piece.truth[0]))
    path = np.column_stack([np.concatenate([[piece.truth[0, 0]], x]),
                            np.concatenate([[piece.truth[0, 1]], y]),
                            np.concatenate([[piece.truth[0, 2]], yaw])])
    return path[piece.at]
