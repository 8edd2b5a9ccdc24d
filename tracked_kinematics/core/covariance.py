"""
Linearised error propagation for tracked-vehicle odometry (Kelly 2004).

Each track's travel error has variance ``k |d| + floor`` (a random walk in distance), propagated as
``P_k = F P_{k-1} F^T + G Q G^T`` along exact arcs; the twist variance is that of the mean speed
over :data:`TWIST_TIME` (our choice, not the papers'). See docs/nodes/odometry_node.md, "Covariance
model".
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .kinematics import IcrParams

# Variance published for the dimensions planar odometry does not observe (z, roll, pitch,
# and their rates): large, so that a filter such as robot_localization ignores them, but
# not infinite and never zero.
UNOBSERVED_VARIANCE = 1e6

# Time over which the travel noise of the model is taken to be correlated, s: the twist
# covariance is that of the mean speed over this long (module docstring).
TWIST_TIME = 1.0

# Largest variance of a pose coordinate (m^2) or of the heading (rad^2): a standard
# deviation of 1000 km, or of 10^6 rad, is "unknown" already.
MAX_VARIANCE = 1e12

# Below this |dtheta| the derivatives of the arc chord use their Taylor series (the
# closed forms lose digits to cancellation); the truncation error is below 2e-13.
_SMALL_ANGLE = 1e-2


@dataclass(frozen=True, slots=True)
class TrackNoise:
    """
    Travel noise of the two tracks: ``k_left``, ``k_right`` in m^2/m, ``floor`` in m^2/sample.

    Raises ValueError when any value is non-finite or negative.
    """

    k_left: float = 1e-3
    k_right: float = 1e-3
    floor: float = 1e-9

    def travel_variances(self, abs_left, abs_right, samples=1):
        """Variances (m^2) of the tracks' travel over distances ``abs_*`` (m), ``samples``."""
        floor = self.floor * samples
        return self.k_left * abs(abs_left) + floor, self.k_right * abs(abs_right) + floor


def body_jacobian(icr: IcrParams):
    """
    Jacobian ``B`` (3 x 2) of the body increments ``(dx, dy, dtheta)`` by the nominal travel.

    Martinez eqs. (7)-(9) with the scales of eqs. (20)-(21) are linear in the travel, so ``B`` is
    constant; it also maps nominal track speeds to the body twist.
    """
    span = icr.y_left - icr.y_right
    sl = icr.scale_left / span
    sr = icr.scale_right / span
    return ((-icr.y_right * sl, icr.y_left * sr),
            (icr.x * sl, -icr.x * sr),
            (-sl, sr))


def _chord_factors(t: float):
    """Return ``S = sin(t)/t``, ``C = (1 - cos(t))/t`` and their derivatives in ``t``."""
    if t == 0.0:
        return 1.0, 0.0, 0.0, 0.5
    sin_t = math.sin(t)
    s = sin_t / t
    c = 2.0 * math.sin(0.5 * t) ** 2 / t
    if abs(t) < _SMALL_ANGLE:
        t2 = t * t
        return s, c, t * (-1.0 / 3.0 + t2 / 30.0), 0.5 - t2 / 8.0 + t2 * t2 / 144.0
    return s, c, (math.cos(t) - s) / t, (sin_t - c) / t


def arc_step(theta0: float, dx: float, dy: float, dtheta: float):
    """
    Fixed-frame displacement of one exact arc step and its 2 x 3 Jacobian by ``(dx, dy, dtheta)``.

    On Python floats (called per encoder message); ``theta0`` in rad, increments in m, m, rad.
    """
    s, c, ds, dc = _chord_factors(dtheta)
    cos0 = math.cos(theta0)
    sin0 = math.sin(theta0)
    chord_x = s * dx - c * dy
    chord_y = c * dx + s * dy
    # d chord / d dtheta
    cx_t = ds * dx - dc * dy
    cy_t = dc * dx + ds * dy
    m = ((cos0 * s - sin0 * c, -cos0 * c - sin0 * s, cos0 * cx_t - sin0 * cy_t),
         (sin0 * s + cos0 * c, -sin0 * c + cos0 * s, sin0 * cx_t + cos0 * cy_t))
    return cos0 * chord_x - sin0 * chord_y, sin0 * chord_x + cos0 * chord_y, m


def travel_jacobian(m, body):
    """Jacobian ``G`` (3 x 2) of the pose after a step by the two tracks' nominal travel."""
    (b0l, b0r), (b1l, b1r), (b2l, b2r) = body
    rows = tuple((r0 * b0l + r1 * b1l + r2 * b2l, r0 * b0r + r1 * b1r + r2 * b2r)
                 for r0, r1, r2 in m)
    return rows + ((b2l, b2r),)


def propagate(p, delta_x, delta_y, g, var_left, var_right):
    """
    One step of linearised covariance propagation, ``F P F^T + G Q G^T``, exactly symmetric.

    ``F`` is the identity plus the column ``(-delta_y, delta_x, 0)`` on the heading (Kelly 2004).

    ``p`` and the result are upper triangles ``(xx, xy, xt, yy, yt, tt)``; ``delta_x``, ``delta_y``
    the step's displacement (m); ``Q = diag(var_left, var_right)`` (m^2).
    """
    xx, xy, xt, yy, yt, tt = p
    a = -delta_y
    b = delta_x
    (gxl, gxr), (gyl, gyr), (gtl, gtr) = g
    return (xx + a * (2.0 * xt + a * tt) + gxl * gxl * var_left + gxr * gxr * var_right,
            xy + a * yt + b * xt + a * b * tt + gxl * gyl * var_left + gxr * gyr * var_right,
            xt + a * tt + gxl * gtl * var_left + gxr * gtr * var_right,
            yy + b * (2.0 * yt + b * tt) + gyl * gyl * var_left + gyr * gyr * var_right,
            yt + b * tt + gyl * gtl * var_left + gyr * gtr * var_right,
            tt + gtl * gtl * var_left + gtr * gtr * var_right)


def twist_covariance(body, var_left, var_right, duration):
    """Covariance of the mean twist over ``duration`` s, ``B Q B^T / T^2`` (upper tri.)."""
    ql = var_left / (duration * duration)
    qr = var_right / (duration * duration)
    (xl, xr), (yl, yr), (tl, tr) = body
    return (xl * xl * ql + xr * xr * qr, xl * yl * ql + xr * yr * qr,
            xl * tl * ql + xr * tr * qr, yl * yl * ql + yr * yr * qr,
            yl * tl * ql + yr * tr * qr, tl * tl * ql + tr * tr * qr)


def twist_variances(noise: TrackNoise, distance_rate_left: float,
                    distance_rate_right: float):
    """Variances ((m/s)^2) of each track's mean speed over :data:`TWIST_TIME`, rate-independent."""
    return noise.travel_variances(distance_rate_left * TWIST_TIME,
                                  distance_rate_right * TWIST_TIME)


def message_twist_covariance(upper, interval: float):
    """
    Scale a twist covariance of the mean over :data:`TWIST_TIME` to one message's interval.

    The noise terms are random walks in the travel (variance linear in the increment), so the
    mean twist over ``interval`` s has ``TWIST_TIME / interval`` times the variance of the
    mean over :data:`TWIST_TIME`: messages at any rate then carry, fused as independent
    measurements (robot_localization), the information of the 1-s mean per second. See
    docs/nodes/odometry_node.md, "Using it with robot_localization".

    Parameters
    ----------
    upper : tuple of float, 6
        Upper triangle ``(xx, xy, xt, yy, yt, tt)`` of the 1-s mean's covariance.
    interval : float
        s the message's mean twist spans (> 0; anything else returns ``upper``).

    """
    if not interval > 0.0:
        return upper
    factor = TWIST_TIME / interval
    return tuple(v * factor for v in upper)


def saturate(p, limit: float = MAX_VARIANCE):
    """
    Cap every variance of an upper triangle ``p`` at ``limit``, keeping it a covariance.

    ``P' = D P D`` with ``D_ii = min(1, sqrt(limit / P_ii))``; non-finite variances become
    ``limit`` with no correlation.
    """
    xx, xy, xt, yy, yt, tt = p
    if xx <= limit and yy <= limit and tt <= limit:  # False for NaN and inf too
        return p  # the correlations are bounded by the variances
    scales = []
    for variance in (xx, yy, tt):
        scales.append(math.sqrt(limit / variance) if variance > limit else 1.0)
    sx, sy, st = scales
    out = [min(xx * sx * sx, limit), xy * sx * sy, xt * sx * st, min(yy * sy * sy, limit),
           yt * sy * st, min(tt * st * st, limit)]
    for diagonal, index in ((0, 0), (3, 1), (5, 2)):
        if not math.isfinite(out[diagonal]):
            out[diagonal] = limit
            for off in ((1, 2), (1, 4), (2, 4))[index]:
                out[off] = 0.0
    return tuple(0.0 if not math.isfinite(v) else v for v in out)


def full_matrix(upper) -> np.ndarray:
    """Return the symmetric 3 x 3 matrix of an upper triangle ``(xx, xy, xt, yy, yt, tt)``."""
    xx, xy, xt, yy, yt, tt = upper
    return np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, tt]])


# Where the planar upper triangle (xx, xy, xt, yy, yt, tt) goes in a row-major ROS 6 x 6
# covariance ((x, y, z, roll, pitch, yaw), or the twist's (v_x, v_y, v_z, w_x, w_y, w_z)):
# pairs (flat index, index in the upper triangle), each entry with its mirror.
ROS_LAYOUT = ((0, 0), (1, 1), (5, 2), (6, 1), (7, 3), (11, 4), (30, 2), (31, 4), (35, 5))


def ros_covariance(upper) -> np.ndarray:
    """
    Embed a planar upper-triangle covariance in a row-major ROS 6 x 6 (36,) array.

    z, roll and pitch (or their rates) get :data:`UNOBSERVED_VARIANCE`, uncorrelated.
    """
    out = np.zeros(36)
    out[[14, 21, 28]] = UNOBSERVED_VARIANCE
    for flat, index in ROS_LAYOUT:
        out[flat] = upper[index]
    return out
