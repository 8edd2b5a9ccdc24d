"""
Drive-train data: commanded and measured track speeds, put on one grid (Fink & Stump sec. IV-A).

The drive-train fit (:mod:`.drivetrain_fit`) compares the simulated response to the commands with
the measured speeds sample by sample, so both series are first resampled onto a common grid
of period ``dt``: the commands as held setpoints (the one in force at each grid time), the
measured speeds linearly. Gaps longer than ``max_gap`` in either stream cut the data into
segments.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..errors import ExcitationError, TrackedKinematicsError
from ..recording import Recording


@dataclass(frozen=True)
class Segment:
    """
    A stretch of data without gaps on the common grid.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Grid times, s.
    commands, speeds : ndarray, shape (N, 2)
        Held commands and interpolated measured speeds at the grid times, m/s.
    name : str
        Recording it belongs to.

    """

    t: np.ndarray
    commands: np.ndarray
    speeds: np.ndarray
    name: str = 'data'


def _series(t, values, what: str, name: str):
    """Sort and clean one time series: finite rows, increasing unique times."""
    ok = np.isfinite(t) & np.all(np.isfinite(values), axis=1)
    t, values = t[ok], values[ok]
    order = np.argsort(t, kind='stable')
    t, values = t[order], values[order]
    keep = np.concatenate([[True], np.diff(t) > 0]) if len(t) else np.zeros(0, bool)
    t, values = t[keep], values[keep]
    if len(t) < 2:
        raise ExcitationError(f'{name}: fewer than two finite {what} samples')
    return t, values


def resample(data: Recording, dt: float, max_gap: float) -> list[Segment]:
    """
    Put commands and measured speeds on one grid, cut at gaps.

    Parameters
    ----------
    data : Recording
        One recording with track setpoints (``commands``).
    dt : float
        Grid period, s.
    max_gap : float
        Longest gap bridged, s: between measured samples, and since the last setpoint.

    Returns
    -------
    list of Segment
        Stretches of at least two samples (possibly none).

    Raises
    ------
    ValueError
        For malformed series (the message names the recording).
    TrackedKinematicsError
        For series that do not overlap in time (the message names the recording).
    ExcitationError
        When a series has fewer than two finite samples.

    """
    name = data.name or 'data'
    if data.command_t is None:
        raise ValueError(f'{name}: no track setpoints (commands)')
    t_c, cmd = _series(data.command_t, data.commands, 'command', name)
    t_m, meas = _series(*data.track_speeds(), 'speed', name)
    start, end = max(t_c[0], t_m[0]), t_m[-1]
    if end <= start:
        raise TrackedKinematicsError(
            f'{name}: the commands ({t_c[0]:.2f}-{t_c[-1]:.2f} s) and the measured '
            f'speeds ({t_m[0]:.2f}-{t_m[-1]:.2f} s) do not overlap in time')
    grid = start + dt * np.arange(int(math.floor((end - start) / dt + 1e-9)) + 1)
    held = np.searchsorted(t_c, grid + 1e-9 * dt, side='right') - 1
    after = np.clip(np.searchsorted(t_m, grid, side='left'), 1, len(t_m) - 1)
    valid = ((grid - t_c[held]) <= max_gap) & ((t_m[after] - t_m[after - 1]) <= max_gap)
    commands = cmd[held]
    speeds = np.column_stack([np.interp(grid, t_m, meas[:, j]) for j in range(2)])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(np.int8), [0]])))
    return [Segment(grid[a:b], commands[a:b], speeds[a:b], name)
            for a, b in zip(edges[::2], edges[1::2]) if b - a >= 2]
