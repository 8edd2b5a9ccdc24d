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

Twist: the body twist published with the pose is the mean over the steps since the last
message, so its error is that of a mean speed. Taking the random walk above literally at
the message rate (travel variance ``k |v| T`` over a window of ``T`` seconds, divided by
``T^2``) gives a speed variance ``k |v| / T`` that grows with the publish rate: at 100 Hz
sigma(v_x) = 0.12 m/s at 0.3 m/s, which a filter rightly ignores. Slip and encoder errors
are not white at the message rate; they are correlated over about a second of driving. The
twist variance is therefore that of the mean speed over :data:`TWIST_TIME` at the current
speeds, from the same noise model (:func:`twist_variances`)::

    var(v_left) = (k_left |v_left| tau + floor) / tau^2,    tau = TWIST_TIME

independent of the publish rate: sigma(v_x) = 0.012 m/s at 0.3 m/s with the default noise.
This is our modelling choice, not an equation of the papers.

Bounds: a variance beyond :data:`MAX_VARIANCE` says nothing more than "unknown", and a
covariance that grew to overflow would freeze the odometry; :func:`saturate` caps each
variance there (keeping the matrix positive semi-definite).
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
    Travel noise of the two tracks.

    Attributes
    ----------
    k_left, k_right : float
        Variance of each track's travel error per metre travelled, m^2/m.
    floor : float
        Variance added per sample and per track, m^2, so the covariance stays positive
        definite when the vehicle stands still.

    Each is finite and >= 0, checked where it enters (odometry_node's ``covariance.*``
    parameters), not here.

    """

    k_left: float = 1e-3
    k_right: float = 1e-3
    floor: float = 1e-9

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


def twist_variances(noise: TrackNoise, distance_rate_left: float,
                    distance_rate_right: float):
    """
    Variances of the mean nominal speed of each track, rate-independent (module docstring).

    Parameters
    ----------
    noise : TrackNoise
        The travel noise model.
    distance_rate_left, distance_rate_right : float
        Mean distance travelled per second by each track, m/s (``|v|`` at a constant speed).

    Returns
    -------
    var_left, var_right : float
        (m/s)^2, for :func:`twist_covariance` with ``duration = TWIST_TIME``.

    """
    return noise.travel_variances(distance_rate_left * TWIST_TIME,
                                  distance_rate_right * TWIST_TIME)


def saturate(p, limit: float = MAX_VARIANCE):
    """
    Cap every variance of a covariance at ``limit``, keeping it positive semi-definite.

    Scales the rows and columns of the over-large variances, ``P' = D P D`` with
    ``D_ii = min(1, sqrt(limit / P_ii))``: correlations are kept and the result stays a
    covariance. Non-finite variances become ``limit`` with no correlation.

    Parameters
    ----------
    p : tuple of float, 6
        Upper triangle ``(xx, xy, xt, yy, yt, tt)``.
    limit : float
        Largest variance.

    Returns
    -------
    tuple of float, 6

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
