"""
Sensors of a live simulation: encoders, and a lidar-ICP-like pose, fed step by step.

The gyro is :class:`.sensors.GyroStream`. What is here:

- :class:`EncoderReadout`: sprocket joint positions and velocities as a motor driver reports
  them: positions floored to whole encoder ticks from a random phase (as
  :func:`.simulation.simulate` does), white noise on positions and velocities, and
  optionally wrapped to ``[-pi, pi)`` (drivers that report a continuous joint's angle
  modulo a turn; odometry_node unwraps them).
- :class:`Schedule`: which steps of a fixed-period simulation a sensor of another rate
  samples (the first step at or after each of its due times).
- :class:`PoseModel` and :class:`PoseStream`: a pose source as lidar ICP gives one: the pose
  of ``delay`` seconds ago (the scan's processing time), white noise on position and
  heading, and occasional jumps (a mis-registration that shifts the estimate by
  ``jump_size`` in a random direction and stays until the next one; a Poisson process of
  ``jump_rate`` per second).

Everything random takes a ``numpy.random.Generator``: a run is reproducible from its seed.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..integration import wrap_angle


class EncoderReadout:
    """
    Joint positions and velocities of the two sprockets from the true nominal travel.

    Parameters
    ----------
    sprocket_radius : float
        m: joint angle (rad) x radius = nominal track travel.
    ticks_per_revolution : float
        Encoder ticks per sprocket turn; 0 for no quantisation.
    position_noise, velocity_noise : float
        Standard deviations of the white noise on reported positions (rad) and velocities
        (rad/s).
    wrap : bool
        Report positions wrapped to ``[-pi, pi)``.
    rng : numpy.random.Generator
        Source of the tick phase (drawn first, as :func:`.simulation.simulate` does) and of
        the noise.

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
        """
        Report the joints for cumulative nominal travel and nominal speeds (left, right).

        Parameters
        ----------
        travel : array_like, shape (2,)
            Nominal track travel since the start, m.
        nominal : array_like, shape (2,)
            Nominal track speeds, m/s.

        Returns
        -------
        position : ndarray, shape (2,)
            rad (wrapped when asked).
        velocity : ndarray, shape (2,)
            rad/s.

        """
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
    The steps at which a sensor of ``rate`` samples a simulation stepped every ``dt``.

    Sample ``k >= 1`` is due at ``k / rate``; it is taken at the first step at or after that
    time (exact when ``rate`` divides the step rate, otherwise within one step).

    Parameters
    ----------
    rate : float
        Hz (> 0).
    dt : float
        Step period of the simulation, s.

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
    A pose source as lidar ICP gives one.

    Attributes
    ----------
    rate : float
        Poses per second, Hz.
    delay : float
        Processing time: the pose measured at ``m`` is available at ``m + delay``, s.
    position_noise : float
        Standard deviation of white noise on x and y, m.
    yaw_noise : float
        Standard deviation of white noise on the heading, rad.
    jump_rate : float
        Mean number of jumps per second (0: none).
    jump_size : float
        Length of the position shift of a jump, m (random direction).
    jump_yaw : float
        Standard deviation of the heading shift of a jump, rad.

    """

    rate: float = 10.0
    delay: float = 0.1
    position_noise: float = 0.01
    yaw_noise: float = 0.005
    jump_rate: float = 0.02
    jump_size: float = 0.2
    jump_yaw: float = 0.02


class PoseStream:
    """
    A :class:`PoseModel` fed with the true poses of a live simulation.

    Parameters
    ----------
    model : PoseModel
        The source.
    rng : numpy.random.Generator
        Source of noise and jumps.

    """

    def __init__(self, model: PoseModel, rng: np.random.Generator):
        self.model = model
        self._rng = rng
        self._t: list[float] = []
        self._pose: list[tuple] = []
        self._next = 0
        self._offset = np.zeros(3)
        self.jumps = 0

    def push(self, t: float, pose) -> list[tuple[float, np.ndarray]]:
        """
        Append the true pose ``(x, y, theta)`` at time ``t``; return the poses now available.

        Returns
        -------
        list of (float, ndarray)
            ``(measurement time, (x, y, theta))`` of each pose whose processing ended at or
            before ``t``; theta wrapped to ``[-pi, pi)``.

        """
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
