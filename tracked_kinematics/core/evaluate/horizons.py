"""
Predictions over horizons, all horizons at once: from the encoders, and from the commands.

From the measured pose at each horizon's start, a model predicts ``horizon`` s (EKF paper eq. 14;
DRIVE, Baril et al. 2024) from the measured travel, or from the commands through the drive train
(Fink & Stump sec. III-B); errors as :func:`.metrics.relative_errors`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from .metrics import horizon_members, horizon_scores
from .pieces import icr_increments, Piece
from ..drivetrain import DriveTrain
from ..integration import arc_chord, wrap_angle


@dataclass(frozen=True)
class Commands:
    """Commanded nominal track speeds ``values`` (N, 2; m/s) at times ``t`` (s), each held."""

    t: np.ndarray
    values: np.ndarray
    source: str = 'setpoints'

    def held(self, times, max_age: float):
        """Return the commands in force at ``times`` and whether each is <= ``max_age`` s old."""
        times = np.asarray(times, dtype=float)
        k = np.searchsorted(self.t, times + 1e-9, side='right') - 1
        fresh = (k >= 0) & (times - self.t[np.maximum(k, 0)] <= max_age)
        return self.values[np.maximum(k, 0)], fresh


@dataclass(frozen=True)
class HorizonErrors:
    """A prediction's errors per horizon from ``t0``: RMS over it and at its end, m and rad."""

    t0: np.ndarray
    rms_translation: np.ndarray
    rms_rotation: np.ndarray
    final_translation: np.ndarray
    final_rotation: np.ndarray

    @classmethod
    def concatenate(cls, parts) -> HorizonErrors:
        """Join the horizons of several pieces."""
        parts = list(parts)
        if not parts:
            empty = np.zeros(0)
            return cls(empty, empty, empty, empty, empty)
        return cls(*(np.concatenate([getattr(p, name) for p in parts]) for name in (
            't0', 'rms_translation', 'rms_rotation', 'final_translation', 'final_rotation')))

    def __len__(self):
        return len(self.t0)


def _motion_since(poses, i, k):
    """Displacement of samples ``k`` in the frame of samples ``i``, and heading change."""
    c, s = np.cos(poses[i, 2]), np.sin(poses[i, 2])
    ex, ey = poses[k, 0] - poses[i, 0], poses[k, 1] - poses[i, 1]
    return c * ex + s * ey, -s * ex + c * ey, poses[k, 2] - poses[i, 2]


def _errors(piece, starts, owner, member, px, py, pth) -> HorizonErrors:
    """Score predicted motions since each start against the ground truth's."""
    qx, qy, qth = _motion_since(piece.truth, starts[owner], member)
    translation = np.hypot(px - qx, py - qy)
    rotation = np.abs(wrap_angle(pth - qth))
    return HorizonErrors(piece.t[starts],
                         *horizon_scores(owner, len(starts), translation, rotation))


def _segment_integrate(dx, dy, dth, first):
    """Integrate body increments along arcs, restarting at the origin at every ``first`` step."""
    segment = np.cumsum(first) - 1
    heading = np.cumsum(dth)
    base = (heading - dth)[first]
    heading = heading - base[segment]
    before = heading - dth
    cx, cy = arc_chord(dx, dy, dth)
    wx = np.cos(before) * cx - np.sin(before) * cy
    wy = np.sin(before) * cx + np.cos(before) * cy
    x, y = np.cumsum(wx), np.cumsum(wy)
    x = x - (x - wx)[first][segment]
    y = y - (y - wy)[first][segment]
    return x, y, heading


def encoder_horizons(piece: Piece, horizon: float, params_at) -> HorizonErrors:
    """
    Errors of predictions from the measured travel over every ``horizon`` (s) of a piece.

    ``params_at(times)`` gives ``(y_left, y_right, x, scale_left, scale_right)`` at the starts.
    """
    starts, owner, member = horizon_members(piece.t, horizon)
    if len(starts) == 0:
        return HorizonErrors.concatenate([])
    ends = member[np.cumsum(np.bincount(owner, minlength=len(starts))) - 1]
    a, b = piece.at[starts], piece.at[ends]
    lengths = b - a
    step_owner = np.repeat(np.arange(len(starts)), lengths)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp)
    step = a[step_owner] + np.arange(int(lengths.sum())) - offsets[step_owner]
    d_left, d_right, _ = piece.steps
    params = [np.broadcast_to(np.asarray(v, float), (len(starts),))[step_owner]
              for v in params_at(piece.t[starts])]
    dx, dy, dth = icr_increments(d_left[step], d_right[step], *params)
    first = np.zeros(len(step), bool)
    first[offsets] = True
    x, y, th = _segment_integrate(dx, dy, dth, first)
    # Member k of horizon h is the pose after step at[k] - 1, i.e. offset at[k] - a - 1.
    where = offsets[owner] + piece.at[member] - a[owner] - 1
    return _errors(piece, starts, owner, member, x[where], y[where], th[where])


def _integrate_columns(dx, dy, dth):
    """Integrate increments of shape (N, C) along axis 0 from the origin; (N + 1, C) poses."""
    heading = np.cumsum(dth, axis=0)
    before = heading - dth
    cx, cy = arc_chord(dx, dy, dth)
    x = np.cumsum(np.cos(before) * cx - np.sin(before) * cy, axis=0)
    y = np.cumsum(np.sin(before) * cx + np.cos(before) * cy, axis=0)
    zero = np.zeros((1,) + dth.shape[1:])
    return (np.concatenate([zero, x]), np.concatenate([zero, y]),
            np.concatenate([zero, heading]))


def start_speeds(piece: Piece, starts):
    """Measured nominal track speeds at sample ``starts``: the grid step ending there, m/s."""
    d_left, d_right, dt = piece.steps
    step = np.clip(piece.at[starts] - 1, 0, len(dt) - 1)
    return np.column_stack([d_left[step] / dt[step], d_right[step] / dt[step]])


def command_horizons(piece: Piece, horizon: float, commands: Commands, params_at,
                     drivetrain: DriveTrain | None, dt: float = 0.05,
                     max_age: float = 0.5, chunk: int = 2000) -> HorizonErrors:
    """
    Errors of predictions from the commands over the horizons of a piece that have them.

    Through ``drivetrain`` from the measured track speeds at the start (None: the commands are the
    speeds, the naive prediction), on steps of ``dt`` s; horizons needing a command older than
    ``max_age`` s are skipped; ``chunk`` horizons are simulated at once.
    """
    starts, owner, member = horizon_members(piece.t, horizon)
    if len(starts) == 0:
        return HorizonErrors.concatenate([])
    steps = int(math.ceil(horizon / dt - 1e-9))
    lag = 0 if drivetrain is None else int(math.ceil(drivetrain.delay / dt - 1e-9))
    offsets = np.arange(steps) - lag
    held, fresh = commands.held(piece.t[starts][:, None] + offsets[None, :] * dt, max_age)
    ok = fresh.all(axis=1)
    if not ok.any():
        return HorizonErrors.concatenate([])
    keep = np.flatnonzero(ok)
    remap = np.full(len(starts), -1)
    remap[keep] = np.arange(len(keep))
    mine = remap[owner] >= 0
    starts, owner, member = starts[keep], remap[owner[mine]], member[mine]
    held = held[keep]                                            # (H, steps, 2)
    params = [np.broadcast_to(np.asarray(v, float), (len(starts),))
              for v in params_at(piece.t[starts])]
    speeds0 = start_speeds(piece, starts)
    px = np.empty(len(member))
    py = np.empty(len(member))
    pth = np.empty(len(member))
    tau = piece.t[member] - piece.t[starts[owner]]
    for lo in range(0, len(starts), chunk):
        hi = min(lo + chunk, len(starts))
        demand = np.swapaxes(held[lo:hi], 0, 1)                  # (steps, C, 2)
        if drivetrain is None:
            speeds = demand
        else:
            # The delay is in the commands sampled (``lag`` steps back); the rest of the
            # drive train starts in steady state at the measured speeds.
            shaped = replace(drivetrain, delay=0.0).simulate(
                demand.reshape(steps, -1), dt, initial=speeds0[lo:hi].reshape(-1))
            speeds = shaped.reshape(demand.shape)
        column = [p[lo:hi][None, :] for p in params]
        dx, dy, dth = icr_increments(speeds[..., 0] * dt, speeds[..., 1] * dt, *column)
        x, y, th = _integrate_columns(dx, dy, dth)
        rows = (owner >= lo) & (owner < hi)
        pos = np.clip(tau[rows] / dt, 0.0, steps)
        n0 = np.minimum(np.floor(pos).astype(np.intp), steps - 1)
        frac = pos - n0
        col = owner[rows] - lo
        for out, path in ((px, x), (py, y), (pth, th)):
            out[rows] = (1.0 - frac) * path[n0, col] + frac * path[n0 + 1, col]
    return _errors(piece, starts, owner, member, px, py, pth)
