"""
Sensors of a live simulation: encoders, and a lidar-ICP-like pose, fed step by step.

Encoder joints (ticks, noise, optionally wrapped), the schedule of a sensor of another rate, and a
pose source with delay, noise and Poisson jumps; the gyro is :class:`.sensors.GyroStream`. See
docs/nodes/tracked_simulator.md, "Sensors".
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..integration import wrap_angle


class EncoderReadout:
    """
    Joint positions and velocities of the two sprockets from the true nominal travel.

    ``sprocket_radius`` in m; ``ticks_per_revolution`` 0 for no quantisation; noise std on
    positions (rad) and velocities (rad/s); ``wrap`` reports positions in ``[-pi, pi)``.
    """

    def __init__(self, sprocket_radius: float, ticks_per_revolution: float = 0.0,
                 position_noise: float = 0.0, velocity_noise: float = 0.0,
                 wrap: bool = False, rng: np.random.Generator | None = None):
        if not (math.isfinite(sprocket_radius) and sprocket_radius > 0.0):
            raise ValueError(f'sprocket_radius must be > 0 m, got {sprocket_radius!r}')
        for name, value in (('ticks_per_revolution', ticks_per_revolution),
                            ('position_noise', position_noise),
                            ('velocity_noise', velocity_noise)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'{name} must be >= 0, got {value!r}')
        self.radius = float(sprocket_radius)
        self.position_noise = float(position_noise)
        self.velocity_noise = float(velocity_noise)
        self.wrap = bool(wrap)
        self._rng = rng if rng is not None else np.random.default_rng(0)
        if ticks_per_revolution > 0:
            self._tick = 2.0 * math.pi / ticks_per_revolution
            self._phase = self._rng.uniform(0.0, 1.0, size=2)
        else:
            self._tick = None

    def read(self, travel, nominal) -> tuple[np.ndarray, np.ndarray]:
        """Report joint positions (rad), velocities (rad/s) of nominal travel (m), speeds (m/s)."""
        angle = np.asarray(travel, float) / self.radius
        if self._tick is not None:
            angle = np.floor(angle / self._tick + self._phase) * self._tick
        if self.position_noise > 0:
            angle = angle + self._rng.normal(0.0, self.position_noise, size=2)
        if self.wrap:
            angle = wrap_angle(angle)
        velocity = np.asarray(nominal, float) / self.radius
        if self.velocity_noise > 0:
            velocity = velocity + self._rng.normal(0.0, self.velocity_noise, size=2)
        return angle, velocity


class Schedule:
    """
    The steps at which a sensor of ``rate`` (Hz) samples a simulation stepped every ``dt`` s.

    Sample ``k >= 1`` is due at ``k / rate`` and taken at the first step at or after it.
    """

    def __init__(self, rate: float, dt: float):
        if not (math.isfinite(rate) and rate > 0.0):
            raise ValueError(f'rate must be > 0 Hz, got {rate!r}')
        self.rate = float(rate)
        self._slack = 1e-6 * dt
        self._next = 1

    def due(self, t: float) -> bool:
        """Tell whether a sample is due at step time ``t`` (and count it when it is)."""
        if t + self._slack < self._next / self.rate:
            return False
        # A sensor faster than the steps samples once per step (the rest are skipped).
        self._next = int(math.floor((t + self._slack) * self.rate)) + 1
        return True


@dataclass(frozen=True, slots=True)
class PoseModel:
    """
    A pose source as lidar ICP gives one (SI units).

    A pose measured at ``m`` is available at ``m + delay``; white noise on position and yaw; jumps
    at ``jump_rate`` per s shift it by ``jump_size`` m (random direction) and ``jump_yaw`` rad
    (std) until the next one.
    """

    rate: float = 10.0
    delay: float = 0.1
    position_noise: float = 0.01
    yaw_noise: float = 0.005
    jump_rate: float = 0.02
    jump_size: float = 0.2
    jump_yaw: float = 0.02


class PoseStream:
    """A :class:`PoseModel` fed with the true poses of a live simulation."""

    def __init__(self, model: PoseModel, rng: np.random.Generator):
        self.model = model
        self._rng = rng
        self._t: list[float] = []
        self._pose: list[tuple] = []
        self._next = 0
        self._offset = np.zeros(3)
        self.jumps = 0

    def push(self, t: float, pose) -> list[tuple[float, np.ndarray]]:
        """Append the true pose at ``t``; return ``(time measured, (x, y, theta))`` now due."""
        m = self.model
        self._t.append(float(t))
        self._pose.append(tuple(pose))
        out = []
        while True:
            measured = self._next / m.rate
            if measured + m.delay > t + 1e-9 or measured > self._t[-1] + 1e-9:
                break
            self._next += 1
            if measured < self._t[0] - 1e-9:
                continue  # before the first truth sample: nothing to measure
            out.append((measured, self._measure(measured)))
        keep = 0
        horizon = self._next / m.rate
        while keep + 1 < len(self._t) and self._t[keep + 1] <= horizon:
            keep += 1
        del self._t[:keep], self._pose[:keep]
        return out

    def _measure(self, at: float) -> np.ndarray:
        m = self.model
        t = np.asarray(self._t)
        pose = np.asarray(self._pose)
        true = np.array([np.interp(at, t, pose[:, k]) for k in range(3)])
        if m.jump_rate > 0 and self._rng.uniform() < -math.expm1(-m.jump_rate / m.rate):
            direction = self._rng.uniform(-math.pi, math.pi)
            self._offset = self._offset + np.array([
                m.jump_size * math.cos(direction), m.jump_size * math.sin(direction),
                self._rng.normal(0.0, m.jump_yaw) if m.jump_yaw > 0 else 0.0])
            self.jumps += 1
        noise = np.zeros(3)
        if m.position_noise > 0:
            noise[:2] = self._rng.normal(0.0, m.position_noise, size=2)
        if m.yaw_noise > 0:
            noise[2] = self._rng.normal(0.0, m.yaw_noise)
        out = true + self._offset + noise
        out[2] = float(wrap_angle(out[2]))
        return out
