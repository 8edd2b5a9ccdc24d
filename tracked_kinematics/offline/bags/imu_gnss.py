"""
Decode an IMU's gyro and GNSS positions: the references of a robot without ground truth.

:class:`Imu`: sensor_msgs/Imu read as odometry_node reads it: the heading's rate of
:func:`tracked_kinematics.core.imu_frame.heading_rate` (the angular velocity turned into
``base_link`` by the mount ``imu_mount.*``, about the world's vertical where the message
has an orientation), and the heading of the orientation
(:func:`~tracked_kinematics.core.imu_frame.orientation_heading`) when every message gives
one (``orientation_covariance[0] != -1``) and it turns at all; a message whose heading rate
is not finite or beyond :data:`MAX_RATE` is dropped, with a warning. :class:`Gnss`:
sensor_msgs/NavSatFix with ``status.status >= 0``, converted to the east-north plane at the
first fix by :mod:`tracked_kinematics.core.geodesy`; or nav_msgs/Odometry,
navsat_transform's, positions only.
"""

from __future__ import annotations

from pathlib import Path
import sys

import numpy as np
from tracked_kinematics.core.errors import SensorDataError
from tracked_kinematics.core.geodesy import geodetic_to_enu, GeoOrigin
from tracked_kinematics.core.imu_frame import heading_rate, orientation_heading

from .columns import Columns, header_stamp, sort_unique
from .opening import topic_connections

IMU_TYPES = ('sensor_msgs/msg/Imu',)

#: rad/s: a heading rate at or beyond this is no measurement (a hundred times any ground
#: vehicle's: odometry_node's imu_saturation gate, 10 by default, may be set higher).
MAX_RATE = 1e3
GNSS_TYPES = ('sensor_msgs/msg/NavSatFix', 'nav_msgs/msg/Odometry')


class Imu:
    """Imu messages -> time, the heading's rate, the heading of the orientation (when given)."""

    def __init__(self, topic: str, path: Path, ref_ns: int, mount=np.eye(3)):
        self.topic = topic
        self.path = path
        self.ref_ns = ref_ns
        self.mount = np.asarray(mount, dtype=float)
        # t, angular velocity (x, y, z), orientation (x, y, z, w), orientation given
        self.columns = Columns(9)

    def connections(self, reader):
        """Return the bag connections of the IMU topic (checked)."""
        return topic_connections(reader, self.path, self.topic, IMU_TYPES, 'IMU')

    def add(self, conn, msg, receive_ns) -> None:
        q, w = msg.orientation, msg.angular_velocity
        self.columns.append((header_stamp(msg.header, receive_ns, self.ref_ns),
                             float(w.x), float(w.y), float(w.z), float(q.x), float(q.y),
                             float(q.z), float(q.w),
                             float(float(msg.orientation_covariance[0]) != -1.0)))

    def gyro(self):
        """Return times (ns), the heading's rates (rad/s) and headings (rad; None: none)."""
        data = self.columns.array
        if len(data) == 0:
            raise SensorDataError(f'{self.path}: no Imu messages on {self.topic}')
        data = sort_unique(data)
        t, omega, quaternion, given = data[:, 0], data[:, 1:4].T, data[:, 4:8].T, data[:, 8] > 0
        with np.errstate(invalid='ignore', over='ignore'):   # garbage: dropped below
            rate, _ = heading_rate(tuple(omega), self.mount, tuple(quaternion), given)
            yaw = orientation_heading(tuple(quaternion), self.mount, given)
        # A garbage sample (NaN, 1e300) would poison every fit that integrates the rate.
        # None plausible: left to the fits, which say the gyro gives no angular velocity.
        plausible = np.abs(rate) < MAX_RATE
        if np.any(plausible) and not np.all(plausible):
            print(f'{self.path}: warning: {np.count_nonzero(~plausible)} of {len(rate)} Imu '
                  f'messages on {self.topic} dropped: their heading rate is not finite or '
                  f'beyond {MAX_RATE:g} rad/s (a driver fault)', file=sys.stderr)
            t, rate, yaw = t[plausible], rate[plausible], yaw[plausible]
        # An orientation that never turns (a driver filling identity with covariance 0 instead
        # of -1) is no heading.
        turns = np.all(np.isfinite(yaw)) and np.ptp(np.unwrap(yaw)) > 1e-3
        return t, rate, yaw if turns else None


class Gnss:
    """NavSatFix or Odometry messages -> time, x, y in a local plane."""

    def __init__(self, topic: str, path: Path, ref_ns: int):
        self.topic = topic
        self.path = path
        self.ref_ns = ref_ns
        self.columns = Columns(5)         # t, a, b, c, status (lat, lon, alt or x, y, nan)
        self.kind = ''

    def connections(self, reader):
        """Return the bag connections of the GNSS topic (checked)."""
        return topic_connections(reader, self.path, self.topic, GNSS_TYPES, 'GNSS')

    def add(self, conn, msg, receive_ns) -> None:
        t = header_stamp(msg.header, receive_ns, self.ref_ns)
        if conn.msgtype == 'sensor_msgs/msg/NavSatFix':
            self.kind = 'navsatfix'
            self.columns.append((t, msg.latitude, msg.longitude, msg.altitude,
                                 float(msg.status.status)))
        else:
            self.kind = 'odometry'
            p = msg.pose.pose.position
            self.columns.append((t, p.x, p.y, np.nan, 0.0))

    def positions(self):
        """Return times (ns), x, y in a local plane; the no-fix samples dropped."""
        data = sort_unique(self.columns.array)
        if self.kind == 'navsatfix':
            fix = (data[:, 4] >= 0) & np.all(np.isfinite(data[:, 1:3]), axis=1)
            if not np.any(fix):
                raise SensorDataError(
                    f'{self.path}: the GNSS on {self.topic} has no fix in '
                    f'{len(data)} messages (status < 0 or no position): nothing to calibrate '
                    'the distance with')
            data = data[fix]
            lat, lon, alt = data[:, 1], data[:, 2], data[:, 3]
            origin = GeoOrigin(float(lat[0]), float(lon[0]),
                               float(alt[0]) if np.isfinite(alt[0]) else 0.0)
            x, y, _ = geodetic_to_enu(lat, lon, alt, origin)
            t = data[:, 0]
        else:
            data = data[np.all(np.isfinite(data[:, 1:3]), axis=1)]
            t, x, y = data[:, 0], data[:, 1], data[:, 2]
        if len(t) < 3:
            raise SensorDataError(f'{self.path}: fewer than three GNSS positions on '
                                  f'{self.topic}')
        return t, x, y
