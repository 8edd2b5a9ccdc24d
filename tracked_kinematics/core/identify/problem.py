"""
The least-squares problem of the identification: Martinez eq. (17) and its Jacobian.

``J(p) = sum_i (dx_i - dx^_i)^2 + (dy_i - dy^_i)^2 + lambda^2 (dphi_i - dphi^_i)^2`` over segments,
with Fink & Stump's sensitivities (eq. 4) in closed form for all segments at once. See
docs/model.md, "Sensitivities of a segment's end pose".
"""

from __future__ import annotations

import math

import numpy as np

from .segments import Segments
from ..errors import TrackedKinematicsError
from ..integration import integrate, relative_pose, wrap_angle
from ..models import MotionModel

LOSSES = ('soft_l1', 'huber', 'cauchy', 'linear')

DEFAULT_HEADING_WEIGHT = 1.0
"""
``lambda`` of eq. (17) unless told otherwise, m/rad: the paper's unweighted sum.

The one default of :class:`SegmentProblem`, :func:`.fitting.fit`, :func:`.procedure.identify`
and the ``--heading-weight`` option of ``identify_icr``; :func:`.procedure.identify` says
why it is not the noise-balancing ``auto`` weight (None, :func:`.fitting.auto_heading_weight`).
"""


def check_heading_weight(heading_weight) -> float:
    """Return a heading weight of eq. (17) as a float; TrackedKinematicsError unless finite > 0."""
    try:
        value = float(heading_weight)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(heading_weight, bool) or not (math.isfinite(value) and value > 0.0):
        raise TrackedKinematicsError(
            'the heading weight (lambda of eq. 17) must be a finite number > 0 m/rad, got '
            f'{heading_weight!r}')
    return value


def _chord_coefficients(dtheta):
    """``S``, ``C`` of :func:`..integration.arc_chord` and their derivatives (series near 0)."""
    t = np.asarray(dtheta, dtype=float)
    s = np.sinc(t / np.pi)
    c = 0.5 * t * np.sinc(t / (2.0 * np.pi)) ** 2
    small = np.abs(t) < 1e-3
    t_safe = np.where(small, 1.0, t)
    t2 = t * t
    ds = np.where(small, -t / 3.0 + t2 * t / 30.0,
                  (t_safe * np.cos(t_safe) - np.sin(t_safe)) / t_safe ** 2)
    one_minus_cos = 2.0 * np.sin(0.5 * t_safe) ** 2
    dc = np.where(small, 0.5 - t2 / 8.0 + t2 * t2 / 144.0,
                  (t_safe * np.sin(t_safe) - one_minus_cos) / t_safe ** 2)
    return s, c, ds, dc


class SegmentProblem:
    """
    Residuals of Martinez eq. (17) over a set of segments, and their Jacobian.

    ``heading_weight`` is ``lambda`` (m/rad). Residuals are ``[dx_0, dy_0, lambda dphi_0, dx_1,
    ...]``, measured minus predicted, heading wrapped to [-pi, pi).
    """

    def __init__(self, model: MotionModel, segments: Segments,
                 heading_weight: float = DEFAULT_HEADING_WEIGHT):
        if len(segments) == 0:
            raise TrackedKinematicsError('no segments')
        self.model = model
        self.segments = segments
        self.heading_weight = check_heading_weight(heading_weight)
        self._start = segments.start
        self._last = segments.stop - 1
        if not model.linear:
            self._v_left = segments.d_left / segments.dt
            self._v_right = segments.d_right / segments.dt

    def _increments(self, p, with_jacobian):
        """Body increments of every step (K, 3) and, if asked, their Jacobian (K, 3, P)."""
        seg = self.segments
        if self.model.linear:
            if not with_jacobian:
                return np.stack(self.model.twist(p, seg.d_left, seg.d_right), axis=-1), None
            return self.model.twist_and_jacobian(p, seg.d_left, seg.d_right)
        dt = seg.dt
        if not with_jacobian:
            twist = np.stack(self.model.twist(p, self._v_left, self._v_right), axis=-1)
            return twist * dt[:, None], None
        twist, jac = self.model.twist_and_jacobian(p, self._v_left, self._v_right)
        return twist * dt[:, None], jac * dt[:, None, None]

    def predict(self, p) -> np.ndarray:
        """Predicted pose increment of every segment, shape (S, 3), heading unwrapped."""
        u, _ = self._increments(np.asarray(p, float), False)
        x, y, th = (np.concatenate([[0.0], v]) for v in integrate(u[:, 0], u[:, 1], u[:, 2]))
        a, b = self._start, self._last + 1
        dx, dy, _ = relative_pose(x[a], y[a], th[a], x[b], y[b], th[b])
        return np.stack([dx, dy, th[b] - th[a]], axis=1)

    def _weigh(self, diff):
        diff = diff.copy()
        diff[:, 2] = self.heading_weight * wrap_angle(diff[:, 2])
        return diff.ravel()

    def residuals(self, p) -> np.ndarray:
        """Weighted residuals, shape (3 S,)."""
        return self._weigh(self.segments.truth - self.predict(p))

    def jacobian(self, p) -> np.ndarray:
        """Jacobian of :meth:`residuals`, shape (3 S, P): Fink & Stump eq. (4), per segment."""
        p = np.asarray(p, float)
        u, du = self._increments(p, True)
        x, y, th = integrate(u[:, 0], u[:, 1], u[:, 2])
        s, c, ds, dc = _chord_coefficients(u[:, 2])
        heading = th - u[:, 2]
        cos_h, sin_h = np.cos(heading), np.sin(heading)
        # World-frame chord derivative R(th_k) dc_k/du_k, as coefficients of du_k/dp; the
        # per-step terms are m_k du_k/dp, one batched (5 x 3) (3 x P) product.
        a_th = ds * u[:, 0] - dc * u[:, 1]
        b_th = dc * u[:, 0] + ds * u[:, 1]
        m = np.zeros((len(u), 5, 3))
        m[:, 0, 0] = cos_h * s - sin_h * c
        m[:, 0, 1] = -cos_h * c - sin_h * s
        m[:, 0, 2] = cos_h * a_th - sin_h * b_th
        m[:, 1, 0] = sin_h * s + cos_h * c
        m[:, 1, 1] = -sin_h * c + cos_h * s
        m[:, 1, 2] = sin_h * a_th + cos_h * b_th
        m[:, 2, 2] = 1.0
        m[:, 3, 2] = x
        m[:, 4, 2] = y
        terms = np.matmul(m, du)
        w_x, w_y, g_sum, xg, yg = np.moveaxis(self.segments.per_segment(terms), 1, 0)
        b = self._last
        # J (P_b G - sum P_k g_k), J (v_x, v_y) = (-v_y, v_x)
        d_x = w_x - (y[b][:, None] * g_sum - yg)
        d_y = w_y + (x[b][:, None] * g_sum - xg)
        th_a = heading[self._start][:, None]
        cos_a, sin_a = np.cos(th_a), np.sin(th_a)
        jac = np.empty((len(b), 3, len(p)))
        jac[:, 0] = -(cos_a * d_x + sin_a * d_y)
        jac[:, 1] = -(-sin_a * d_x + cos_a * d_y)
        jac[:, 2] = -self.heading_weight * g_sum
        return jac.reshape(-1, len(p))


def robust_cost(residuals, loss: str = 'linear', f_scale: float = 1.0) -> float:
    """Cost ``0.5 sum f^2 rho((r / f)^2)`` exactly as scipy's ``least_squares`` defines it."""
    z = (np.asarray(residuals, dtype=float) / f_scale) ** 2
    if loss == 'linear':
        rho = z
    elif loss == 'soft_l1':
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == 'huber':
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    elif loss == 'cauchy':
        rho = np.log1p(z)
    else:
        raise ValueError(f'loss must be one of {", ".join(LOSSES)}, got {loss!r}')
    return float(0.5 * f_scale ** 2 * np.sum(rho))
