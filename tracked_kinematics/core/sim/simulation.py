"""
Trajectory simulation of a tracked vehicle: commands -> drive train -> dynamics -> sensors.

Drive train, encoder scales (Martinez eqs. 20-21), the stationary dynamics through a precomputed
:class:`TwistTable`, exact arcs, then the sensors; everything random takes a
``numpy.random.Generator``. See docs/tools/simulate_bag.md, "The simulation chain".
"""

from __future__ import annotations

from dataclasses import dataclass, field
import functools
import math

import numpy as np

from .dynamics import StationarySolver, Vehicle
from .icr_maps import averaged_icr, icr_map
from ..drivetrain import DriveTrain
from ..integration import arc_chord, compose, integrate_twist, wrap_angle
from ..kinematics import IcrParams


class TwistTable:
    """
    Precomputed stationary response: true track speeds -> body twist, vectorised.

    Tabulated over ``n_angles`` directions ``atan2(V_r, V_l)`` and, with load transfer,
    ``n_speeds`` levels of ``V_l^2 + V_r^2``; cubic splines in between. Raises RuntimeError when
    the solver fails at a table point.
    """

    def __init__(self, vehicle: Vehicle, n_angles: int = 144, n_speeds: int = 8,
                 solver: StationarySolver | None = None):
        if n_angles < 8:
            raise ValueError(f'n_angles must be >= 8, got {n_angles}')
        self.vehicle = vehicle
        solver = solver or StationarySolver(vehicle)
        self.angles = np.linspace(-np.pi, np.pi, n_angles, endpoint=False)
        top = math.sqrt(2.0) * vehicle.max_track_speed
        if vehicle.inertial:
            if n_speeds < 2:
                raise ValueError(f'n_speeds must be >= 2 with load transfer, got {n_speeds}')
            # Equally spaced in S^2; the lowest level is nearly inertia-free.
            self.speeds = top * np.sqrt(np.linspace(1e-4, 1.0, n_speeds))
        else:
            self.speeds = np.array([top])
        # Solve level by level, each from the previous level's solution scaled to its speed
        # (a continuation in speed: the inertial terms grow smoothly).
        unit = np.empty((len(self.speeds), n_angles, 3))
        guess = None
        for j, level in enumerate(self.speeds):
            v_left, v_right = level * np.cos(self.angles), level * np.sin(self.angles)
            twist, ok = solver.solve_many(v_left, v_right,
                                          None if guess is None else guess * level)
            if not np.all(ok):
                bad = np.flatnonzero(~ok)[0]
                raise RuntimeError(
                    f'the stationary solver did not converge at track speeds '
                    f'({v_left[bad]:.3f}, {v_right[bad]:.3f}) m/s for vehicle {vehicle.name!r}')
            unit[j] = guess = twist / level
        # Cubic splines along phi (periodic: padded by a quarter turn on both sides) and, with
        # load transfer, along S^2.
        from scipy.interpolate import CubicSpline, RectBivariateSpline   # lazily, 0.2 s
        pad = n_angles // 4
        angles = np.concatenate([self.angles[-pad:] - 2 * np.pi, self.angles,
                                 self.angles[:pad] + 2 * np.pi])
        padded = np.concatenate([unit[:, -pad:], unit, unit[:, :pad]], axis=1)
        if len(self.speeds) == 1:
            self._splines = [CubicSpline(angles, padded[0, :, k]) for k in range(3)]
        else:
            order = min(3, len(self.speeds) - 1)
            self._splines = [RectBivariateSpline(self.speeds ** 2, angles, padded[..., k],
                                                 kx=order, ky=3) for k in range(3)]

    @staticmethod
    def of(vehicle: Vehicle) -> TwistTable:
        """
        Return the default table of ``vehicle``, built once per process and shared (read-only).

        Building one solves the stationary dynamics at up to 1,152 track speeds (0.26 s for
        the packbot); a simulator that switches back to a terrain, or a process that
        simulates several drives of one vehicle, takes it from here. RuntimeError as the
        constructor.
        """
        return _table_of(vehicle)

    def __call__(self, v_left, v_right):
        """Body twist ``v_x, v_y, w`` for true track speeds (m/s; clamped to the table)."""
        v_left, v_right = np.broadcast_arrays(np.asarray(v_left, float),
                                              np.asarray(v_right, float))
        shape = v_left.shape
        speed = np.hypot(v_left, v_right).ravel()
        angle = np.arctan2(v_right, v_left).ravel()
        if len(self.speeds) == 1:
            unit = np.stack([spline(angle) for spline in self._splines], axis=-1)
        else:
            sq = np.clip(speed ** 2, self.speeds[0] ** 2, self.speeds[-1] ** 2)
            unit = np.stack([spline(sq, angle, grid=False) for spline in self._splines], -1)
        twist = unit * speed[:, None]
        return (twist[:, 0].reshape(shape), twist[:, 1].reshape(shape),
                twist[:, 2].reshape(shape))


@functools.lru_cache(maxsize=16)
def _table_of(vehicle: Vehicle) -> TwistTable:
    return TwistTable(vehicle)


@dataclass(frozen=True, slots=True)
class Encoders:
    """
    Sprocket encoders and their errors.

    Attributes
    ----------
    sprocket_radius : float
        Nominal radius, m: joint angle (rad) x radius = nominal track travel.
    ticks_per_revolution : float
        Encoder ticks per sprocket revolution (after gearing); 0 for no quantisation.
    scale_left, scale_right : float
        True track speed = scale x nominal (Martinez eqs. 20-21).
    position_noise, velocity_noise : float
        Standard deviations of white noise on the reported joint positions (rad) and
        velocities (rad/s).

    """

    sprocket_radius: float = 0.1
    ticks_per_revolution: float = 0.0
    scale_left: float = 1.0
    scale_right: float = 1.0
    position_noise: float = 0.0
    velocity_noise: float = 0.0


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """Ground-truth pose sensor: ``rate`` (Hz), white noise on x, y (m) and heading (rad)."""

    rate: float = 10.0
    position_noise: float = 0.0
    yaw_noise: float = 0.0


@dataclass(frozen=True)
class Robot:
    """Everything the simulator needs about one vehicle on one terrain."""

    vehicle: Vehicle
    drivetrain: DriveTrain = field(default_factory=DriveTrain)
    encoders: Encoders = field(default_factory=Encoders)

    def true_icr(self, n: int = 21, weighting: str = 'uniform') -> IcrParams:
        """
        Averaged constant-ICR model (Martinez sec. 5.2) with the encoders' scales.

        The terrain model an identification from this robot's encoders should approach.
        """
        icr = averaged_icr(icr_map(self.vehicle, n), weighting)
        return IcrParams(icr.track_width, icr.y_left, icr.y_right, icr.x,
                         self.encoders.scale_left, self.encoders.scale_right)


@dataclass(frozen=True)
class Run:
    """
    One simulated run: sample ``k`` at ``t[k]`` (s), step ``k`` from ``t[k]`` to ``t[k + 1]``.

    Attributes
    ----------
    commands, nominal, true_speeds : ndarray, shape (N, 2)
        Commanded, achieved (as encoders measure) and true (``scale * nominal``) track speeds.
    twist : ndarray, shape (N - 1, 3)
        Body twist held over each step.
    pose : ndarray, shape (N, 3)
        True pose (theta continuous).
    joint_position, joint_velocity : ndarray, shape (N, 2)
        What the encoders report: rad, rad/s.
    gt_t, gt_pose, gt_pose_true : ndarray
        Ground-truth times and poses with noise (theta wrapped) and without (continuous).

    """

    t: np.ndarray
    commands: np.ndarray
    nominal: np.ndarray
    true_speeds: np.ndarray
    twist: np.ndarray
    pose: np.ndarray
    joint_position: np.ndarray
    joint_velocity: np.ndarray
    gt_t: np.ndarray
    gt_pose: np.ndarray
    gt_pose_true: np.ndarray

    @property
    def duration(self) -> float:
        """Length of the run, s."""
        return float(self.t[-1] - self.t[0])

    @property
    def distance(self) -> float:
        """Length of the driven path, m."""
        return float(np.sum(np.hypot(np.diff(self.pose[:, 0]), np.diff(self.pose[:, 1]))))

    def best_constant_icr(self, track_width: float) -> IcrParams | None:
        """
        Constant tread ICRs that best fit this run's true twists (least squares), or None.

        What an identification on perfect data would find; None when the run never turns.
        """
        mean = 0.5 * (self.true_speeds[1:] + self.true_speeds[:-1])
        v_x, v_y, w = self.twist.T
        ww = float(np.sum(w * w))
        if ww <= 0.0:
            return None
        y_left = float(np.sum(w * (v_x - mean[:, 0]))) / ww
        y_right = float(np.sum(w * (v_x - mean[:, 1]))) / ww
        x = float(-np.sum(w * v_y)) / ww
        try:
            return IcrParams(track_width, y_left, y_right, x)
        except ValueError:
            return None


def simulate(robot: Robot, commands, dt: float, table: TwistTable | None = None,
             ground_truth: GroundTruth | None = None, rng: np.random.Generator | None = None,
             pose0=(0.0, 0.0, 0.0)) -> Run:
    """
    Simulate a run from commanded track speeds.

    Parameters
    ----------
    robot : Robot
        Vehicle, drive train and encoders.
    commands : array_like, shape (N, 2)
        Commanded nominal track speeds, m/s, one per encoder sample of period ``dt`` (s).
    dt : float
        Encoder sample period, s.
    table : TwistTable, optional
        Precomputed dynamics of ``robot.vehicle``; reuse it across runs (it is the costly part).
    ground_truth : GroundTruth, optional
        Default: 10 Hz, no noise.
    rng : numpy.random.Generator, optional
        Sensor noise and the initial tick phase (default: seeded with 0).
    pose0 : tuple of float
        Start pose ``(x, y, theta)``.

    """
    commands = np.asarray(commands, dtype=float)
    if commands.ndim != 2 or commands.shape[1] != 2 or len(commands) < 2:
        raise ValueError(f'commands must have shape (N >= 2, 2), got {commands.shape}')
    if not np.all(np.isfinite(commands)):
        raise ValueError('commands must be finite')
    if table is None:
        table = TwistTable.of(robot.vehicle)
    elif table.vehicle != robot.vehicle:
        raise ValueError('the twist table was computed for another vehicle')
    ground_truth = ground_truth or GroundTruth()
    rng = rng if rng is not None else np.random.default_rng(0)
    enc = robot.encoders
    n = len(commands)
    t = np.arange(n) * dt

    nominal = robot.drivetrain.simulate(commands, dt)
    true_speeds = nominal * np.array([enc.scale_left, enc.scale_right])
    # Speeds are continuous; over each step use their mean (the trapezoidal travel).
    step_speeds = 0.5 * (true_speeds[1:] + true_speeds[:-1])
    twist = np.stack(table(step_speeds[:, 0], step_speeds[:, 1]), axis=-1)
    x, y, theta = integrate_twist(twist[:, 0], twist[:, 1], twist[:, 2], dt, pose0)
    pose = np.column_stack([np.r_[pose0[0], x], np.r_[pose0[1], y], np.r_[pose0[2], theta]])

    # Encoders: cumulative nominal travel -> sprocket angle, floored to whole ticks from a
    # random phase (a counter does not start aligned with the motion).
    nominal_step = 0.5 * (nominal[1:] + nominal[:-1]) * dt
    angle = np.vstack([np.zeros((1, 2)), np.cumsum(nominal_step, axis=0)]) / enc.sprocket_radius
    if enc.ticks_per_revolution > 0:
        tick = 2.0 * np.pi / enc.ticks_per_revolution
        phase = rng.uniform(0.0, 1.0, size=2)
        angle = np.floor(angle / tick + phase) * tick
    if enc.position_noise > 0:
        angle = angle + rng.normal(0.0, enc.position_noise, size=angle.shape)
    velocity = nominal / enc.sprocket_radius
    if enc.velocity_noise > 0:
        velocity = velocity + rng.normal(0.0, enc.velocity_noise, size=velocity.shape)

    gt_t = np.arange(0.0, t[-1] + 1e-9, 1.0 / ground_truth.rate)
    gt_true = _poses_at(gt_t, t, pose, twist)
    gt_noisy = gt_true.copy()
    if ground_truth.position_noise > 0:
        gt_noisy[:, :2] += rng.normal(0.0, ground_truth.position_noise, size=(len(gt_t), 2))
    if ground_truth.yaw_noise > 0:
        gt_noisy[:, 2] += rng.normal(0.0, ground_truth.yaw_noise, size=len(gt_t))
    gt_noisy[:, 2] = wrap_angle(gt_noisy[:, 2])
    return Run(t=t, commands=commands, nominal=nominal, true_speeds=true_speeds, twist=twist,
               pose=pose, joint_position=angle, joint_velocity=velocity, gt_t=gt_t,
               gt_pose=gt_noisy, gt_pose_true=gt_true)


def _poses_at(times, t, pose, twist):
    """Exact poses at arbitrary times inside the run: last sample, then part of its arc."""
    dt = t[1] - t[0]
    k = np.clip(np.floor(times / dt + 1e-9).astype(int), 0, len(t) - 1)
    tau = times - t[k]
    tw = np.vstack([twist, np.zeros((1, 3))])[k]
    chord_x, chord_y = arc_chord(tw[:, 0] * tau, tw[:, 1] * tau, tw[:, 2] * tau)
    return np.column_stack(compose(*pose[k].T, chord_x, chord_y, tw[:, 2] * tau))
