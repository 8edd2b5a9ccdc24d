"""
The EKF paper's simulations (sec. 4), rebuilt: truth, sensors, and how to score a filter.

The paper gives its settings in words; what it does not say is ours and marked in
:func:`abrupt_change` and :func:`low_rate`. :class:`VelocityEkf` is the velocity-based method of
its ref. [5]; :func:`prediction_errors` scores 2-s predictions as its Figs. 6, 8, 11.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .ekf import EstimatorConfig, model_icr
from ..integration import integrate, relative_pose, wrap_angle
from ..models import AdaptiveIcr, ConstantIcr, IdealDiffDrive, MotionModel

PAPER_TRACK_WIDTH = 2.464
"""Distance between the track centrelines of the paper's 13.6-t vehicle, m (sec. 5.1)."""


@dataclass(frozen=True)
class Scenario:
    """
    One simulated run: the truth and what the sensors saw (SI units).

    ``t_fine``, ``v_left``, ``v_right``: fine grid and true track speeds per step; ``truth`` (N +
    1, 3) and ``true_icr`` (N, 3); encoder steps ``enc_t, enc_left, enc_right, enc_dt`` (end time,
    travel, duration); noisy ``poses`` at ``pose_t``.
    """

    track_width: float
    t_fine: np.ndarray
    v_left: np.ndarray
    v_right: np.ndarray
    truth: np.ndarray
    true_icr: np.ndarray
    enc_t: np.ndarray
    enc_left: np.ndarray
    enc_right: np.ndarray
    enc_dt: np.ndarray
    pose_t: np.ndarray
    poses: np.ndarray

    @property
    def fine_dt(self) -> float:
        """Return the fine step, s."""
        return float(self.t_fine[1] - self.t_fine[0])

    def truth_at(self, t) -> np.ndarray:
        """Return the true poses at times ``t`` (on the fine grid, nearest sample)."""
        index = np.clip(np.rint(np.asarray(t) / self.fine_dt).astype(int), 0,
                        len(self.truth) - 1)
        return self.truth[index]

    def icr_at(self, t) -> np.ndarray:
        """Return the true ICRs at times ``t``."""
        index = np.clip(np.rint(np.asarray(t) / self.fine_dt).astype(int), 0,
                        len(self.true_icr) - 1)
        return self.true_icr[index]


def _sensors(track_width, t_fine, v_left, v_right, twist, icr, encoder_rate, pose_rate,
             pose_std_xy, pose_std_yaw, rng) -> Scenario:
    dt = float(t_fine[1] - t_fine[0])
    v_x, v_y, w = twist
    x, y, yaw = integrate(v_x * dt, v_y * dt, w * dt)
    truth = np.column_stack([np.concatenate([[0.0], x]), np.concatenate([[0.0], y]),
                             np.concatenate([[0.0], yaw])])
    cum_left = np.concatenate([[0.0], np.cumsum(v_left * dt)])
    cum_right = np.concatenate([[0.0], np.cumsum(v_right * dt)])
    enc_every = int(round(1.0 / (encoder_rate * dt)))
    enc_index = np.arange(enc_every, len(t_fine) + 1, enc_every)
    enc_t = enc_index * dt
    enc_left = np.diff(np.concatenate([[0.0], cum_left[enc_index]]))
    enc_right = np.diff(np.concatenate([[0.0], cum_right[enc_index]]))
    pose_every = int(round(1.0 / (pose_rate * dt)))
    pose_index = np.arange(0, len(t_fine) + 1, pose_every)
    noise = rng.normal(size=(len(pose_index), 3)) * [pose_std_xy, pose_std_xy, pose_std_yaw]
    poses = truth[pose_index] + noise
    poses[:, 2] = wrap_angle(poses[:, 2])
    return Scenario(track_width, t_fine, v_left, v_right, truth, icr, enc_t, enc_left,
                    enc_right, np.full(len(enc_t), enc_every * dt), pose_index * dt, poses)


def abrupt_change(seed: int = 0, encoder_rate: float = 100.0, pose_rate: float = 10.0,
                  pose_std_xy: float = 0.02, pose_std_yaw: float = 0.01,
                  duration: float = 20.0) -> Scenario:
    """
    Sec. 4.1: straight, then an arc where the ICRs jump at 2 s and again at 12 s.

    The paper's: 13.6 t, ICRs +-1.23 -> (2.23, -2.23, 0.5) m, 10 Hz poses, 100 Hz encoders. Ours:
    the second jump's values (1.73, -1.73, 0.25) m, the 20 s end, pose noise 2 cm / 0.01 rad (the
    paper: "similar to the errors of the sensor devices").
    """
    dt = 1e-3
    t = np.arange(int(round(duration / dt))) * dt
    half = 0.5 * PAPER_TRACK_WIDTH
    v_left = np.full_like(t, 2.0)
    v_right = np.where(t < 2.0, 2.0, 1.0)
    icr = np.where((t < 2.0)[:, None], [half, -half, 0.0],
                   np.where((t < 12.0)[:, None], [2.23, -2.23, 0.5], [1.73, -1.73, 0.25]))
    span = icr[:, 0] - icr[:, 1]
    w = (v_right - v_left) / span
    twist = ((v_right * icr[:, 0] - v_left * icr[:, 1]) / span, -icr[:, 2] * w, w)
    return _sensors(PAPER_TRACK_WIDTH, t, v_left, v_right, twist, icr, encoder_rate,
                    pose_rate, pose_std_xy, pose_std_yaw, np.random.default_rng(seed))


LOW_RATE_TRUE_P = np.array([1.2, 0.4, 1.0, 0.3, 0.5, 0.1])
"""True coefficients of eq. (11) in :func:`low_rate` (m per m/s^2, m per 1/m)."""


def low_rate(seed: int = 0, encoder_rate: float = 10.0, pose_rate: float = 1.0,
             pose_std_xy: float = 0.02, pose_std_yaw: float = 0.01,
             duration: float = 40.0) -> Scenario:
    """
    Sec. 4.2: 1 Hz poses, 10 Hz encoders, varying speeds, speed-dependent ICRs.

    Ours: the speed profiles (two sines, as a driver's) and the true eq. (11) coefficients
    :data:`LOW_RATE_TRUE_P`.
    """
    dt = 1e-3
    t = np.arange(int(round(duration / dt))) * dt
    v_left = 1.6 + 0.6 * np.sin(2.0 * np.pi * t / 7.0)
    v_right = 1.2 - 0.7 * np.sin(2.0 * np.pi * t / 5.0 + 1.0)
    model = AdaptiveIcr(PAPER_TRACK_WIDTH)
    y_left, y_right, x, _ = model._floored_icr(LOW_RATE_TRUE_P, v_left, v_right)
    twist = model.twist(LOW_RATE_TRUE_P, v_left, v_right)
    return _sensors(PAPER_TRACK_WIDTH, t, v_left, v_right, twist,
                    np.column_stack([y_left, y_right, x]), encoder_rate, pose_rate,
                    pose_std_xy, pose_std_yaw, np.random.default_rng(seed))


@dataclass(frozen=True)
class Run:
    """A filter's history over a scenario per pose time ``t``: parameters ``p``, ICRs, outcomes."""

    t: np.ndarray
    p: np.ndarray
    icr: np.ndarray
    status: list


def run_filter(scenario: Scenario, estimator, heading_only: bool = False) -> Run:
    """Feed a scenario's encoder steps and poses, in time order, to a filter."""
    times, ps, icrs, status = [], [], [], []
    k = 0
    n_enc = len(scenario.enc_t)
    for t, pose in zip(scenario.pose_t, scenario.poses):
        while k < n_enc and scenario.enc_t[k] <= t + 1e-9:
            estimator.add_step(scenario.enc_t[k], scenario.enc_left[k], scenario.enc_right[k],
                               scenario.enc_dt[k])
            k += 1
        if heading_only:
            outcome = estimator.add_heading(t, pose[2])
        else:
            outcome = estimator.add_pose(t, *pose)
        times.append(t)
        ps.append(estimator.p.copy())
        icrs.append(estimator.icr())
        status.append(outcome.status)
    return Run(np.array(times), np.array(ps), np.array(icrs), status)


def settling_time(run: Run, scenario: Scenario, t_change: float, tolerance: float = 0.1,
                  until: float = math.inf) -> float:
    """Seconds after ``t_change`` until the estimated ICRs stay within ``tolerance`` m (or inf)."""
    window = (run.t >= t_change) & (run.t < until)
    t = run.t[window]
    error = np.max(np.abs(run.icr[window] - scenario.icr_at(t)), axis=1)
    bad = np.nonzero(error > tolerance)[0]
    if len(bad) == 0:
        return 0.0 if len(t) else math.inf
    if bad[-1] == len(t) - 1:
        return math.inf
    return float(t[bad[-1] + 1] - t_change)


def prediction_errors(scenario: Scenario, model: MotionModel, run: Run, horizon: float = 2.0,
                      start: float = 0.0):
    """
    End-of-horizon errors of slip and no-slip predictions from every pose time.

    From the true pose at each ``t_k >= start``, the recorded track speeds are integrated with the
    estimate of ``t_k`` and with ideal drive; returns ``t`` and ``slip_position``,
    ``noslip_position`` (m), ``slip_heading``, ``noslip_heading`` (rad).
    """
    dt = scenario.fine_dt
    steps = int(round(horizon / dt))
    ideal = IdealDiffDrive(scenario.track_width)
    out = {key: [] for key in ('t', 'slip_position', 'noslip_position', 'slip_heading',
                               'noslip_heading')}
    for t, p in zip(run.t, run.p):
        i = int(round(t / dt))
        if t < start or i + steps > len(scenario.v_left):
            continue
        d_left = scenario.v_left[i:i + steps] * dt
        d_right = scenario.v_right[i:i + steps] * dt
        start_pose = scenario.truth[i]
        end = scenario.truth[i + steps]
        out['t'].append(t)
        for name, m, q in (('slip', model, p), ('noslip', ideal, ())):
            x, y, yaw = m.integrate(q, d_left, d_right, dt, pose0=tuple(start_pose))
            out[f'{name}_position'].append(math.hypot(x[-1] - end[0], y[-1] - end[1]))
            out[f'{name}_heading'].append(abs(wrap_angle(yaw[-1] - end[2])))
    return {key: np.array(value) for key, value in out.items()}


class VelocityEkf:
    """
    The traditional method (the paper's ref. [5]): update from differentiated poses.

    The pose change over an interval, divided by it, against the model's twist at the latest track
    speeds: biased with low-rate poses (sec. 4.2).
    """

    def __init__(self, model: MotionModel, p0=None, config: EstimatorConfig | None = None):
        self.model = model
        self.config = config or EstimatorConfig()
        self.p = model.initial() if p0 is None else np.asarray(p0, float).copy()
        self.P = np.eye(model.n_params) * self.config.initial_std ** 2
        self.last_speeds = (0.0, 0.0)
        self._previous = None

    def add_step(self, t, d_left, d_right, dt):
        """Record the latest track speeds."""
        self.last_speeds = (d_left / dt, d_right / dt)

    def add_pose(self, t, x, y, yaw):
        """Update from the velocity between this pose and the previous one."""
        previous, self._previous = self._previous, (t, x, y, yaw)
        if previous is None:
            return _Status('anchored')
        span = t - previous[0]
        dx, dy, dyaw = relative_pose(*previous[1:], x, y, yaw)
        z = np.array([dx, dy, dyaw]) / span
        twist, jac = self.model.twist_and_jacobian(self.p, *self.last_speeds)
        h, H = twist[0], jac[0]
        cfg = self.config
        pos = 2.0 * cfg.pose_std_xy ** 2 / span ** 2
        R = np.diag([pos, pos, 2.0 * cfg.pose_std_yaw ** 2 / span ** 2])
        P = self.P + np.eye(len(self.p)) * cfg.process_std ** 2 * span
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        innovation = z - h
        self.p = self.p + K @ innovation
        A = np.eye(len(self.p)) - K @ H
        P = A @ P @ A.T + K @ R @ K.T
        self.P = 0.5 * (P + P.T)
        return _Status('updated')

    def icr(self):
        """Estimated ICRs at the latest track speeds."""
        return model_icr(self.model, self.p, *self.last_speeds)


@dataclass(frozen=True)
class _Status:
    status: str


def icr_error(run: Run, scenario: Scenario, start: float = 0.0) -> float:
    """Mean of the largest ICR coordinate error (m) over the pose times from ``start``."""
    keep = run.t >= start
    return float(np.mean(np.max(np.abs(run.icr[keep] - scenario.icr_at(run.t[keep])), axis=1)))


def paper_models(track_width: float = PAPER_TRACK_WIDTH):
    """Return the paper's model (adaptive ICRs) and the constant-ICR alternative."""
    return AdaptiveIcr(track_width), ConstantIcr(track_width, with_scales=False)
