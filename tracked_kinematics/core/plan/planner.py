"""
Trajectory generation with identified motion models, Fink & Stump sec. III-C and IV-C.

A plan is nominal track speed setpoints, piecewise linear between knots, found by COBYLA so that
the motion model driven through the drive train (eqs. 6-8) reaches a goal or follows a path. See
docs/tools/plan_trajectory.md, "How it plans".
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import time

import numpy as np

from .trajectories import Reference
from ..command import CommandLimits
from ..drivetrain import DriveTrain
from ..errors import PlanningError
from ..integration import integrate_twist, relative_pose
from ..kinematics import forward, IcrParams
from ..models import MotionModel


@dataclass(frozen=True)
class Plan:
    """
    A planned command sequence and what the planning model predicts for it.

    Attributes
    ----------
    commands : ndarray, shape (N, 2)
        Nominal setpoints ``(left, right)``, m/s, one per ``dt`` (s), held; the last is zero.
    poses : ndarray, shape (N + S, 3)
        Predicted poses at the command times and through ``S`` settling samples.
    position_error, yaw_error : float
        Predicted final pose minus goal: m and rad.
    path_deviation : float
        Largest distance of the predicted path from the reference path, m (NaN without one).

    """

    commands: np.ndarray
    dt: float
    poses: np.ndarray
    goal: np.ndarray
    position_error: float
    yaw_error: float
    success: bool
    message: str
    model: str = ''
    path_deviation: float = math.nan
    nfev: int = 0
    seconds: float = 0.0
    knots: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def t(self) -> np.ndarray:
        """Command times, s."""
        return np.arange(len(self.commands)) * self.dt

    def twists(self, icr: IcrParams):
        """
        ``cmd_vel`` ``(v_x, w)`` the translator with model ``icr`` turns into these.

        The forward kinematics of ``scale * nominal``, inverting Martinez eqs. (10)-(11),
        (20)-(21).
        """
        v_x, _, w = forward(self.commands[:, 0] * icr.scale_left,
                            self.commands[:, 1] * icr.scale_right, icr)
        return np.asarray(v_x, float), np.asarray(w, float)


def path_deviation(path, ref_path) -> np.ndarray:
    """Distance (m) of each point of ``path`` to the nearest of ``ref_path`` (F&S eq. 9)."""
    path = np.asarray(path, float)[:, :2]
    ref = np.asarray(ref_path, float)[:, :2]
    d2 = (np.sum(path ** 2, 1)[:, None] + np.sum(ref ** 2, 1)[None, :]
          - 2.0 * path @ ref.T)
    return np.sqrt(np.maximum(d2.min(axis=1), 0.0))


def _within(z, matrix, bound):
    """Scale knots toward rest into the limits ``matrix z <= bound`` (COBYLA's catol)."""
    load = matrix @ z
    over = load > bound
    if not np.any(over):
        return z
    return z * float(np.min(bound[over] / load[over]))


class _OutOfTime(Exception):
    """The optimiser's time limit passed (raised from the cost, caught around COBYLA)."""


def reach(speed: float, accel: float, horizon: float) -> float:
    """Longest travel of a track that starts and ends at rest within ``horizon``, m."""
    if math.isinf(accel):
        return speed * horizon
    if horizon >= 2.0 * speed / accel:
        return speed * (horizon - speed / accel)
    return 0.25 * accel * horizon ** 2


class Planner:
    """
    Command sequences for a motion model through a drive-train model, within limits.

    Parameters
    ----------
    model, p : MotionModel, array_like
        Planning model and its parameters.
    drivetrain : DriveTrain
        Command -> measured track speed response.
    limits : CommandLimits, optional
        The translator's limits, as constraints; track limits default to the drive train's.
    command_icr : IcrParams, optional
        The translator's model (twist limits, ``cmd_vel``); default the ideal drive.
    dt, knot_spacing, settle : float
        Command period, time between knots, settling time after the last command: s.

    """

    def __init__(self, model: MotionModel, p, drivetrain: DriveTrain,
                 limits: CommandLimits | None = None, command_icr: IcrParams | None = None,
                 dt: float = 0.02, knot_spacing: float = 0.4, settle: float = 1.0):
        self.model = model
        self.p = np.asarray(p, dtype=float)
        if len(self.p) != model.n_params or not np.all(np.isfinite(self.p)):
            raise PlanningError(f'{model.name} needs {model.n_params} finite parameters, '
                                f'got {self.p.tolist()}')
        self.drivetrain = drivetrain
        self.limits = limits or CommandLimits()
        self.command_icr = command_icr or IcrParams.ideal(model.track_width)
        for label, value in (('dt', dt), ('knot_spacing', knot_spacing)):
            if not (math.isfinite(value) and value > 0.0):
                raise PlanningError(f'{label} must be a finite number > 0 s, got {value!r}')
        if not (math.isfinite(settle) and settle >= 0.0):
            raise PlanningError(f'settle must be a finite number >= 0 s, got {settle!r}')
        self.dt, self.knot_spacing = float(dt), float(knot_spacing)
        self.smoothing = 1e-4
        self.settle_steps = int(round(settle / dt))
        self.max_speed = min(self.limits.max_track_speed, drivetrain.max_speed)
        self.max_accel = min(self.limits.max_track_accel, drivetrain.max_accel)
        if math.isinf(self.max_speed):
            raise PlanningError('planning needs a finite max_track_speed (or a drive-train '
                                'speed limit)')

    # Prediction ---------------------------------------------------------------------------

    def predict(self, commands, start=(0.0, 0.0, 0.0)) -> np.ndarray:
        """Poses (N + S, 3) the model predicts for setpoints (N, 2; m/s), through settling."""
        commands = np.asarray(commands, dtype=float)
        full = np.vstack([commands, np.zeros((self.settle_steps, 2))])
        speeds = self.drivetrain.simulate(full, self.dt)
        step = 0.5 * (speeds[1:] + speeds[:-1])
        v_x, v_y, w = self.model.twist(self.p, step[:, 0], step[:, 1])
        x, y, th = integrate_twist(v_x, v_y, w, self.dt, tuple(start))
        return np.column_stack([np.r_[start[0], x], np.r_[start[1], y], np.r_[start[2], th]])

    # Knots and constraints ----------------------------------------------------------------

    def _grid(self, horizon: float):
        """Sample count, knot count and the knot -> sample interpolation matrix."""
        n = int(round(horizon / self.dt))
        m = max(2, int(math.ceil(horizon / self.knot_spacing - 1e-9)))
        t = np.arange(n) * self.dt
        knot_t = np.linspace(0.0, (n - 1) * self.dt, m + 1)   # the last command is a knot
        eye = np.eye(m + 1)
        interp = np.stack([np.interp(t, knot_t, eye[j]) for j in range(m + 1)], axis=1)
        return n, m, interp[:, 1:m], knot_t[1] - knot_t[0]

    def _constraints(self, m: int, h: float):
        """Linear inequalities ``G z <= b`` on the free knots, normalised by max_speed."""
        free = m - 1
        scale = self.max_speed
        rows, bounds = [], []
        # Knot values of both tracks (including the fixed zero ends) as matrices of z.
        pad = np.zeros((m + 1, free))
        pad[1:m] = np.eye(free)
        left = np.hstack([pad, np.zeros_like(pad)])
        right = np.hstack([np.zeros_like(pad), pad])
        diff = np.diff(np.eye(m + 1), axis=0)

        def add(matrix, limit):
            if math.isfinite(limit):
                rows.extend([matrix, -matrix])
                bounds.extend([np.full(len(matrix), limit)] * 2)

        for track in (left, right):
            add(track[1:m] * scale, self.max_speed)
            add(diff @ track * scale, self.max_accel * h)
        icr, lim = self.command_icr, self.limits
        span = icr.y_left - icr.y_right
        v_x = (icr.scale_right * icr.y_left * right - icr.scale_left * icr.y_right * left) / span
        w = (icr.scale_right * right - icr.scale_left * left) / span
        add(v_x[1:m] * scale, lim.max_linear_velocity)
        add(diff @ v_x * scale, lim.max_linear_acceleration * h)
        add(w[1:m] * scale, lim.max_angular_velocity)
        add(diff @ w * scale, lim.max_angular_acceleration * h)
        return np.vstack(rows), np.concatenate(bounds)

    def _optimise(self, cost, z0, matrix, bound, maxiter, extra=(), tol=1e-4,
                  time_limit=None):
        """Run COBYLA over the free knots; return them and whether ``time_limit`` stopped it."""
        cons = {'type': 'ineq', 'fun': lambda z: bound - matrix @ z,
                'jac': lambda z: -matrix}
        # Start inside the limits: shrink the guess toward rest (which is feasible).
        worst = float(np.max(matrix @ z0 / bound)) if len(bound) else 0.0
        if worst > 1.0:
            z0 = z0 / worst * 0.999
        deadline = None if time_limit is None else time.perf_counter() + time_limit
        best = {'cost': math.inf, 'z': z0}

        def timed(z):
            if deadline is not None and time.perf_counter() > deadline:
                raise _OutOfTime
            value = cost(z)
            if value < best['cost'] and np.all(matrix @ z <= bound + 1e-9):
                best.update(cost=value, z=np.array(z, dtype=float))
            return value

        from scipy import optimize   # lazily: the nodes import this package, never optimise
        try:
            res = optimize.minimize(timed, z0, method='COBYLA', constraints=[cons, *extra],
                                    options={'rhobeg': 0.1, 'tol': tol, 'maxiter': maxiter,
                                             'catol': 1e-9})
        except _OutOfTime:   # the best point within the limits so far
            return _within(best['z'], matrix, bound), True
        return _within(res.x, matrix, bound), False

    def _commands(self, z, interp, free):
        knots = z.reshape(2, free).T * self.max_speed
        return interp @ knots, knots

    # Planning -----------------------------------------------------------------------------

    def plan_to(self, goal, horizon: float, start=(0.0, 0.0, 0.0),
                tolerance=(0.05, 0.05), heading_weight: float = 0.5,
                maxiter: int = 3000, time_limit: float | None = None) -> Plan:
        """
        Setpoints that bring the robot from ``start`` to ``goal`` within ``horizon`` (s).

        Minimises ``|dp|^2 + (lambda dtheta)^2 + mu sum (knot steps)^2`` of the final pose error
        (eq. 10 as a penalty), subject to the limits. ``tolerance`` is (m, rad), ``heading_weight``
        is ``lambda`` (m/rad). A missed or unreachable goal gives ``success`` False with a message;
        ValueError on a non-finite pose, a too-short horizon or a non-positive tolerance.
        """
        started = time.perf_counter()
        goal, start = self._check_pose(goal, 'goal'), self._check_pose(start, 'start')
        horizon = self._check_horizon(horizon)
        tol_pos, tol_yaw = (float(v) for v in tolerance)
        if not (tol_pos > 0.0 and tol_yaw > 0.0):
            raise PlanningError(f'tolerance must be > 0, got {tolerance!r}')
        dx, dy, dth = (float(v) for v in relative_pose(*start, *goal))
        distance = math.hypot(dx, dy)
        n, m, interp, h = self._grid(horizon)
        free = m - 1
        # Reachability: the farthest a track can go, times the model's speed per track speed.
        v_fwd, _, _ = self.model.twist(self.p, [1.0, -1.0], [1.0, -1.0])
        _, _, w_spin = self.model.twist(self.p, [-1.0, 1.0], [1.0, -1.0])
        track_reach = reach(self.max_speed, self.max_accel, n * self.dt)
        max_distance = track_reach * float(np.max(np.abs(v_fwd)))
        max_turn = track_reach * float(np.max(np.abs(w_spin)))
        # Twist limits act on the translator's model; carry them over to the planning model
        # by the ratio of the two models' speed per track speed.
        lim, icr = self.limits, self.command_icr
        cmd_v, _, _ = forward(icr.scale_left, icr.scale_right, icr)
        _, _, cmd_w = forward(-icr.scale_left, icr.scale_right, icr)
        max_distance = min(max_distance, reach(
            lim.max_linear_velocity, lim.max_linear_acceleration, n * self.dt)
            * float(np.max(np.abs(v_fwd))) / abs(float(cmd_v)))
        max_turn = min(max_turn, reach(
            lim.max_angular_velocity, lim.max_angular_acceleration, n * self.dt)
            * float(np.max(np.abs(w_spin))) / abs(float(cmd_w)))
        empty = np.zeros((n, 2))
        if distance > max_distance + tol_pos or abs(dth) > max_turn + tol_yaw:
            what = (f'{distance:.2f} m away, at most {max_distance:.2f} m'
                    if distance > max_distance + tol_pos else
                    f'a {math.degrees(abs(dth)):.0f} deg turn, at most '
                    f'{math.degrees(max_turn):.0f} deg')
            msg = (f'goal unreachable within {horizon:g} s: {what} with max track speed '
                   f'{self.max_speed:g} m/s and acceleration {self.max_accel:g} m/s^2 '
                   f'({self.model.name} model); give a longer horizon or a nearer goal')
            return self._failed(empty, goal, start, msg, started)
        z0 = self._guess(dx, dy, dth, n, m, free)
        matrix, bound = self._constraints(m, h)
        mu = self.smoothing
        count = [0]

        def cost(z):
            count[0] += 1
            commands, knots = self._commands(z, interp, free)
            end = self.predict(commands, start)[-1]
            ex, ey, eth = relative_pose(*goal, *end)
            smooth = np.sum(np.diff(np.vstack([[0, 0], z.reshape(2, free).T, [0, 0]]),
                                    axis=0) ** 2)
            return float(ex * ex + ey * ey + (heading_weight * eth) ** 2 + mu * smooth)

        z, stopped = self._optimise(cost, z0, matrix, bound, maxiter, time_limit=time_limit)
        return self._finish(z, interp, free, goal, start, tol_pos, tol_yaw, count[0],
                            started, None, time_limit if stopped else None)

    def follow(self, ref: Reference, start=(0.0, 0.0, 0.0), tolerance=(0.05, 0.05),
               path_weight: float = 1.0, goal_weight: float = 10.0,
               heading_weight: float = 0.5, maxiter: int = 3000,
               time_limit: float | None = None) -> Plan:
        """
        Setpoints that follow a reference path and end at its final pose (eqs. 9 and 10).

        Minimises ``w_p mean_t min_s ||rho(t) - rho_d(s)|| + w_g (|dp| + lambda |dtheta|)`` over
        the reference's horizon (the ``w_t t_f`` term is left out), from the ideal drive's inputs.
        """
        started = time.perf_counter()
        start = self._check_pose(start, 'start')
        tol_pos, tol_yaw = (float(v) for v in tolerance)
        c, s = math.cos(start[2]), math.sin(start[2])
        ref_path = np.column_stack([start[0] + c * ref.path[:, 0] - s * ref.path[:, 1],
                                    start[1] + s * ref.path[:, 0] + c * ref.path[:, 1],
                                    start[2] + ref.path[:, 2]])
        goal = ref_path[-1]
        horizon = self._check_horizon(ref.duration)
        n, m, interp, h = self._grid(horizon)
        free = m - 1
        # Initial guess: the ideal-drive inputs, sampled at the knots, scaled into the limits.
        ideal = ref.tracks(self.model.track_width)
        knot_t = np.linspace(0.0, (n - 1) * self.dt, m + 1)[1:m]
        t_ref = (np.arange(len(ideal)) + 0.5) * ref.dt
        z0 = np.concatenate([np.interp(knot_t, t_ref, ideal[:, k]) for k in (0, 1)])
        z0 /= self.max_speed
        matrix, bound = self._constraints(m, h)
        from scipy.spatial import cKDTree
        tree = cKDTree(ref_path[:, :2])
        count = [0]
        memo = {}

        def predicted(z):
            key = z.tobytes()
            if key not in memo:
                count[0] += 1
                memo.clear()
                poses = self.predict(self._commands(z, interp, free)[0], start)
                ex, ey, eth = relative_pose(*goal, *poses[-1])
                memo[key] = (poses, math.hypot(ex, ey), abs(float(eth)))
            return memo[key]

        def cost(z):
            poses, pos_err, yaw_err = predicted(z)
            deviation = float(np.mean(tree.query(poses[:, :2])[0]))
            return path_weight * deviation + goal_weight * (pos_err + heading_weight * yaw_err)

        # The final-pose condition of eq. (10), as inequalities within half the tolerance.
        goal_cons = {'type': 'ineq', 'fun': lambda z: np.array(
            [0.5 * tol_pos - predicted(z)[1], 0.5 * tol_yaw - predicted(z)[2]])}
        # The goal is held by the constraints; the path cost needs less precision than a
        # goal cost (a final trust radius of 1e-3 of max speed halves the time, same paths).
        z, stopped = self._optimise(cost, z0, matrix, bound, maxiter, extra=[goal_cons],
                                    tol=1e-3, time_limit=time_limit)
        return self._finish(z, interp, free, goal, start, tol_pos, tol_yaw, count[0],
                            started, ref_path, time_limit if stopped else None)

    # Helpers ------------------------------------------------------------------------------

    def _guess(self, dx, dy, dth, n, m, free):
        """Start of the search: one arc through the goal position, or a spin in place."""
        horizon = (n - 1) * self.dt
        knot_t = np.linspace(0.0, horizon, m + 1)[1:m]
        ramp = max(self.max_speed / self.max_accel if math.isfinite(self.max_accel) else 0.0,
                   self.knot_spacing)
        ramp = min(ramp, 0.5 * horizon)
        shape = np.minimum(1.0, np.minimum(knot_t, horizon - knot_t) / ramp)
        area = horizon - ramp    # integral of the shape over the horizon, s
        half = 0.5 * self.model.track_width
        distance = math.hypot(dx, dy)
        if distance < 1e-3:
            v, w = 0.0, dth / area
        else:
            # Forward arc tangent to the start heading through the goal position (mirrored
            # when the goal is behind: reversing along the mirrored arc).
            sign = -1.0 if dx < 0.0 else 1.0
            angle = 2.0 * math.atan2(dy, sign * dx)
            length = distance if abs(angle) < 1e-6 else (
                distance * angle / (2.0 * math.sin(0.5 * angle)))
            v, w = sign * length / area, sign * angle / area
        left, right = v - half * w, v + half * w
        return np.concatenate([left * shape, right * shape]) / self.max_speed

    def _finish(self, z, interp, free, goal, start, tol_pos, tol_yaw, nfev, started,
                ref_path, stopped_at=None):
        commands, knots = self._commands(z, interp, free)
        poses = self.predict(commands, start)
        ex, ey, eth = relative_pose(*goal, *poses[-1])
        pos_err, yaw_err = math.hypot(ex, ey), abs(float(eth))
        deviation = (float(np.max(path_deviation(poses, ref_path)))
                     if ref_path is not None else math.nan)
        success = pos_err <= tol_pos and yaw_err <= tol_yaw
        if success:
            message = (f'planned with the {self.model.name} model: predicted final pose '
                       f'{pos_err * 100:.1f} cm and {math.degrees(yaw_err):.1f} deg from the '
                       f'goal')
        else:
            message = (f'no plan within tolerance: the best the optimiser found with the '
                       f'{self.model.name} model ends {pos_err:.3f} m and '
                       f'{math.degrees(yaw_err):.1f} deg from the goal (tolerance '
                       f'{tol_pos:g} m, {math.degrees(tol_yaw):.1f} deg)')
        if stopped_at is not None:
            message += (f'; the optimiser was stopped at its time limit of {stopped_at:g} s '
                        f'after {nfev} predictions')
        return Plan(commands=commands, dt=self.dt, poses=poses, goal=np.asarray(goal),
                    position_error=pos_err, yaw_error=yaw_err, success=success,
                    message=message, model=self.model.name, path_deviation=deviation,
                    nfev=nfev, seconds=time.perf_counter() - started, knots=knots)

    def _failed(self, commands, goal, start, message, started):
        poses = np.tile(np.asarray(start, float), (len(commands) + self.settle_steps, 1))
        ex, ey, eth = relative_pose(*goal, *start)
        return Plan(commands=commands, dt=self.dt, poses=poses, goal=np.asarray(goal),
                    position_error=math.hypot(ex, ey), yaw_error=abs(float(eth)),
                    success=False, message=message, model=self.model.name,
                    seconds=time.perf_counter() - started)

    @staticmethod
    def _check_pose(pose, label):
        try:
            pose = np.asarray(pose, dtype=float).reshape(3)
        except (TypeError, ValueError):
            raise PlanningError(f'{label} must be three numbers (x y yaw), got {pose!r}') from None
        if not np.all(np.isfinite(pose)):
            raise PlanningError(f'{label} must be finite, got {pose.tolist()}')
        return pose

    def _check_horizon(self, horizon):
        horizon = float(horizon)
        if not (math.isfinite(horizon) and horizon >= 2.0 * self.knot_spacing
                and horizon >= 4 * self.dt):
            raise PlanningError(f'horizon must be a finite number >= '
                                f'{2 * self.knot_spacing:g} s (two knots), got {horizon!r}')
        return horizon
