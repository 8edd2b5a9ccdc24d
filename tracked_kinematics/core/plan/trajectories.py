"""
Canonical reference trajectories: Fink & Stump Table V and three of ours.

Table V: a trapezoidal speed profile ``p_v = [v0, a0, v_trav, af, vf]`` (Fig. 3(a)) and a
curvature through evenly spaced knots ``kappa_0..kappa_5`` (Fig. 3(b)). The paper does not
say how its splines interpolate; we use a monotone cubic (PCHIP), which does not overshoot
between knots (a natural cubic spline through ``[0, 0, 1.5, 0, 0, 0]`` turns the wrong way
between them). The desired path is the ideal differential drive's path of these inputs, as
in the paper (sec. IV-C). Straight, spin and lane change complete the set (not in Table V;
ours). The planner (:mod:`.planner`) follows these paths.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..integration import integrate_twist

CANONICAL = ('straight', 'left', 'right', 's_curve', 'lane_change', 'spin')


def trapezoid_profile(t, t_f: float, v0: float = 0.0, a0: float = 5.0, v_trav: float = 1.0,
                      a_f: float = 5.0, v_f: float = 0.0) -> np.ndarray:
    """
    Trapezoidal profile ``[v0, a0, v_trav, af, vf]`` of Fink & Stump Fig. 3(a).

    Ramps from ``v0`` toward ``v_trav`` at ``a0``, travels, and ramps to ``v_f`` at ``a_f``
    so as to arrive at ``t_f``; when the ramps meet before ``v_trav`` the profile turns at
    their crossing.

    Parameters
    ----------
    t : array_like
        Times, s, in ``[0, t_f]``.
    t_f : float
        Duration, s.
    v0, v_trav, v_f : float
        Initial, travelling and final values (same sign, ``|v_trav|`` the largest).
    a0, a_f : float
        Ramp rates, > 0 (unit of ``v`` per second).

    Returns
    -------
    ndarray
        The profile at ``t``.

    """
    t = np.asarray(t, dtype=float)
    if not (a0 > 0.0 and a_f > 0.0):
        raise ValueError(f'ramp rates must be > 0, got a0={a0!r}, a_f={a_f!r}')
    sign = -1.0 if v_trav < 0.0 else 1.0
    rise = sign * v0 + a0 * t
    fall = sign * v_f + a_f * (t_f - t)
    return sign * np.minimum(np.minimum(rise, fall), abs(v_trav))


def curvature_profile(t, t_f: float, knots) -> np.ndarray:
    """
    Curvature through knots evenly spaced over ``[0, t_f]`` (Fink & Stump Fig. 3(b)).

    Interpolated by a monotone cubic (PCHIP); see the module notes.

    Parameters
    ----------
    t : array_like
        Times, s.
    t_f : float
        Duration, s.
    knots : array_like, shape (K,), K >= 2
        Curvature at ``t_f * k / (K - 1)``, 1/m.

    Returns
    -------
    ndarray
        Curvature at ``t``, 1/m.

    """
    knots = np.asarray(knots, dtype=float)
    if knots.ndim != 1 or len(knots) < 2:
        raise ValueError('curvature knots must be a sequence of at least 2 values')
    return PchipInterpolator(np.linspace(0.0, t_f, len(knots)), knots)(t)


@dataclass(frozen=True)
class Reference:
    """
    Reference inputs and the path they give an ideal differential drive.

    Attributes
    ----------
    name : str
        Trajectory name.
    dt : float
        Sample period, s.
    v, w : ndarray, shape (N,)
        Reference forward speed (m/s) and turn rate (rad/s), held over each period.
    path : ndarray, shape (N + 1, 3)
        Desired path ``(x, y, theta)`` from the origin, ideal drive without drive train.

    """

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

    With the defaults, ``left``, ``right`` and ``s_curve`` are Table V exactly:
    ``p_v = [0 m/s, 5 m/s^2, 1 m/s, 5 m/s^2, 0 m/s]`` with the curvature knots
    ``[0, 0, 1.5, 0, 0, 0]`` over 4 s (``p_L``), ``[0, 0, -1.5, 0, 0, 0]`` over 4 s
    (``p_R``), ``[0, 0, -1, 0, 1, 0]`` over 6 s (``p_S``). Ours: ``straight`` (4 s, zero
    curvature), ``lane_change`` (5 s, knots ``[0, 0.75, 0, -0.75, 0]``: a sideways offset
    with the heading back to zero) and ``spin`` (no forward speed, the turn rate a trapezoid
    to ``speed / 0.5 m`` rad/s lasting 3 s).

    Parameters
    ----------
    name : str
        One of :data:`CANONICAL`.
    dt : float
        Sample period, s.
    speed : float
        Travelling speed ``v_trav``, m/s (> 0); scale it to the vehicle.
    accel : float
        Ramp rates ``a0 = af`` of the speed profile, m/s^2.
    curvature_scale : float
        Factor on the curvature knots (a smaller vehicle turns tighter).

    Returns
    -------
    Reference

    Raises
    ------
    ValueError
        For an unknown name or a non-positive speed, accel or dt.

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
