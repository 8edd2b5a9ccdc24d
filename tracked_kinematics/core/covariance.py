"""
Linearised error propagation for tracked-vehicle odometry (Kelly 2004).

Noise model: the measured (nominal) travel of each track over a step carries independent
zero-mean errors whose variance grows linearly with the distance that track travelled, plus
a small floor per sample (quantisation, timing)::

    var(d_left)  = k_left  |d_left|  + floor
    var(d_right) = k_right |d_right| + floor

so that the error of a track's travel is a random walk in distance, the model of Kelly's
"Linearized error propagation in odometry" (IJRR 23(2), 2004). ``k_*`` is in m^2 per m
travelled, ``floor`` in m^2 per sample.

Propagation: one step moves the pose along an exact arc (:mod:`.integration`) whose body
increments come from the travel through the tread-ICR kinematics (:mod:`.kinematics`). With
``Delta = (Delta_x, Delta_y)`` the step's displacement in the fixed frame, the Jacobians are::

    F = d pose_k / d pose_{k-1} = [[1, 0, -Delta_y],
                                   [0, 1,  Delta_x],
                                   [0, 0,  1      ]]
    G = d pose_k / d (d_left, d_right) = [R(theta) dchord/d(dx, dy, dtheta); 0 0 1] B

(``B`` is the Jacobian of the body increments with respect to the travel, the ICR model
with the scales), and ``P_k = F P_{k-1} F^T + G Q G^T``, Kelly's linearised propagation
applied to this kinematic model. The product of the ``F`` of many steps keeps their form,
with ``Delta`` the displacement over all of them: an early heading error moves the later
pose sideways by the distance travelled since, so the covariance grows with distance and
with turning.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
import math

import numpy as np

from .kinematics import IcrParams

# Variance published for the dimensions planar odometry does not observe (z, roll, pitch,
# and their rates): large, so that a filter such as robot_localization ignores them, but
# not infinite and never zero.
UNOBSERVED_VARIANCE = 1e6

# Below this |dtheta| the derivatives of the arc chord use their Taylor series (the
# closed forms lose digits to cancellation); the truncation error is below 2e-13.
_SMALL_ANGLE = 1e-2


@dataclass(frozen=True, slots=True)
class TrackNoise:
    """
    Travel noise of the two tracks.

    Attributes
    ----------
    k_left, k_right : float
        Variance of each track's travel error per metre travelled, m^2/m.
    floor : float
        Variance added per sample and per track, m^2, so the covariance stays positive
        definite when the vehicle stands still.

    Raises
    ------
    ValueError
        When any value is non-finite or negative (the message names it).

    """

    k_left: float = 1e-3
    k_right: float = 1e-3
    floor: float = 1e-9

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f'{f.name} must be a number, got {value!r}')
            if not math.isfinite(value) or value < 0.0:
                raise ValueError(f'{f.name} must be finite and >= 0, got {value!r}')
            object.__setattr__(self, f.name, float(value))

    def travel_variances(self, abs_left, abs_right, samples=1):
        """
        Variances of the measured travel of each track.

        Works on floats and, elementwise, on arrays.

        Parameters
        ----------
        abs_left, abs_right : float or ndarray
            Distance travelled by each track, m (the sum of ``|d|`` over the samples).
        samples : int or ndarray
            Number of encoder samples the distances were measured over.

        Returns
        -------
        var_left, var_right : float or ndarray
            m^2.

        """
        floor = self.floor * samples
        return self.k_left * abs(abs_left) + floor, self.k_right * abs(abs_right) + floor


def body_jacobian(icr: IcrParams):
    """
    Jacobian ``B`` of the body increments ``(dx, dy, dtheta)`` by the nominal travel.

    The ICR forward kinematics (Martinez eqs. 7-9 with the scales of eqs. 20-21) are linear
    in the travel, so ``B`` is constant for a model; it also maps nominal track speeds to
    the body twist.

    Parameters
    ----------
    icr : IcrParams
        Kinematic model.

    Returns
    -------
    tuple of tuple of float, 3 x 2
        Rows ``(dx, dy, dtheta)``, columns ``(d_left, d_right)``.

    """
    span = icr.y_left - icr.y_right
    sl = icr.scale_left / span
    sr = icr.scale_right / span
    return ((-icr.y_right * sl, icr.y_left * sr),
            (icr.x * sl, -icr.x * sr),
            (-sl, sr))


def _chord_factors(t: float):
    """
    Return ``S, C`` of the arc chord and their derivatives ``dS/dt``, ``dC/dt``.

    ``S = sin(t) / t``, ``C = (1 - cos(t)) / t`` (:func:`.integration.arc_chord`).
    """
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
    Displacement of one exact arc step and its Jacobian by the body increments.

    Written for one step with Python floats: the node calls it once per encoder message,
    where numpy's per-call overhead on 3 x 3 matrices would cost a hundred times the
    arithmetic. The step is the one of :func:`.integration.integrate`.

    Parameters
    ----------
    theta0 : float
        Heading at the start of the step, rad.
    dx, dy, dtheta : float
        Body-frame increments of the step: m, m, rad.

    Returns
    -------
    delta_x, delta_y : float
        Displacement in the fixed frame, m (the heading changes by ``dtheta``).
    m : tuple of tuple of float, 2 x 3
        ``d (delta_x, delta_y) / d (dx, dy, dtheta)``; the heading row is ``(0, 0, 1)``.

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
    """
    Jacobian ``G`` of the pose after a step by the nominal travel of the two tracks.

    Parameters
    ----------
    m : tuple of tuple of float, 2 x 3
        From :func:`arc_step`.
    body : tuple of tuple of float, 3 x 2
        From :func:`body_jacobian`.

    Returns
    -------
    tuple of tuple of float, 3 x 2
        Rows ``(x, y, theta)``, columns ``(d_left, d_right)``.

    """
    (b0l, b0r), (b1l, b1r), (b2l, b2r) = body
    rows = tuple((r0 * b0l + r1 * b1l + r2 * b2l, r0 * b0r + r1 * b1r + r2 * b2r)
                 for r0, r1, r2 in m)
    return rows + ((b2l, b2r),)


def propagate(p, delta_x, delta_y, g, var_left, var_right):
    """
    One step of linearised covariance propagation, ``F P F^T + G Q G^T``.

    ``F`` is the identity plus the column ``(-delta_y, delta_x, 0)`` on the heading
    (module docstring); ``Q = diag(var_left, var_right)``. The products are written out,
    so the result is exactly symmetric.

    Parameters
    ----------
    p : tuple of float, 6
        Pose covariance before the step, upper triangle ``(xx, xy, xt, yy, yt, tt)``.
    delta_x, delta_y : float
        Displacement of the step in the fixed frame, m.
    g : tuple of tuple of float, 3 x 2
        :func:`travel_jacobian`.
    var_left, var_right : float
        Travel variances, m^2 (:meth:`TrackNoise.travel_variances`).

    Returns
    -------
    tuple of float, 6
        Pose covariance after the step, same layout.

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
    """
    Covariance of the mean body twist over a window, ``B Q B^T / T^2``.

    Parameters
    ----------
    body : tuple of tuple of float, 3 x 2
        :func:`body_jacobian`.
    var_left, var_right : float
        Variances of the travel over the window, m^2.
    duration : float
        Length of the window, s.

    Returns
    -------
    tuple of float, 6
        Upper triangle of the covariance of ``(v_x, v_y, w)``, layout of :func:`propagate`.

    """
    ql = var_left / (duration * duration)
    qr = var_right / (duration * duration)
    (xl, xr), (yl, yr), (tl, tr) = body
    return (xl * xl * ql + xr * xr * qr, xl * yl * ql + xr * yr * qr,
            xl * tl * ql + xr * tr * qr, yl * yl * ql + yr * yr * qr,
            yl * tl * ql + yr * tr * qr, tl * tl * ql + tr * tr * qr)


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
    Embed a planar covariance of ``(x, y, yaw)`` (or ``(v_x, v_y, w)``) in a ROS 6 x 6 one.

    z, roll and pitch (or their rates) get :data:`UNOBSERVED_VARIANCE` on the diagonal and
    no correlation: large, so a filter ignores them, and never zero.

    Parameters
    ----------
    upper : tuple of float, 6
        Upper triangle ``(xx, xy, xt, yy, yt, tt)``.

    Returns
    -------
    ndarray, shape (36,)
        Row-major, as the ``covariance`` fields of geometry_msgs carry it.

    """
    out = np.zeros(36)
    out[[14, 21, 28]] = UNOBSERVED_VARIANCE
    for flat, index in ROS_LAYOUT:
        out[flat] = upper[index]
    return out
