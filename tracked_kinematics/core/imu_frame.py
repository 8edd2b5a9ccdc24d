"""
The gyro in the vehicle frame: an IMU's angular velocity turned into the heading's rate.

A sensor_msgs/Imu gives the angular velocity in the IMU's own frame and, when it has one, the
orientation of that frame in a world frame (REP-145: ENU, z up). The odometry's heading is the
direction of ``base_link``'s x axis projected onto the horizontal plane, so its rate is

- with an orientation: the heading's rate from the world-frame angular velocity ``w`` and the
  base's x axis ``h`` in the world, ``w_z - h_z (w_x h_x + w_y h_y) / (h_x^2 + h_y^2)`` (the
  rate about the vertical, corrected by the pitch; on a slope driven along the contour it is
  ``cos(slope)`` times the body rate);
- without one: the body z rate, the angular velocity turned into ``base_link`` by the mount
  rotation (exact on level ground only).

Which way is up is the mount's: an orientation whose world z points down from the base (an NED
IMU) has its rate negated, so that one mount rotation right serves both, and a mount wrong by
a half turn gives a rate of the wrong sign (refused by the gyro's consistency check) whatever
the orientation says. See docs/nodes/odometry_node.md, "IMU frames".
"""

from __future__ import annotations

import math

import numpy as np

#: Largest tilt of the base from the vertical the orientation is believed at, rad: beyond it
#: the orientation disagrees with the mount (or the robot is on a wall) and is not used.
MAX_TILT = math.radians(60.0)

#: Largest departure of an orientation's quaternion norm from 1 that is read as a rotation.
UNIT_TOLERANCE = 0.01

#: Weight in the body rate below which an axis is not read when it is not finite: a one-axis
#: gyro's NaN on x and y, with the mount at 0 or a half turn typed as 3.14159 (sin: 2.7e-6).
MINOR = 0.01

_COS_MAX_TILT = math.cos(MAX_TILT)


def mount_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """
    Rotation of the IMU's frame in ``base_link``, as a URDF joint's ``rpy``.

    ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (fixed axes x, y, z; REP-103), so that a vector ``v`` in
    the IMU's frame is ``R v`` in ``base_link``. An IMU mounted upside down (z down) or an NED
    one (x forward, y right, z down) is ``roll = pi``.

    Parameters
    ----------
    roll, pitch, yaw : float
        rad.

    Returns
    -------
    ndarray, (3, 3)

    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _finite(value):
    return abs(value) < math.inf   # False for NaN; elementwise on arrays


def _weighed(m, w):
    """Return ``m w``; 0 where the axis barely counts (:data:`MINOR`) and ``w`` is not finite."""
    if abs(m) >= MINOR:
        return m * w
    if isinstance(w, np.ndarray):
        with np.errstate(invalid='ignore'):
            return np.where(_finite(w), m * w, 0.0)
    return m * w if _finite(w) else 0.0


def heading_rate(omega, mount, quaternion=None, has_orientation=False):
    """
    Rate of the heading of ``base_link`` from an IMU sample (or arrays of samples).

    Elementwise on Python floats (one sample, the node's path: a few microseconds) or on
    arrays of samples.

    Parameters
    ----------
    omega : tuple of float or array_like, 3
        ``angular_velocity`` (x, y, z) in the IMU's frame, rad/s.
    mount : ndarray or nested tuple, (3, 3)
        :func:`mount_rotation`: the IMU's frame in ``base_link`` (a tuple of rows is read
        fastest).
    quaternion : tuple of float or array_like, 4, optional
        ``orientation`` (x, y, z, w) of the IMU's frame in the world.
    has_orientation : bool or array_like of bool
        Whether the message carries an orientation (``orientation_covariance[0] != -1``).
        It is used when, besides, its norm is 1 within :data:`UNIT_TOLERANCE`, it tilts the
        base by at most :data:`MAX_TILT` from the vertical (either way up: see the module)
        and the rate it gives is finite (an axis of ``omega`` NaN: the body rate is used).

    Returns
    -------
    rate : float or ndarray
        rad/s.
    used : bool or ndarray of bool
        Where the orientation was used (else the rate is the body z rate).

    """
    wx, wy, wz = omega
    rows = mount.tolist() if isinstance(mount, np.ndarray) else mount
    (m00, m01, m02), _, (m20, m21, m22) = rows
    body = _weighed(m20, wx) + _weighed(m21, wy) + _weighed(m22, wz)
    if quaternion is None:
        return body, _false_like(body)
    unit, rows_r = _orientation(quaternion, has_orientation)
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rows_r
    # The angular velocity in the world (the mount cancels), the base's x axis in the world
    # (R m_row0), the world z component of the base's z axis (R m_row2). A garbage axis
    # (inf, NaN) makes the rate NaN, which is caught below: no RuntimeWarning on the way.
    with np.errstate(invalid='ignore', over='ignore'):
        w0 = r00 * wx + r01 * wy + r02 * wz
        w1 = r10 * wx + r11 * wy + r12 * wz
        w2 = r20 * wx + r21 * wy + r22 * wz
        h0 = r00 * m00 + r01 * m01 + r02 * m02
        h1 = r10 * m00 + r11 * m01 + r12 * m02
        h2 = r20 * m00 + r21 * m01 + r22 * m02
        up = r20 * m20 + r21 * m21 + r22 * m22
        horizontal = h0 * h0 + h1 * h1
        horizontal = horizontal + (horizontal == 0.0)
        rate = w2 - h2 * (w0 * h0 + w1 * h1) / horizontal
        rate = rate * (1.0 - 2.0 * (up < 0.0))
    # The orientation's rate needs every axis: where one is not finite, the body rate (which
    # needs only those the mount reads).
    used = unit & (abs(up) >= _COS_MAX_TILT) & _finite(rate)
    if isinstance(used, np.ndarray) or isinstance(rate, np.ndarray):
        return np.where(used, rate, body), np.asarray(used) & np.ones_like(rate, dtype=bool)
    return (rate, True) if used else (body, False)


def orientation_heading(quaternion, mount, has_orientation=True):
    """
    Heading of ``base_link`` from an IMU's orientation (or arrays of them), rad.

    The direction of the base's x axis projected onto the horizontal plane, ``atan2(h_y,
    h_x)``, ``h`` that axis in the world; negated where the world's z points down from the
    base (an NED IMU: its heading then grows as the ENU heading does, to a constant). Where
    the orientation is not used (as :func:`heading_rate` decides), NaN.

    Parameters
    ----------
    quaternion : tuple of float or array_like, 4
        ``orientation`` (x, y, z, w) of the IMU's frame in the world.
    mount : ndarray or nested tuple, (3, 3)
        :func:`mount_rotation`.
    has_orientation : bool or array_like of bool
        As :func:`heading_rate`.

    Returns
    -------
    heading : float or ndarray
        rad, in (-pi, pi].

    """
    rows = mount.tolist() if isinstance(mount, np.ndarray) else mount
    (m00, m01, m02), _, (m20, m21, m22) = rows
    unit, ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22)) = _orientation(
        quaternion, has_orientation)
    h0 = r00 * m00 + r01 * m01 + r02 * m02
    h1 = r10 * m00 + r11 * m01 + r12 * m02
    up = r20 * m20 + r21 * m21 + r22 * m22
    used = unit & (abs(up) >= _COS_MAX_TILT)
    heading = np.arctan2(h1, h0) * (1.0 - 2.0 * (up < 0.0))
    return np.where(used, heading, np.nan) if np.ndim(heading) else (
        float(heading) if used else math.nan)


def _orientation(quaternion, has_orientation):
    """Return whether a quaternion is a usable rotation, and its (normalised) rotation rows."""
    qx, qy, qz, qw = quaternion
    n2 = qx * qx + qy * qy + qz * qz + qw * qw
    unit = _finite(n2) & (abs(n2 - 1.0) <= 2.0 * UNIT_TOLERANCE) & has_orientation
    s = 2.0 / (n2 + (n2 == 0.0))
    return unit, (
        (1.0 - s * (qy * qy + qz * qz), s * (qx * qy - qz * qw), s * (qx * qz + qy * qw)),
        (s * (qx * qy + qz * qw), 1.0 - s * (qx * qx + qz * qz), s * (qy * qz - qx * qw)),
        (s * (qx * qz - qy * qw), s * (qy * qz + qx * qw), 1.0 - s * (qx * qx + qy * qy)))


def _false_like(value):
    if isinstance(value, np.ndarray):
        return np.zeros(value.shape, dtype=bool)
    return False
