"""
The gyro's samples on the encoders' clock: plausibility gates, stamp order, a bounded buffer.

The integral of the rate is kept relative to where it is used (:meth:`GyroSamples.integral`
sums the samples between two times), never as a growing cumulative sum: one implausible
sample that got through could otherwise leave a sum so large that later increments are
lost to rounding. Stamps going back by more than :func:`.config.time_limit` restart the
buffer (a bag played in a loop, a simulated clock reset), as the encoders restart; a smaller
step back is an out-of-order sample, dropped. A sample that would restart the buffer (far
back, or after a gap of more than ``timeout``) is held until the next one says which it is:
the next continuing from it confirms the restart; the next continuing the buffer shows it was
one wild stamp (a second publisher, a corrupt ``nanosec``), dropped, so that it neither
restarts the gyro nor shuts out the samples that follow it.
"""

from __future__ import annotations

from collections import deque
import math

from .gyro_config import GyroConfig, time_limit

#: Most samples kept (10 s at 400 Hz): the buffer is bounded whatever the clocks do.
MAX_SAMPLES = 4096

NON_FINITE = 'the gyro reads a non-finite value'
SATURATED = 'the gyro is saturated'
JUMP = 'the gyro jumps'
STALE = 'the gyro was stale'
BACK = 'the gyro stamps went back'
ORDER = ('a gyro stamp not after the last one (two publishers on the topic, a stamp that does '
         'not advance, or a wild one?)')


class GyroSamples:
    """
    Healthy gyro samples ``(t, w)``, ``t`` on the encoders' clock (stamp minus ``imu_delay``).

    Attributes
    ----------
    last_t : float
        Time of the newest healthy sample (-inf: none).
    healthy_since : float
        Time since which the samples are continuous and healthy (nan: not).
    fault : str
        Why the last sample was refused ('' when it was accepted).

    """

    def __init__(self, config: GyroConfig):
        self.config = config
        self._samples: deque = deque(maxlen=MAX_SAMPLES)
        self._last_w = math.nan
        self.last_t = -math.inf
        self.healthy_since = math.nan
        self.fault = ''
        self.refused = 0
        self.arrived = 0      # samples received, any
        self.dropped = 0      # samples dropped as out of order (or wild: see the module)
        self._held = None     # (ts, w) of a sample that would restart the buffer

    def clear(self) -> None:
        """Forget every sample: the integral across the gap is unknown."""
        self._samples.clear()
        self._held = None
        self.last_t = -math.inf
        self.healthy_since = math.nan

    def add(self, t: float, w: float) -> str:
        """
        Take one sample: stamp ``t`` (s, the IMU's clock), rate ``w`` (rad/s).

        Returns
        -------
        str
            '' when taken; 'order' for an out-of-order sample (dropped, counted in
            ``dropped``, no fault) or one held (see the module); else the fault (the buffer
            restarts: the integral across it is unknown).

        """
        cfg = self.config
        self.arrived += 1
        ts = t - cfg.imu_delay
        previous, self._last_w = self._last_w, math.nan
        if not (math.isfinite(ts) and math.isfinite(w)):
            return self._refuse(NON_FINITE)
        if abs(w) >= cfg.saturation:
            return self._refuse(SATURATED)
        if math.isfinite(previous) and abs(w - previous) > cfg.max_jump:
            return self._refuse(JUMP)
        samples = self._samples
        fault = ''
        if samples:
            last = samples[-1][0]
            if 0.0 <= last - ts <= time_limit(cfg):
                self._last_w = previous
                self.dropped += 1
                self.fault = ORDER
                return 'order'
            if ts < last or ts - last > cfg.timeout:
                held, self._held = self._held, (ts, w)
                if held is None or not 0.0 < ts - held[0] <= cfg.timeout:
                    self._last_w = previous
                    self.fault = ORDER
                    return 'order'      # held: the next sample tells
                fault = BACK if ts < last else STALE
                self.clear()
                samples.append(held)
                self.healthy_since = held[0]
            if self._held is not None:  # a held sample the stream did not follow: wild
                self._held = None
                self.dropped += 1
        samples.append((ts, w))
        self._last_w = w
        if not math.isfinite(self.healthy_since):
            self.healthy_since = ts
        self.last_t = ts
        self.fault = fault
        return fault

    def _refuse(self, reason: str) -> str:
        self.refused += 1
        self.fault = reason
        self.clear()
        return reason

    @property
    def first_t(self) -> float:
        """Return the time of the oldest sample kept (inf: none)."""
        return self._samples[0][0] if self._samples else math.inf

    @property
    def last_rate(self) -> float:
        """Return the newest sample's rate, rad/s (0 when none)."""
        return self._samples[-1][1] if self._samples else 0.0

    def integral(self, a: float, b: float) -> float:
        """
        Return the integral of the rate from ``a`` to ``b`` (rad), ``first_t <= a <= b``.

        Linear between samples (the trapezoid), the newest rate held beyond the newest one.
        """
        total = 0.0
        samples = self._samples
        t_prev, w_prev = samples[0]
        for t_next, w_next in samples:
            if t_next <= a:
                t_prev, w_prev = t_next, w_next
                continue
            if t_prev >= b:
                break
            lo, hi = max(a, t_prev), min(b, t_next)
            if hi > lo:
                slope = (w_next - w_prev) / (t_next - t_prev)
                total += (hi - lo) * (w_prev + slope * (0.5 * (lo + hi) - t_prev))
            t_prev, w_prev = t_next, w_next
        if b > t_prev:
            total += w_prev * (b - max(a, t_prev))
        return total

    def drop_before(self, t: float) -> None:
        """Forget the samples before ``t`` but the last one (the interpolation needs it)."""
        samples = self._samples
        while len(samples) > 1 and samples[1][0] <= t:
            samples.popleft()
