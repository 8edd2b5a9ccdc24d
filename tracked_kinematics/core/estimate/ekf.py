"""
Online estimation of the slip-model parameters by an EKF, after the EKF paper (sec. 3).

State: a motion model's parameters as a random walk (eq. 15); measurement: a pose change over a
window (eqs. 16-18); the Jacobian of eq. (19) is lost from the text, we use the exact integration
sensitivities (Fink & Stump eq. 4); Joseph-form update (eqs. 20-21). Gates, re-anchoring and what
real pose sources needed: docs/nodes/icr_estimator.md, "How it works, and what we reconstructed".
"""

from __future__ import annotations

from collections import deque
import functools
import math

import numpy as np

from .config import EstimatorConfig, Outcome
from ..identify import SegmentProblem, Segments
from ..integration import relative_pose, wrap_angle
from ..kinematics import IcrParams
from ..models import AdaptiveIcr, ConstantIcr, MotionModel

__all__ = ['EstimatorConfig', 'model_icr', 'Outcome', 'SlipEstimator']


@functools.lru_cache(maxsize=16)
def _gate(probability: float, dof: int) -> float:
    """Chi-square quantile of the innovation gate (cached: scipy's is slow per call)."""
    from scipy.stats import chi2   # 0.6 s to import: not at every node's start
    return float(chi2.ppf(probability, dof))


def model_icr(model: MotionModel, p, v_left: float, v_right: float):
    """Tread ICRs ``(y_left, y_right, x)`` (m) of a model at ``p``; TypeError if it has none."""
    if isinstance(model, AdaptiveIcr):
        y_left, y_right, x, _ = model._floored_icr(p, v_left, v_right)
        return float(y_left), float(y_right), float(x)
    if isinstance(model, ConstantIcr):
        return float(p[0]), float(p[1]), float(p[2])
    icr = model.as_icr(p)
    if icr is None:
        raise TypeError(f'the {model.name} model has no tread ICRs')
    return icr.y_left, icr.y_right, icr.x


class _TravelLog:
    """Encoder steps ``(t_start, t_end, d_left, d_right)`` of the last ``span`` seconds."""

    def __init__(self, span: float):
        self.span = span
        self.steps: deque = deque()

    @property
    def end(self) -> float:
        return self.steps[-1][1] if self.steps else -math.inf

    def append(self, t_end: float, d_left: float, d_right: float, dt: float) -> None:
        self.steps.append((t_end - dt, t_end, d_left, d_right))
        while self.steps and self.steps[0][1] < t_end - self.span:
            self.steps.popleft()

    def window(self, t_a: float, t_b: float):
        """Clip the steps to ``[t_a, t_b]`` pro rata: travel, durations, covered fraction."""
        if not self.steps:
            return np.zeros(0), np.zeros(0), np.zeros(0), 0.0
        data = np.array(self.steps)
        lo = np.maximum(data[:, 0], t_a)
        hi = np.minimum(data[:, 1], t_b)
        keep = hi > lo
        full = data[keep, 1] - data[keep, 0]
        part = hi[keep] - lo[keep]
        frac = np.divide(part, full, out=np.ones_like(part), where=full > 0.0)
        covered = float(part.sum()) / (t_b - t_a)
        return data[keep, 2] * frac, data[keep, 3] * frac, part, covered


class SlipEstimator:
    """
    EKF over the parameters of a motion model, from encoder travel and pose measurements.

    ``p0`` defaults to ``model.initial()`` (ideal drive); other start values count as identified,
    and the prior and fallback of ``config`` hold them. Feed :meth:`add_step` every encoder step
    and :meth:`add_pose` / :meth:`add_heading` every pose, in time order; a pose ahead of the
    encoders waits. Attributes ``p``, ``P`` are the state and its covariance.
    """

    def __init__(self, model: MotionModel, p0=None, config: EstimatorConfig | None = None):
        self.model = model
        self.config = config or EstimatorConfig()
        p0 = model.initial() if p0 is None else np.asarray(p0, dtype=float).copy()
        if p0.shape != (model.n_params,) or not np.all(np.isfinite(p0)):
            raise ValueError(f'p0 must be {model.n_params} finite numbers, got {p0!r}')
        self._p0 = p0.copy()
        self.p = p0
        self.P = np.eye(model.n_params) * self.config.initial_std ** 2
        self._log = _TravelLog(self.config.max_window + 1.0)
        self._history: deque = deque()   # accepted poses (t, x, y, yaw), newest last
        self._heading_only = False
        self._pending = None      # (t, pose, heading_only)
        self._t_state = None      # time of the covariance
        self._outliers = 0
        self._re_anchored = False  # re-anchored after refusals, no update since
        self.updates = 0
        self.last_speeds = (0.0, 0.0)
        self.noise_scale = 1.0
        self._excess: deque = deque(maxlen=self.config.noise_memory)
        self._costs: deque = deque()   # (t, filter cost, start-value cost) of recent windows
        self._trusted = False          # the filter earned its place over the start values

    # --- inputs -------------------------------------------------------------------------

    def add_step(self, t: float, d_left: float, d_right: float, dt: float) -> Outcome | None:
        """
        Record nominal travel (m) of each track over ``dt`` s ending at ``t``.

        Returns the :class:`Outcome` of a deferred pose this step made processable, or None; raises
        ValueError for a non-finite value or ``dt <= 0``.
        """
        values = (t, d_left, d_right, dt)
        if not all(math.isfinite(v) for v in values) or dt <= 0.0:
            raise ValueError(f'encoder step must be finite with dt > 0, got {values!r}')
        if t < self._log.end - 1e-9:
            # Time went back (simulation reset, bag loop): the past no longer matches.
            self._log.steps.clear()
            self._history.clear()
            self._pending = None
        self._log.append(float(t), float(d_left), float(d_right), float(dt))
        self.last_speeds = (d_left / dt, d_right / dt)
        if self._pending is not None and self._pending[0] <= self._log.end:
            t_p, pose, heading_only = self._pending
            self._pending = None
            return self._measure(t_p, pose, heading_only)
        return None

    def add_pose(self, t: float, x: float, y: float, yaw: float) -> Outcome:
        """Process a full pose measurement (position in any fixed frame, m; yaw, rad)."""
        return self._receive(t, (x, y, yaw), False)

    def add_heading(self, t: float, yaw: float) -> Outcome:
        """Process a heading-only measurement (rad), e.g. an IMU while RTK GPS is out."""
        return self._receive(t, (math.nan, math.nan, yaw), True)

    def configure(self, config: EstimatorConfig) -> None:
        """Use new noise, window and gate settings from the next measurement on."""
        self.config = config
        self._log.span = config.max_window + 1.0
        self._excess = deque(self._excess, maxlen=config.noise_memory)
        if not config.adaptive_noise:
            self._excess.clear()
            self.noise_scale = 1.0

    def set_initial(self, p0) -> None:
        """Set the parameters :meth:`reset` returns to (the estimate itself is kept)."""
        p0 = np.asarray(p0, dtype=float)
        if p0.shape != self._p0.shape or not np.all(np.isfinite(p0)):
            raise ValueError(f'p0 must be {len(self._p0)} finite numbers, got {p0!r}')
        if not np.array_equal(p0, self._p0):
            self._costs.clear()
            self._trusted = False
        self._p0 = p0.copy()

    def reset(self, p0=None) -> None:
        """Forget the anchor and restart from ``p0`` (default: the initial parameters)."""
        self.p = (self._p0 if p0 is None else np.asarray(p0, float)).copy()
        self.P = np.eye(self.model.n_params) * self.config.initial_std ** 2
        self._history.clear()
        self._pending = None
        self._t_state = None
        self._outliers = 0
        self._re_anchored = False
        self._costs.clear()
        self._trusted = False

    # --- outputs ------------------------------------------------------------------------

    @property
    def informed(self) -> bool:
        """Tell whether the start values are identified ones (not ideal drive)."""
        return not np.allclose(self._p0, self.model.initial(), rtol=0.0, atol=1e-12)

    @property
    def estimate(self) -> np.ndarray:
        """
        Return the parameters the estimator stands behind: what to predict and publish with.

        The state :attr:`p`, except with ``fallback`` and identified start values: those until the
        filter's a-priori predictions over ``fallback_span`` s beat theirs by ``fallback_margin``.
        """
        if self._trusted or not self.config.fallback:
            return self.p
        return self._p0

    def icr(self, v_left: float | None = None, v_right: float | None = None):
        """Tread ICRs (m) of the :attr:`estimate`, at the given (default: latest) track speeds."""
        if v_left is None:
            v_left, v_right = self.last_speeds
        return model_icr(self.model, self.estimate, v_left, v_right)

    def icr_params(self, v_left=None, v_right=None, scales=(1.0, 1.0)) -> IcrParams | None:
        """Return the estimate as terrain parameters, or None while it is not physical."""
        y_left, y_right, x = self.icr(v_left, v_right)
        try:
            return IcrParams(self.model.track_width, y_left, y_right, x, *scales)
        except ValueError:
            return None

    def pose_now(self):
        """Return ``(t, x, y, yaw)``: the last pose dead-reckoned to the last step, or None."""
        if not self._history or self._heading_only:
            return None
        t_a, x, y, yaw = self._history[-1]
        t_b = self._log.end
        if t_b <= t_a:
            return t_a, x, y, yaw
        d_left, d_right, dt, _ = self._log.window(t_a, t_b)
        if len(dt) == 0:
            return t_a, x, y, yaw
        xs, ys, yaws = self.model.integrate(self.estimate, d_left, d_right, dt,
                                            pose0=(x, y, yaw))
        return t_b, float(xs[-1]), float(ys[-1]), float(yaws[-1])

    @property
    def std(self) -> np.ndarray:
        """Return the standard deviations of the parameters."""
        return np.sqrt(np.diag(self.P))

    # --- the filter ---------------------------------------------------------------------

    def _receive(self, t, pose, heading_only) -> Outcome:
        t = float(t)
        measured = pose[2:] if heading_only else pose
        if not math.isfinite(t) or not all(math.isfinite(v) for v in measured):
            return Outcome('non_finite', f'non-finite pose measurement {pose!r} at t={t!r}')
        t -= self.config.pose_delay
        if self._history and t <= self._history[-1][0]:
            if t >= self._history[-1][0] - self.config.max_window:
                return Outcome('stale', f'pose stamp {t:.3f} s is not after the previous '
                                        f'one ({self._history[-1][0]:.3f} s)')
            # Far in the past: the pose source's clock was reset; so are the windows.
            self._history.clear()
        if self._history and heading_only != self._heading_only:
            # A switch between full poses and headings: the windows do not compare.
            self._history.clear()
        self._heading_only = heading_only
        if t > self._log.end:
            # A newer pose replaces one still waiting: the window then simply starts later.
            self._pending = (t, pose, heading_only)
            return Outcome('deferred', 'waiting for encoder data up to the pose stamp')
        return self._measure(t, pose, heading_only)

    def _restart(self, t, pose) -> None:
        """Forget the past poses: windows start at this one."""
        self._history.clear()
        self._history.append((t, *pose))

    def _anchor_for(self, t):
        """Past pose starting the window ending at ``t`` (newest ``window`` s old, or oldest)."""
        cfg = self.config
        while self._history and t - self._history[0][0] > cfg.max_window:
            self._history.popleft()
        anchor = None
        for past in self._history:
            if t - past[0] < cfg.window:
                break
            anchor = past
        if anchor is None and self._history:
            anchor = self._history[0]
        return anchor

    def _measure(self, t, pose, heading_only) -> Outcome:
        cfg = self.config
        anchor = self._anchor_for(t)
        if anchor is None:
            self._restart(t, pose)
            return Outcome('anchored', 'no recent pose: the next window starts here')
        t_a = anchor[0]
        if t - t_a < cfg.min_window:
            return Outcome('short', f'window {t - t_a:.3f} s < min_window {cfg.min_window:g} s')
        d_left, d_right, dt, covered = self._log.window(t_a, t)
        if covered < cfg.min_coverage or len(dt) == 0:
            self._restart(t, pose)
            return Outcome('gap', f'encoder data cover {100 * covered:.0f} % of the '
                                  f'{t - t_a:.2f} s window: window restarts here')
        z = self._measurement(anchor, pose, heading_only)
        # Time update, eq. (20): random walk since the last update (or the prior's pull).
        p, P = self._time_update(0.0 if self._t_state is None else max(0.0, t - self._t_state))
        h, H = self._predict(d_left, d_right, dt, p)
        travel = 0.5 * float(np.sum(np.abs(d_left) + np.abs(d_right)))
        fixed, per_travel = self._noise_parts(travel, z)
        innovation = z - h
        innovation[-1] = wrap_angle(innovation[-1])
        if not heading_only:
            self._learn_noise(innovation, np.diag(H @ P @ H.T) + fixed, per_travel, travel)
        R = np.diag(fixed + self.noise_scale * per_travel)
        rows = [2] if heading_only else [0, 1, 2]
        H, R, innovation = H[rows], R[np.ix_(rows, rows)], innovation[rows]
        S = H @ P @ H.T + R
        nis = float(innovation @ np.linalg.solve(S, innovation))
        gate = _gate(cfg.gate_probability, len(rows))
        self._score(t, gate, d_left, d_right, dt, z, innovation, R, rows)
        if nis > gate:
            self._outliers += 1
            if self._outliers >= cfg.max_outliers:
                self._outliers = 0
                self._restart(t, pose)
                self.p, self.P, self._t_state = p, P, t
                if not self._re_anchored:
                    # A re-localised pose source: the windows from the new anchor agree.
                    self._re_anchored = True
                    return Outcome('anchored', f'{cfg.max_outliers} windows in a row disagree '
                                               'with the model: re-anchored', nis)
                # The windows from the new anchor disagree too: the terrain changed. (With a
                # prior, never wider than it: the terrain stays within it of the start.)
                self._re_anchored = False
                self.P = P + np.eye(len(p)) * min(cfg.initial_std, self._prior()) ** 2
                return Outcome('anchored', f'{cfg.max_outliers} windows in a row disagree '
                                           'with the model again: re-anchored, covariance '
                                           'widened', nis)
            return Outcome('outlier', f'pose change disagrees with the prediction (NIS '
                                      f'{nis:.1f}): refused as a jump', nis)
        # Measurement update, eq. (21), in Joseph form (stays symmetric positive definite).
        K = np.linalg.solve(S, H @ P).T
        p = p + K @ innovation
        if not self._physical(p):
            self._restart(t, pose)
            return Outcome('invalid', 'the update would put the left ICR right of the right '
                                      'one: window skipped', nis)
        A = np.eye(len(p)) - K @ H
        P = A @ P @ A.T + K @ R @ K.T
        self.P = 0.5 * (P + P.T)
        self.p = p
        self._t_state = t
        self._outliers = 0
        self._re_anchored = False
        self.updates += 1
        self._history.append((t, *pose))
        return Outcome('updated', '', nis)

    def _prior(self) -> float:
        """Spread of the parameters about the start values (inf: the paper's random walk)."""
        if not self.informed:
            return math.inf
        return self.config.prior_std * self.model.track_width

    def _time_update(self, elapsed: float):
        """
        Predicted state and covariance ``elapsed`` s after the last update.

        Random walk, eq. (15): ``P + process_std^2 elapsed``. With a finite prior, the exact
        Ornstein-Uhlenbeck step about ``p0`` instead (ours, not the paper's): ``p0 + a (p - p0)``,
        ``a^2 P + prior^2 (1 - a^2)``, ``a = exp(-elapsed / prior_time)``.
        """
        n = len(self.p)
        prior = self._prior()
        if math.isinf(prior) or elapsed == 0.0:
            return self.p, self.P + np.eye(n) * self.config.process_std ** 2 * elapsed
        a = math.exp(-elapsed / self.config.prior_time)
        return (self._p0 + a * (self.p - self._p0),
                a * a * self.P + np.eye(n) * prior ** 2 * (1.0 - a * a))

    def _learn_noise(self, innovation, known, per_travel, travel) -> None:
        """
        Update the adaptive factor on ``travel_std^2`` from one full-pose window.

        Per window ``s_k = (|nu|^2 - tr(H P H^T + R_fixed)) / tr(R_travel)`` (method of moments);
        the factor is the median over the last ``noise_memory`` moving windows, at least 1.
        """
        cfg = self.config
        unit = float(per_travel.sum())
        if not cfg.adaptive_noise or unit <= 0.0 or travel < 0.1 * self.model.track_width:
            return
        self._excess.append((float(innovation @ innovation) - float(known.sum())) / unit)
        if len(self._excess) >= 20:
            self.noise_scale = max(1.0, float(np.median(self._excess)))

    def _score(self, t, gate, d_left, d_right, dt, z, innovation, R, rows) -> None:
        """Record what the filter and the start values predicted of this window (fallback)."""
        cfg = self.config
        if not cfg.fallback:
            return
        h0, _ = self._predict(d_left, d_right, dt, self._p0, jacobian=False)
        nu0 = (z - h0)[rows]
        nu0[-1] = wrap_angle(nu0[-1])
        var = np.diag(R)
        # The same yardstick for both: squared errors over the measurement noise (the
        # filter's own uncertainty must not excuse its errors), capped at the gate.
        self._costs.append((t, min(float(np.sum(innovation ** 2 / var)), gate),
                            min(float(np.sum(nu0 ** 2 / var)), gate)))
        while self._costs and self._costs[0][0] < t - cfg.fallback_span:
            self._costs.popleft()
        if len(self._costs) >= 10:
            costs = np.array([c[1:] for c in self._costs])
            self._trusted = bool(costs[:, 0].sum() < (1.0 - cfg.fallback_margin)
                                 * costs[:, 1].sum())

    @staticmethod
    def _measurement(anchor, pose, heading_only) -> np.ndarray:
        _, x_a, y_a, yaw_a = anchor
        if heading_only:
            return np.array([0.0, 0.0, wrap_angle(pose[2] - yaw_a)])
        dx, dy, dyaw = relative_pose(x_a, y_a, yaw_a, *pose)
        return np.array([dx, dy, dyaw], dtype=float)

    def _predict(self, d_left, d_right, dt, p=None, jacobian=True):
        """Predicted pose change of the window, eq. (14), and its Jacobian, eq. (19)."""
        p = self.p if p is None else p
        segment = Segments(d_left, d_right, dt, np.zeros(1, np.intp), np.zeros((1, 3)),
                           np.zeros(1), np.zeros(1), np.zeros(1, np.intp))
        problem = SegmentProblem(self.model, segment)
        h = problem.predict(p)[0]
        if not jacobian:
            return h, None
        # SegmentProblem's Jacobian is that of measured - predicted.
        H = -problem.jacobian(p) if self.model.n_params else np.zeros((3, 0))
        return h, H

    def _noise_parts(self, travel, z):
        """Diagonals ``(fixed, per_travel)`` of a window's measurement noise."""
        cfg = self.config
        distance2 = float(z[0] ** 2 + z[1] ** 2)
        pos = 2.0 * cfg.pose_std_xy ** 2 + cfg.pose_std_yaw ** 2 * distance2
        yaw = 2.0 * cfg.pose_std_yaw ** 2
        travel2 = (cfg.travel_std * travel) ** 2
        # The noise model's random walks over the window (docs/nodes/icr_estimator.md): the
        # tracks' travel, the heading and the position per radian turned (the measured turn).
        turned = abs(float(z[2]))
        width2 = self.model.track_width ** 2
        model_pos = 0.5 * cfg.track_noise * travel + cfg.slip_noise * turned
        model_yaw = 2.0 * cfg.track_noise * travel / width2 + cfg.turn_noise * turned
        return (np.array([pos, pos, yaw]),
                np.array([travel2 + model_pos, travel2 + model_pos,
                          2.0 * travel2 / width2 + model_yaw]))

    def _physical(self, p) -> bool:
        if not np.all(np.isfinite(p)):
            return False
        if isinstance(self.model, ConstantIcr):
            return bool(p[0] - p[1] > 0.01 * self.model.track_width)
        return True
