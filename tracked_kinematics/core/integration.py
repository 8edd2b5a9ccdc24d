"""
Planar pose integration, exact for a constant body twist over each step.

Exact arcs make the result independent of the encoder rate and allow a closed form without a Python
loop: a cumulative heading, then the cumulative sum of rotated arc chords.
"""

from __future__ import annotations

import numpy as np


def wrap_angle(angle):
    """Wrap angles (rad) to [-pi, pi)."""
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def arc_chord(dx, dy, dtheta):
    """
    Displacement (m) over one step of body increments ``dx, dy, dtheta``, in its start frame.

    ::

        [X]   [S  -C] [dx]        S = sin(dtheta) / dtheta
        [Y] = [C   S] [dy],       C = (1 - cos(dtheta)) / dtheta

    with ``S -> 1``, ``C -> dtheta / 2`` as ``dtheta -> 0`` (evaluated without a division).
    """
    dx = np.asarray(dx, dtype=float)
    dy = np.asarray(dy, dtype=float)
    dtheta = np.asarray(dtheta, dtype=float)
    s = np.sinc(dtheta / np.pi)
    c = 0.5 * dtheta * np.sinc(dtheta / (2.0 * np.pi)) ** 2
    return s * dx - c * dy, c * dx + s * dy


def integrate(dx, dy, dtheta, pose0=(0.0, 0.0, 0.0)):
    """
    Integrate body-frame increments (m, m, rad per step) into poses, exactly along arcs.

    Heading ``theta0 + cumsum(dtheta)``; position the cumulative sum of the arc chords rotated by
    the heading at each step's start. Returns ``x, y, theta`` after each step; ``theta`` is
    continuous (wrap it with :func:`wrap_angle` for messages).
    """
    dtheta = np.asarray(dtheta, dtype=float)
    chord_x, chord_y = arc_chord(dx, dy, dtheta)
    theta = pose0[2] + np.cumsum(dtheta)
    theta_start = theta - dtheta
    cos_t = np.cos(theta_start)
    sin_t = np.sin(theta_start)
    x = pose0[0] + np.cumsum(cos_t * chord_x - sin_t * chord_y)
    y = pose0[1] + np.cumsum(sin_t * chord_x + cos_t * chord_y)
    return x, y, theta


def integrate_twist(v_x, v_y, w, dt, pose0=(0.0, 0.0, 0.0)):
    """Integrate a piecewise-constant twist (m/s, m/s, rad/s over ``dt`` s) exactly along arcs."""
    dt = np.asarray(dt, dtype=float)
    return integrate(np.asarray(v_x) * dt, np.asarray(v_y) * dt, np.asarray(w) * dt, pose0)


def relative_pose(x0, y0, theta0, x1, y1, theta1):
    """Pose 1 in the frame of pose 0 (``pose0^-1 (+) pose1``), heading wrapped to [-pi, pi)."""
    theta0 = np.asarray(theta0, dtype=float)
    ex = np.asarray(x1, dtype=float) - x0
    ey = np.asarray(y1, dtype=float) - y0
    c = np.cos(theta0)
    s = np.sin(theta0)
    return c * ex + s * ey, -s * ex + c * ey, wrap_angle(np.asarray(theta1) - theta0)


def compose(x0, y0, theta0, dx, dy, dtheta):
    """Apply a displacement given in the frame of pose 0 (``pose0 (+) d``); heading not wrapped."""
    theta0 = np.asarray(theta0, dtype=float)
    c = np.cos(theta0)
    s = np.sin(theta0)
    return (x0 + c * np.asarray(dx) - s * np.asarray(dy),
            y0 + s * np.asarray(dx) + c * np.asarray(dy),
            theta0 + np.asarray(dtheta))


# Headings and stamps as ROS messages carry them ------------------------------------------
# The one place where a planar heading meets a quaternion and a time meets a (sec, nanosec)
# stamp; nodes and bag readers/writers call these instead of their own copies.

def yaw_from_quaternion(x, y, z, w):
    """Heading of a quaternion (rad, REP-103): rotation about z of its projection on the plane."""
    x, y, z, w = (np.asarray(v, dtype=float) for v in (x, y, z, w))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return float(yaw) if yaw.ndim == 0 else yaw


def quaternion_from_yaw(yaw):
    """Quaternion ``(x, y, z, w)`` of a rotation by ``yaw`` rad about z."""
    half = 0.5 * np.asarray(yaw, dtype=float)
    z, w = np.sin(half), np.cos(half)
    if z.ndim == 0:
        return 0.0, 0.0, float(z), float(w)
    zeros = np.zeros_like(z)
    return zeros, zeros, z, w


_NS = 1_000_000_000


def stamp_ns(sec, nanosec):
    """Nanoseconds of a ``(sec, nanosec)`` stamp: an int, or int64 arrays of them."""
    if isinstance(sec, np.ndarray) or isinstance(nanosec, np.ndarray):
        return np.asarray(sec, dtype=np.int64) * _NS + np.asarray(nanosec, dtype=np.int64)
    return int(sec) * _NS + int(nanosec)


def split_stamp(ns: int) -> tuple[int, int]:
    """``(sec, nanosec)`` of a time in nanoseconds (``nanosec`` in [0, 1e9))."""
    ns = int(ns)
    return ns // _NS, ns % _NS


def seconds_to_stamp(seconds: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of a time in seconds, rounded to the nanosecond."""
    return split_stamp(round(float(seconds) * _NS))
