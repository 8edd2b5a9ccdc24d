"""
Canonical reference trajectories: Fink & Stump Table V and three of ours.

A trapezoidal speed (Fig. 3(a)) and a curvature through knots (Fig. 3(b)), interpolated by PCHIP
(the paper does not say how; a natural spline overshoots); the desired path is the ideal drive's
(sec. IV-C). See docs/tools/plan_trajectory.md, "How it plans".
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..integration import integrate_twist

CANONICAL = ('straight', 'left', 'right', 's_curve', 'lane_change', 'spin')


def trapezoid_profile(t, t_f: float, v0: float = 0.0, a0: float = 5.0, v_trav: float = 1.0,
                      a_f: float = 5.0, v_f: float = 0.0) -> np.ndarray:
    """
    Trapezoidal profile ``[v0, a0, v_trav, af, vf]`` of Fink & Stump Fig. 3(a) at times ``t``.

    Ramps at ``a0`` and ``a_f`` (> 0, per s) to arrive at ``t_f`` (s); turns at the ramps' crossing
    when they meet before ``v_trav`` (``|v_trav|`` the largest, same signs).
    """
    t = np.asarray(t, dtype=float)
    if not (a0 > 0.0 and a_f > 0.0):
        raise ValueError(f'ramp rates must be > 0, got a0={a0!r}, a_f={a_f!r}')
    sign = -1.0 if v_trav < 0.0 else 1.0
    rise = sign * v0 + a0 * t
    fall = sign * v_f + a_f * (t_f - t)
    return sign * np.minimum(np.minimum(rise, fall), abs(v_trav))


def curvature_profile(t, t_f: float, knots) -> np.ndarray:
    """Curvature (1/m) at ``t``, PCHIP through ``knots`` spread over ``[0, t_f]`` (Fig. 3(b))."""
    knots = np.asarray(knots, dtype=float)
    if knots.ndim != 1 or len(knots) < 2:
        raise ValueError('curvature knots must be a sequence of at least 2 values')
    from scipy.interpolate import PchipInterpolator   # lazily, as the planner's scipy
    return PchipInterpolator(np.linspace(0.0, t_f, len(knots)), knots)(t)


@dataclass(frozen=True)
class Reference:
    """Reference inputs ``v`` (m/s), ``w`` (rad/s) per ``dt`` s, and the ideal drive's path."""

    name: str
    dt: float
    v: np.ndarray
    w: np.ndarray
    path: np.ndarray

    @property
    def duration(self) -> float:
        """Length of the reference, s."""
        return len(self.v) * self.dt

    @property
    def goal(self) -> np.ndarray:
        """Return the final pose of the desired path."""
        return self.path[-1].copy()

    def tracks(self, track_width: float) -> np.ndarray:
        """Track speeds ``(N, 2)`` of the reference inputs for an ideal drive."""
        half = 0.5 * float(track_width)
        return np.column_stack([self.v - half * self.w, self.v + half * self.w])


def reference(name: str, v, w, dt: float) -> Reference:
    """Build a :class:`Reference` from inputs held over periods of ``dt``."""
    v = np.asarray(v, dtype=float)
    w = np.asarray(w, dtype=float)
    x, y, th = integrate_twist(v, np.zeros_like(v), w, dt)
    path = np.column_stack([np.r_[0.0, x], np.r_[0.0, y], np.r_[0.0, th]])
    return Reference(name, float(dt), v, w, path)


def canonical(name: str, dt: float = 0.02, speed: float = 1.0, accel: float = 5.0,
              curvature_scale: float = 1.0) -> Reference:
    """
    Canonical reference trajectory, Fink & Stump Table V and three of ours.

    With the defaults, ``left``, ``right`` and ``s_curve`` are Table V exactly (``p_v = [0, 5, 1,
    5, 0]``, knots ``[0, 0, +-1.5, 0, 0, 0]`` over 4 s and ``[0, 0, -1, 0, 1, 0]`` over 6 s). Ours:
    ``straight`` (4 s), ``lane_change`` (5 s, knots ``[0, 0.75, 0, -0.75, 0]``) and ``spin`` (turn
    rate a trapezoid to ``speed / 0.5 m`` rad/s for 3 s). ``speed`` (m/s), ``accel`` (m/s^2) and
    ``curvature_scale`` scale them to the vehicle. ValueError for an unknown name or a non-positive
    speed, accel or dt.
    """
    for label, value in (('dt', dt), ('speed', speed), ('accel', accel)):
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f'{label} must be a finite number > 0, got {value!r}')
    table = {'straight': (4.0, [0.0, 0.0]),
             'left': (4.0, [0, 0, 1.5, 0, 0, 0]),
             'right': (4.0, [0, 0, -1.5, 0, 0, 0]),
             's_curve': (6.0, [0, 0, -1, 0, 1, 0]),
             'lane_change': (5.0, [0, 0.75, 0, -0.75, 0])}
    if name == 'spin':
        t_f = 3.0
        t = (np.arange(int(round(t_f / dt))) + 0.5) * dt
        w = trapezoid_profile(t, t_f, 0.0, 2.0 * accel, speed / 0.5, 2.0 * accel, 0.0)
        return reference(name, np.zeros_like(w), w, dt)
    if name not in table:
        raise ValueError(f'unknown canonical trajectory {name!r}; choose one of '
                         f'{", ".join(CANONICAL)}')
    t_f, knots = table[name]
    t = (np.arange(int(round(t_f / dt))) + 0.5) * dt
    v = trapezoid_profile(t, t_f, 0.0, accel, speed, accel, 0.0)
    kappa = curvature_scale * curvature_profile(t, t_f, knots)
    return reference(name, v, v * kappa, dt)
