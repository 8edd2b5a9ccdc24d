"""
From encoder readings to nominal track travel, for the input kinds drivers publish.

Joint positions (rad, cumulative or wrapped into [-pi, pi]), joint or track velocities (trapezoidal
rule) and wrapping tick counters; vectorised for logs, and one sample at a time with a live
stream's checks (:class:`IncrementTracker`). The encoder scales (Martinez eqs. 18-21) turn nominal
into true travel.
"""

from __future__ import annotations

import math

import numpy as np


def mean_over_joints(values) -> np.ndarray:
    """Average the joints of one side, (N, J) -> (N,) (several sprockets or wheels per track)."""
    values = np.asarray(values, dtype=float)
    return values if values.ndim == 1 else values.mean(axis=-1)


def travel_from_positions(positions, radius: float) -> np.ndarray:
    """Nominal travel (m, N - 1) between cumulative sprocket angles (rad) of a ``radius`` (m)."""
    return np.diff(np.asarray(positions, dtype=float)) * radius


def travel_from_velocities(velocities, stamps, scale: float = 1.0) -> np.ndarray:
    """
    Nominal travel (m, N - 1) from sampled speeds at ``stamps`` (s), by the trapezoidal rule.

    ``scale`` converts the velocity unit to m/s: the sprocket radius for rad/s, 1 for m/s.
    """
    velocities = np.asarray(velocities, dtype=float)
    dt = np.diff(np.asarray(stamps, dtype=float))
    return 0.5 * (velocities[1:] + velocities[:-1]) * dt * scale


def counter_increments(counts, bits: int) -> np.ndarray:
    """
    Increments (int64, N - 1) of a wrapping ``bits``-bit tick counter, the smallest in magnitude.

    A counter must therefore be sampled at least twice per half range.
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
    """Nominal travel (m) of tick increments: ``ticks / ticks_per_rev * 2 pi * radius``."""
    return np.asarray(tick_increments, dtype=float) * (2.0 * np.pi * radius
                                                       / ticks_per_revolution)


# Joint angles a driver reports wrapped into [-pi, pi] (a continuous joint) are recognised by
# staying within this bound; cumulative ones leave it as soon as the joint turns half a turn.
WRAP_LIMIT = math.pi + 1e-6
# A jump of a wrapped angle across +-pi is "about 2 pi": larger than this in magnitude. A
# step between pi and this is a fast wheel (a small sprocket at a low encoder rate turns more
# than half a turn per sample), not a wrap; diff_drive_controller integrates it as it is.
WRAP_JUMP = 1.5 * math.pi


def unwrap_increments(increments):
    """Read angle increments (rad) beyond :data:`WRAP_JUMP` as crossing +-pi; keep the rest."""
    delta = np.asarray(increments, dtype=float)
    out = np.where(np.abs(delta) > WRAP_JUMP,
                   np.remainder(delta + np.pi, 2.0 * np.pi) - np.pi, delta)
    return float(out) if out.ndim == 0 else out


def unwrap_if_wrapped(positions) -> np.ndarray:
    """
    Unwrap joint angles (rad) that a driver reports wrapped into [-pi, pi] (continuous joints).

    A series within [-pi, pi] that jumps by more than :data:`WRAP_JUMP` is wrapped and is
    unwrapped; any other is returned as it is. The one rule of logs and :class:`IncrementTracker`.
    """
    if len(positions) < 2 or np.max(np.abs(positions)) > WRAP_LIMIT:
        return positions
    steps = np.diff(positions)
    if not np.any(np.abs(steps) > WRAP_JUMP):
        return positions
    return positions[0] + np.concatenate([[0.0], np.cumsum(unwrap_increments(steps))])


# Timing jitter allowed by the plausibility gate, s: a step may travel up to
# max_plausible_speed x (dt + this), so that messages timed on arrival (track_speeds,
# encoder_ticks), which may come in bursts, are not refused for it.
PLAUSIBILITY_SLACK = 0.02


class Status:
    """What :meth:`IncrementTracker.update` did with a sample."""

    STEP = 'step'              # a step of travel was produced
    LONG_STEP = 'long_step'    # a step over a gap longer than max_dt (positions, ticks: exact)
    RESUMED = 'resumed'        # a step from the sample after an implausible one (a restart)
    FIRST = 'first'            # first sample: it became the baseline
    KIND_CHANGED = 'kind'      # positions <-> velocities: restarted from this sample
    NON_FINITE = 'non_finite'  # NaN or inf: skipped, the baseline kept
    TIME_BACK = 'time_back'    # stamp not after the baseline's: restarted from this sample
    DUPLICATE = 'duplicate'    # the baseline again (same stamp and readings): ignored
    GAP = 'gap'                # velocities, longer than max_dt: restarted, gap not bridged
    IMPLAUSIBLE = 'implausible'  # faster than max_plausible_speed: skipped, baseline kept

    # The statuses that produce a step of travel.
    STEPS = frozenset((STEP, LONG_STEP, RESUMED))


class IncrementTracker:
    """
    Turn a live stream of encoder samples into steps of nominal track travel.

    The per-sample form of the functions above, on Python numbers, with a live stream's checks:
    non-finite samples skipped, velocity gaps beyond ``max_dt`` (s) restarted, steps faster than
    ``max_speed`` (m/s) refused by the plausibility gate, stamps that go back restarted. See
    docs/nodes/odometry_node.md, "The plausibility gate".
    """

    def __init__(self, max_dt: float = 0.5, max_speed: float = 10.0):
        self.max_dt = float(max_dt)
        self.max_speed = float(max_speed)
        self.reset()

    def reset(self) -> None:
        """Forget the baseline: the next sample starts afresh."""
        self._last = None
        self._skipped = None
        self._wrapped = [True, True]

    def _travel(self, kind, left, right, base, factor, bits):
        """Nominal travel of both tracks from the sample ``base`` to this one."""
        base_left, base_right = base[2], base[3]
        if kind == 'position':
            d_left = left - base_left
            d_right = right - base_right
            wrapped = self._wrapped
            if wrapped[0] and abs(d_left) > WRAP_JUMP:
                d_left = unwrap_increments(d_left)
            if wrapped[1] and abs(d_right) > WRAP_JUMP:
                d_right = unwrap_increments(d_right)
            return d_left * factor, d_right * factor
        modulus = 1 << bits
        half_range = 1 << (bits - 1)
        return (((left - base_left + half_range) % modulus - half_range) * factor,
                ((right - base_right + half_range) % modulus - half_range) * factor)

    def _plausible(self, d_left, d_right, dt) -> bool:
        allowed = self.max_speed * (dt + PLAUSIBILITY_SLACK)
        # Also False for NaN and inf (a difference of huge readings overflows).
        return abs(d_left) <= allowed and abs(d_right) <= allowed

    def update(self, stamp_ns: int, kind: str, left, right, factor: float, bits: int = 64):
        """
        Take one sample of both tracks; return ``(status, d_left, d_right, dt)``.

        Parameters
        ----------
        stamp_ns : int
            Sample time, ns.
        kind : str
            ``'position'``, ``'velocity'`` (trapezoidal) or ``'ticks'`` (``bits``-bit counters).
        left, right : float or int
            The two tracks' readings (averaged over the joints of each side).
        bits : int
            Counter width for ``'ticks'``.
        factor : float
            Metres per unit of the reading (sprocket radius for rad and rad/s, 1 for m/s,
            ``2 pi r / ticks_per_revolution`` for ticks).

        Returns
        -------
        status : str
            One of :class:`Status`; ``Status.STEPS`` produce a step.
        d_left, d_right, dt : float
            Nominal travel (m) over the step and its duration (s); for a refused step what was
            refused (velocities: the speeds), else 0.

        """
        if kind != 'ticks' and not (math.isfinite(left) and math.isfinite(right)):
            return Status.NON_FINITE, 0.0, 0.0, 0.0
        if kind == 'position':
            wrapped = self._wrapped
            if wrapped[0] and abs(left) > WRAP_LIMIT:
                wrapped[0] = False
            if wrapped[1] and abs(right) > WRAP_LIMIT:
                wrapped[1] = False
        elif kind == 'velocity':
            max_speed = self.max_speed
            if abs(left * factor) > max_speed or abs(right * factor) > max_speed:
                dt = 0.0 if self._last is None else (stamp_ns - self._last[0]) * 1e-9
                return Status.IMPLAUSIBLE, left * factor, right * factor, dt
        sample = (stamp_ns, kind, left, right)
        last = self._last
        if last is None:
            self._last = sample
            return Status.FIRST, 0.0, 0.0, 0.0
        dt = (stamp_ns - last[0]) * 1e-9
        if last[1] != kind:
            self._last, self._skipped = sample, None
            return Status.KIND_CHANGED, 0.0, 0.0, dt
        if dt <= 0.0:
            if dt == 0.0 and left == last[2] and right == last[3]:
                return Status.DUPLICATE, 0.0, 0.0, 0.0
            self._last, self._skipped = sample, None
            return Status.TIME_BACK, 0.0, 0.0, dt
        if kind == 'velocity':
            self._last = sample
            if dt > self.max_dt:
                return Status.GAP, 0.0, 0.0, dt
            half = 0.5 * dt * factor
            return Status.STEP, (left + last[2]) * half, (right + last[3]) * half, dt
        d_left, d_right = self._travel(kind, left, right, last, factor, bits)
        if self._plausible(d_left, d_right, dt):
            self._last, self._skipped = sample, None
            return (Status.STEP if dt <= self.max_dt else Status.LONG_STEP), d_left, d_right, dt
        skipped = self._skipped
        if skipped is not None and stamp_ns > skipped[0]:
            resumed_dt = (stamp_ns - skipped[0]) * 1e-9
            r_left, r_right = self._travel(kind, left, right, skipped, factor, bits)
            if self._plausible(r_left, r_right, resumed_dt):
                self._last, self._skipped = sample, None
                return Status.RESUMED, r_left, r_right, resumed_dt
        self._skipped = sample
        return Status.IMPLAUSIBLE, d_left, d_right, dt
