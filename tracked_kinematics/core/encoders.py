"""
From encoder readings to nominal track travel, for the three input kinds drivers publish.

- joint positions (rad, cumulative): exact travel ``radius * delta angle``;
- joint or track velocities: travel by the trapezoidal rule between samples;
- tick counters (integers that wrap around at 2^bits): unwrapped increments.

Everything is vectorised over samples (for logs); :class:`IncrementTracker` is the same
arithmetic one sample at a time, with the checks a live stream needs (for nodes).
Travel is *nominal* (encoder) travel: the scale corrections of the kinematic model turn it
into true travel (Martinez eqs. 18-21).
"""

from __future__ import annotations

import math

import numpy as np


def mean_over_joints(values) -> np.ndarray:
    """
    Average the joints of one side (several sprockets or wheels per track).

    Parameters
    ----------
    values : array_like, shape (N, J) or (N,)
        One column per joint of the side.

    Returns
    -------
    ndarray, shape (N,)

    """
    values = np.asarray(values, dtype=float)
    return values if values.ndim == 1 else values.mean(axis=-1)


def travel_from_positions(positions, radius: float) -> np.ndarray:
    """
    Nominal track travel between consecutive joint positions.

    Parameters
    ----------
    positions : array_like, shape (N,)
        Cumulative sprocket angle, rad.
    radius : float
        Sprocket radius, m.

    Returns
    -------
    ndarray, shape (N - 1,)
        Travel over each interval, m.

    """
    return np.diff(np.asarray(positions, dtype=float)) * radius


def travel_from_velocities(velocities, stamps, scale: float = 1.0) -> np.ndarray:
    """
    Nominal track travel from sampled speeds, by the trapezoidal rule.

    Parameters
    ----------
    velocities : array_like, shape (N,)
        Joint angular velocities (rad/s, with ``scale`` = sprocket radius) or track speeds
        (m/s, with ``scale`` = 1).
    stamps : array_like, shape (N,)
        Sample times, s.
    scale : float
        Factor from the velocity unit to m/s.

    Returns
    -------
    ndarray, shape (N - 1,)
        Travel over each interval, m.

    """
    velocities = np.asarray(velocities, dtype=float)
    dt = np.diff(np.asarray(stamps, dtype=float))
    return 0.5 * (velocities[1:] + velocities[:-1]) * dt * scale


def counter_increments(counts, bits: int) -> np.ndarray:
    """
    Increments of a wrapping tick counter.

    The counter is taken to be a ``bits``-bit integer (signed or unsigned, the increments
    are the same) that wraps around; any increment is read as the smallest in magnitude,
    so a counter must be sampled at least twice per half range.

    Parameters
    ----------
    counts : array_like of int, shape (N,)
        Raw counter values.
    bits : int
        Counter width (32 for std_msgs/Int32, 64 for Int64).

    Returns
    -------
    ndarray of int64, shape (N - 1,)

    """
    counts = np.asarray(counts)
    if bits >= 64:
        # Wrapping int64 arithmetic gives the modular difference directly.
        with np.errstate(over='ignore'):
            return np.diff(counts.astype(np.int64))
    modulus = 1 << bits
    half = 1 << (bits - 1)
    diff = np.diff(counts.astype(np.int64))
    return (diff + half) % modulus - half


def travel_from_ticks(tick_increments, ticks_per_revolution: float, radius: float) -> np.ndarray:
    """
    Nominal track travel of tick increments: ``ticks / ticks_per_rev * 2 pi * radius``.

    Parameters
    ----------
    tick_increments : array_like
        Counter increments (:func:`counter_increments`).
    ticks_per_revolution : float
        Ticks per sprocket revolution (after any gearing).
    radius : float
        Sprocket radius, m.

    Returns
    -------
    ndarray
        Travel, m.

    """
    return np.asarray(tick_increments, dtype=float) * (2.0 * np.pi * radius
                                                       / ticks_per_revolution)


class Status:
    """What :meth:`IncrementTracker.update` did with a sample."""

    STEP = 'step'              # a step of travel was produced
    FIRST = 'first'            # first sample: it became the baseline
    KIND_CHANGED = 'kind'      # positions <-> velocities: restarted from this sample
    NON_FINITE = 'non_finite'  # NaN or inf: skipped, the baseline kept
    TIME_BACK = 'time_back'    # stamp not after the baseline's: restarted from this sample
    GAP = 'gap'                # longer than max_dt since the baseline: restarted, gap skipped


class IncrementTracker:
    """
    Turn a live stream of encoder samples into steps of nominal track travel.

    The per-sample form of :func:`travel_from_positions`, :func:`travel_from_velocities`
    and :func:`counter_increments` / :func:`travel_from_ticks`, plus the checks a live
    stream needs. Written with Python numbers because a node calls it once per message.

    - A sample with a non-finite value is skipped and the baseline kept, so that cumulative
      positions still give the exact travel across it.
    - A stamp not after the baseline's (a sim-time reset, a bag loop, a duplicate) or a gap
      longer than ``max_dt`` restarts from the new sample without producing a step: the
      travel over the gap is unknown or meaningless, and the odometry keeps its pose.
    - Switching between positions and velocities restarts the same way.

    Parameters
    ----------
    max_dt : float
        Longest step integrated, s.

    """

    def __init__(self, max_dt: float = 0.5):
        self.max_dt = float(max_dt)
        self.reset()

    def reset(self) -> None:
        """Forget the baseline: the next sample starts afresh."""
        self._last = None

    def update(self, stamp_ns: int, kind: str, left, right, factor: float, bits: int = 64):
        """
        Take one sample of both tracks.

        Parameters
        ----------
        stamp_ns : int
            Sample time, ns (integers, so differences of large stamps stay exact).
        kind : str
            ``'position'`` (cumulative angle or distance; travel = difference x ``factor``),
            ``'velocity'`` (travel = trapezoidal rule x ``factor``) or ``'ticks'`` (integer
            counters of ``bits`` bits that wrap; travel = increment x ``factor``).
        left, right : float or int
            The two tracks' readings (averaged over the joints of each side).
        factor : float
            Metres per unit of the reading (sprocket radius for rad and rad/s, 1 for m/s,
            ``2 pi r / ticks_per_revolution`` for ticks).
        bits : int
            Counter width for ``'ticks'``.

        Returns
        -------
        status : str
            One of :class:`Status`.
        d_left, d_right : float
            Nominal travel over the step, m (0 unless the status is ``Status.STEP``).
        dt : float
            The step's duration, s; for ``TIME_BACK`` and ``GAP`` the offending interval.

        """
        if kind != 'ticks' and not (math.isfinite(left) and math.isfinite(right)):
            return Status.NON_FINITE, 0.0, 0.0, 0.0
        last = self._last
        self._last = (stamp_ns, kind, left, right)
        if last is None:
            return Status.FIRST, 0.0, 0.0, 0.0
        last_ns, last_kind, last_left, last_right = last
        dt = (stamp_ns - last_ns) * 1e-9
        if last_kind != kind:
            return Status.KIND_CHANGED, 0.0, 0.0, dt
        if dt <= 0.0:
            return Status.TIME_BACK, 0.0, 0.0, dt
        if dt > self.max_dt:
            return Status.GAP, 0.0, 0.0, dt
        if kind == 'position':
            return Status.STEP, (left - last_left) * factor, (right - last_right) * factor, dt
        if kind == 'velocity':
            half = 0.5 * dt * factor
            return Status.STEP, (left + last_left) * half, (right + last_right) * half, dt
        modulus = 1 << bits
        half_range = 1 << (bits - 1)
        ticks_left = (left - last_left + half_range) % modulus - half_range
        ticks_right = (right - last_right + half_range) % modulus - half_range
        return Status.STEP, ticks_left * factor, ticks_right * factor, dt
