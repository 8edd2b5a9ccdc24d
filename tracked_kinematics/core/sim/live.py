"""
The simulator one step at a time: for a live node that does not know its commands ahead.

:class:`LiveSimulator` keeps the state of the chain of :func:`.simulation.simulate` and reproduces
it to rounding when fed the same commands; the terrain may change between steps. The sensors of a
live run are in :mod:`.live_sensors`.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

import numpy as np

from .simulation import Robot, TwistTable
from ..drivetrain import DriveTrain
from ..integration import integrate_twist


class DriveTrainStepper:
    """
    A :class:`~tracked_kinematics.core.drivetrain.DriveTrain` run sample by sample, on floats.

    The chain of :meth:`DriveTrain.simulate`, the speed loop as a direct-form II transposed filter
    (what ``scipy.signal.lfilter`` runs).
    """

    def __init__(self, drivetrain: DriveTrain, dt: float):
        self.drivetrain = drivetrain
        self.dt = float(dt)
        lag = int(math.ceil(drivetrain.delay / self.dt - 1e-9))
        self._delay = [deque([0.0] * lag), deque([0.0] * lag)]
        self._shaped = [0.0, 0.0]
        self._step = drivetrain.max_accel * self.dt
        if drivetrain.loop is None:
            self._b = self._a = None
            self._z = [[], []]
        else:
            b, a = drivetrain.discretise(self.dt)
            n = max(len(a), len(b))
            b = np.r_[b, np.zeros(n - len(b))] / a[0]
            a = np.r_[a, np.zeros(n - len(a))] / a[0]
            self._b, self._a = [float(v) for v in b], [float(v) for v in a]
            self._z = [[0.0] * (n - 1), [0.0] * (n - 1)]
        self.speeds = (0.0, 0.0)

    def step(self, left: float, right: float) -> tuple[float, float]:
        """Take the commands (m/s) of the next sample; return the track speeds then, m/s."""
        out = []
        top = self.drivetrain.max_speed
        for side, command in enumerate((left, right)):
            line = self._delay[side]
            if line:
                line.append(command)
                command = line.popleft()
            target = min(max(command, -top), top)
            value = self._shaped[side]
            value += min(max(target - value, -self._step), self._step)
            self._shaped[side] = value
            out.append(self._filter(side, value))
        self.speeds = (out[0], out[1])
        return self.speeds

    def _filter(self, side: int, x: float) -> float:
        b = self._b
        if b is None:
            return x
        a, z = self._a, self._z[side]
        y = b[0] * x + z[0] if z else b[0] * x
        last = len(z) - 1
        for i in range(last):
            z[i] = b[i + 1] * x + z[i + 1] - a[i + 1] * y
        if z:
            z[last] = b[last + 1] * x - a[last + 1] * y
        return y


@dataclass(frozen=True, slots=True)
class SimState:
    """
    The true state after a step (SI units; pose in odom, theta continuous).

    ``twist`` is held over the step; ``nominal`` the track speeds as encoders see them,
    ``true_speeds`` ``scale * nominal``, ``travel`` the cumulative nominal travel (m).
    """

    t: float
    pose: tuple
    twist: tuple
    nominal: tuple
    true_speeds: tuple
    travel: tuple
    command: tuple


@dataclass(frozen=True)
class Steps:
    """The states after several steps (:meth:`LiveSimulator.step_many`), a row per step."""

    t: np.ndarray
    pose: np.ndarray
    twist: np.ndarray
    nominal: np.ndarray
    true_speeds: np.ndarray
    travel: np.ndarray
    command: np.ndarray

    def __len__(self) -> int:
        """Return the number of steps."""
        return len(self.t)

    def state(self, k: int) -> SimState:
        """Return step ``k`` as a :class:`SimState`."""
        return SimState(float(self.t[k]), tuple(self.pose[k].tolist()),
                        tuple(self.twist[k].tolist()), tuple(self.nominal[k].tolist()),
                        tuple(self.true_speeds[k].tolist()), tuple(self.travel[k].tolist()),
                        tuple(self.command[k].tolist()))


class LiveSimulator:
    """
    Step the simulated robot by ``dt`` (s) per call, given the track setpoints in force.

    Sample 0 is the robot at rest at ``pose0``; stepping through ``commands[1:]`` gives the run
    :func:`.simulation.simulate` makes of ``commands`` when ``commands[0]`` is zero.
    """

    def __init__(self, robot: Robot, dt: float, table: TwistTable | None = None,
                 pose0=(0.0, 0.0, 0.0)):
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'dt must be a finite number > 0 s, got {dt!r}')
        self.robot = robot
        self.dt = dt
        self.table = table if table is not None else TwistTable.of(robot.vehicle)
        self._drives = DriveTrainStepper(robot.drivetrain, dt)
        self._scale = (robot.encoders.scale_left, robot.encoders.scale_right)
        self.steps = 0
        zero = (0.0, 0.0)
        self.state = SimState(0.0, tuple(float(v) for v in pose0), (0.0, 0.0, 0.0), zero,
                              zero, zero, zero)

    @property
    def t(self) -> float:
        """Return the simulated time of the current state, s."""
        return self.state.t

    def set_table(self, table: TwistTable) -> None:
        """Use other dynamics (a new terrain) from the next step on; the drives keep going."""
        self.table = table

    def step(self, left: float, right: float) -> SimState:
        """
        Advance one period with commands ``left``, ``right`` (m/s); return the :class:`SimState`.

        Raises ValueError on a non-finite command (the state is left as it was).
        """
        left, right = float(left), float(right)
        if not (math.isfinite(left) and math.isfinite(right)):
            raise ValueError(f'commands must be finite, got ({left!r}, {right!r})')
        prev = self.state
        nominal = self._drives.step(left, right)
        true = (self._scale[0] * nominal[0], self._scale[1] * nominal[1])
        mean_l = 0.5 * (prev.true_speeds[0] + true[0])
        mean_r = 0.5 * (prev.true_speeds[1] + true[1])
        v_x, v_y, w = (float(c) for c in self.table(mean_l, mean_r))
        pose = _arc_step(prev.pose, v_x * self.dt, v_y * self.dt, w * self.dt)
        travel = (prev.travel[0] + 0.5 * (prev.nominal[0] + nominal[0]) * self.dt,
                  prev.travel[1] + 0.5 * (prev.nominal[1] + nominal[1]) * self.dt)
        self.steps += 1
        self.state = SimState(self.steps * self.dt, pose, (v_x, v_y, w), nominal, true, travel,
                              (left, right))
        return self.state

    def step_many(self, commands) -> Steps:
        """
        Take one step per row of ``commands`` (n, 2; m/s), vectorised; return :class:`Steps`.

        Equal to :meth:`step` per row to rounding. Raises ValueError on a non-finite command or a
        wrong shape (no step is taken then).
        """
        commands = np.asarray(commands, dtype=float).reshape(-1, 2)
        if not np.all(np.isfinite(commands)):
            raise ValueError('commands must be finite')
        n = len(commands)
        if n == 1:  # one step: plain floats are faster than arrays of one
            state = self.step(*commands[0].tolist())
            return Steps(np.array([state.t]), *(np.array([v], dtype=float) for v in (
                state.pose, state.twist, state.nominal, state.true_speeds, state.travel,
                state.command)))
        prev = self.state
        nominal = np.array([self._drives.step(left, right)
                            for left, right in commands.tolist()]).reshape(n, 2)
        true = nominal * np.asarray(self._scale)
        speeds = np.vstack([np.asarray(prev.true_speeds)[None], true])
        mean = 0.5 * (speeds[1:] + speeds[:-1])
        twist = np.stack(self.table(mean[:, 0], mean[:, 1]), axis=-1).reshape(n, 3)
        x, y, theta = integrate_twist(twist[:, 0], twist[:, 1], twist[:, 2], self.dt,
                                      prev.pose)
        noms = np.vstack([np.asarray(prev.nominal)[None], nominal])
        travel = np.asarray(prev.travel) + np.cumsum(0.5 * (noms[1:] + noms[:-1]) * self.dt,
                                                     axis=0)
        t = (self.steps + np.arange(1, n + 1)) * self.dt
        steps = Steps(t, np.column_stack([x, y, theta]), twist, nominal, true, travel,
                      commands)
        if n:
            self.steps += n
            self.state = steps.state(n - 1)
        return steps


def _sinc(x: float) -> float:
    """``numpy.sinc`` on a float: ``sin(pi x) / (pi x)``, 1 at 0."""
    y = math.pi * (x if x != 0.0 else 1e-20)
    return math.sin(y) / y


def _arc_step(pose, dx: float, dy: float, dtheta: float) -> tuple:
    """Pose after one arc of body increments, on floats, as :func:`.integration.integrate`."""
    s = _sinc(dtheta / math.pi)
    c = 0.5 * dtheta * _sinc(dtheta / (2.0 * math.pi)) ** 2
    chord_x, chord_y = s * dx - c * dy, c * dx + s * dy
    theta = pose[2] + dtheta
    start = theta - dtheta
    cos_t, sin_t = math.cos(start), math.sin(start)
    return (pose[0] + (cos_t * chord_x - sin_t * chord_y),
            pose[1] + (sin_t * chord_x + cos_t * chord_y), theta)


class SetpointHold:
    """
    The setpoint in force for one track: the last valid one, or zero once it is stale.

    Stale: older than ``timeout`` (s) in both simulated and wall time, so a wall-paced publisher
    survives a fast simulation and a dead one stops the robot. ``limit`` (m/s) clamps.
    """

    def __init__(self, timeout: float, limit: float):
        self.timeout = float(timeout)
        self.limit = float(limit)
        self.value = 0.0
        self._sim = -math.inf
        self._wall = -math.inf

    def take(self, value, sim_t: float, wall_t: float) -> str | None:
        """Take a setpoint received at ``sim_t`` / ``wall_t``; return what was wrong, or None."""
        try:
            value = float(value)
        except (TypeError, ValueError):
            return f'ignored a setpoint that is not a number ({value!r})'
        if not math.isfinite(value):
            return f'ignored a non-finite setpoint ({value!r}); the last good one holds'
        problem = None
        if abs(value) > self.limit:
            problem = (f'clamped a setpoint of {value!r} m/s to +-{self.limit:g} m/s (the '
                       'vehicle envelope)')
            value = math.copysign(self.limit, value)
        self.value, self._sim, self._wall = value, sim_t, wall_t
        return problem

    def stale(self, sim_t: float, wall_t: float) -> bool:
        """Tell whether the setpoint is older than the timeout in both clocks."""
        return (sim_t - self._sim > self.timeout) and (wall_t - self._wall > self.timeout)

    def current(self, sim_t: float, wall_t: float) -> float:
        """Return the setpoint in force: the last one, or 0 when stale."""
        return 0.0 if self.stale(sim_t, wall_t) else self.value
