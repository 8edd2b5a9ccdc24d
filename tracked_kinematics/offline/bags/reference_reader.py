"""
Read the references of a robot without ground truth: an IMU's gyro, GNSS, a pose.

:func:`read_reference_bag` streams the encoders (as :func:`.reader.read_bag` does) and any
of: a sensor_msgs/Imu topic (the yaw rate ``angular_velocity.z``, or the yaw of
``orientation`` when every message gives one, ``orientation_covariance[0] != -1``, and it
turns at all), a
position topic (sensor_msgs/NavSatFix with ``status.status >= 0``, converted to the
east-north plane at the first fix by :mod:`tracked_kinematics.core.geodesy`; or
nav_msgs/Odometry, navsat_transform's, positions only) and a ground-truth pose. It returns
a :class:`tracked_kinematics.core.recording.Recording`, times in seconds from the
first sample of any stream.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tracked_kinematics.core.errors import SensorDataError
from tracked_kinematics.core.geodesy import geodetic_to_enu, GeoOrigin
from tracked_kinematics.core.recording import Recording
from tracked_kinematics.offline.errors import BagError

from .columns import Columns, header_stamp, sort_unique
from .ground_truth import GroundTruth
from .opening import guarded, topic_connections
from .sources import GroundTruthSource
from .streaming import read_streams

IMU_TYPES = ('sensor_msgs/msg/Imu',)
GNSS_TYPES = ('sensor_msgs/msg/NavSatFix', 'nav_msgs/msg/Odometry')


class _References:
    """Imu, GNSS and pose messages of one bag -> columns."""

    def __init__(self, sources, path: Path, ref_ns: int):
        self.imu_topic, self.gnss_topic, ground_truth = sources
        self.path = path
        self.ref_ns = ref_ns
        self.imu = Columns(4)          # t, wz, yaw, orientation given
        self.gnss = Columns(5)         # t, a, b, c, status (lat, lon, alt or x, y, nan)
        self.gnss_kind = ''
        self.pose = GroundTruth(ground_truth, path, ref_ns) if ground_truth else None
        self._kind = {}

    def connections(self, reader):
        conns = []
        if self.imu_topic:
            found = topic_connections(reader, self.path, self.imu_topic, IMU_TYPES, 'IMU')
            conns += found
            self._kind.update({id(c): 'imu' for c in found})
        if self.gnss_topic:
            found = topic_connections(reader, self.path, self.gnss_topic, GNSS_TYPES, 'GNSS')
            conns += found
            self._kind.update({id(c): 'gnss' for c in found})
        if self.pose is not None:
            found = [c for c in self.pose.connections(reader) if id(c) not in self._kind]
            conns += found
            self._kind.update({id(c): 'pose' for c in found})
        return conns

    def add(self, conn, msg, receive_ns) -> None:
        kind = self._kind.get(id(conn))
        if kind == 'imu':
            q = msg.orientation
            given = float(msg.orientation_covariance[0]) != -1.0 \
                and (q.x, q.y, q.z, q.w) != (0.0, 0.0, 0.0, 0.0)
            yaw = float(np.arctan2(2.0 * (q.w * q.z + q.x * q.y),
                                   1.0 - 2.0 * (q.y * q.y + q.z * q.z))) if given else np.nan
            self.imu.append((header_stamp(msg.header, receive_ns, self.ref_ns),
                             float(msg.angular_velocity.z), yaw, float(given)))
        elif kind == 'gnss':
            t = header_stamp(msg.header, receive_ns, self.ref_ns)
            if conn.msgtype == 'sensor_msgs/msg/NavSatFix':
                self.gnss_kind = 'navsatfix'
                self.gnss.append((t, msg.latitude, msg.longitude, msg.altitude,
                                  float(msg.status.status)))
            else:
                self.gnss_kind = 'odometry'
                p = msg.pose.pose.position
                self.gnss.append((t, p.x, p.y, np.nan, 0.0))
        elif kind == 'pose':
            self.pose.add(conn, msg, receive_ns)

    def gyro(self):
        """Return times (ns), and rates or yaw (one is None)."""
        data = self.imu.array
        if len(data) == 0:
            raise SensorDataError(f'{self.path}: no Imu messages on {self.imu_topic}')
        data = sort_unique(data)
        t, wz, yaw, given = data.T
        # An orientation that never turns (a driver filling identity with covariance 0 instead
        # of -1) is no heading: the rates are used then.
        turns = np.all(np.isfinite(yaw)) and np.ptp(np.unwrap(yaw)) > 1e-3
        if np.all(given > 0) and turns:
            return t, None, yaw
        return t, wz, None

    def positions(self):
        """Return times (ns), x, y in a local plane; the no-fix samples dropped."""
        data = sort_unique(self.gnss.array)
        if self.gnss_kind == 'navsatfix':
            fix = (data[:, 4] >= 0) & np.all(np.isfinite(data[:, 1:3]), axis=1)
            if not np.any(fix):
                raise SensorDataError(
                    f'{self.path}: the GNSS on {self.gnss_topic} has no fix in '
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
                                  f'{self.gnss_topic}')
        return t, x, y


def read_reference_bag(path, encoders, imu_topic: str | None = None,
                       gnss_topic: str | None = None,
                       ground_truth: GroundTruthSource | None = None,
                       progress: bool = False) -> Recording:
    """
    Read the encoders and the references of one bag.

    Parameters
    ----------
    path, encoders, progress
        As :func:`.reader.read_bag`.
    imu_topic, gnss_topic : str, optional
        sensor_msgs/Imu; sensor_msgs/NavSatFix or nav_msgs/Odometry.
    ground_truth : GroundTruthSource, optional
        A pose reference as well.

    Raises
    ------
    BagError
        For a missing or unreadable bag, a missing topic or one of another type.
    SensorDataError
        For an Imu topic without messages, a GNSS without a fix.

    """
    if not (imu_topic or gnss_topic or ground_truth):
        raise ValueError('read_reference_bag needs an IMU, GNSS or ground-truth topic')
    return guarded(Path(path), _read_references, encoders,
                   (imu_topic, gnss_topic, ground_truth), progress)


def _read_references(reader, path, encoders, sources, progress) -> Recording:
    enc, refs = read_streams(reader, path, encoders, _References, sources, progress)
    enc_t, left, right = enc.travel()
    starts = [enc_t[0]]
    gyro = positions = pose = None
    if refs.imu_topic:
        gyro = refs.gyro()
        starts.append(gyro[0][0])
    if refs.gnss_topic:
        positions = refs.positions()
        starts.append(positions[0][0])
    if refs.pose is not None:
        pose = refs.pose.poses()
        starts.append(pose[0][0])
    t0 = min(starts)
    seconds = (lambda t: (np.asarray(t) - t0) * 1e-9)   # noqa: E731
    kwargs = {}
    if gyro is not None:
        kwargs['gyro_t'] = seconds(gyro[0])
        kwargs['gyro_rate' if gyro[1] is not None else 'gyro_yaw'] = \
            gyro[1] if gyro[1] is not None else gyro[2]
    if positions is not None:
        kwargs.update(gnss_t=seconds(positions[0]), gnss_x=positions[1], gnss_y=positions[2])
    if pose is not None:
        kwargs.update(zip(('gt_t', 'gt_x', 'gt_y', 'gt_yaw'), (seconds(pose[0]), *pose[1:])))
    try:
        return Recording(seconds(enc_t), left, right, name=str(path), **kwargs)
    except ValueError as err:
        raise BagError(f'{path}: {err}') from None
