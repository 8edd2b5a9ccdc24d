"""
Write rosbags without ROS: rosbag2 (sqlite3 or mcap) and ROS 1 bags, through ``rosbags``.

Used by the simulator to record synthetic runs and by the tests to make bags of a known
vehicle. Messages are built from plain numbers with the typestore of the bag's ROS version,
so the same calls write a Jazzy rosbag2 or a Noetic .bag. :class:`BagWriter` writes where it
is told; the tools give it the temporary path of an
:class:`~tracked_kinematics.offline.outputs.Outputs` bag (``directory=True``), which is
renamed onto the target only once the bag is closed, so a killed run never leaves a bag
without its ``metadata.yaml`` at the target.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
from rosbags.typesys import get_types_from_msg, get_typestore, Stores
from tracked_kinematics.core.integration import quaternion_from_yaw, split_stamp
from tracked_kinematics.offline.errors import BagError, UsageError

STORAGES = ('sqlite3', 'mcap', 'rosbag1')


@functools.lru_cache(maxsize=None)
def _typestore(ros1: bool):
    """
    Return the typestore of a ROS version, made once per process.

    A typestore generates the serialiser of each message type on first use: a new one per
    bag made every writer generate them again (half the CPU of writing a short bag).
    """
    if not ros1:
        return get_typestore(Stores.ROS2_JAZZY)
    store = get_typestore(Stores.ROS1_NOETIC)
    # Noetic's store has no tf2_msgs; its definition is one line.
    store.register(get_types_from_msg('geometry_msgs/TransformStamped[] transforms',
                                      'tf2_msgs/msg/TFMessage'))
    return store


class BagWriter:
    """
    Context manager that writes one bag.

    Parameters
    ----------
    path : path-like
        A rosbag2 directory (must not exist) or, for ``storage='rosbag1'``, a ``.bag`` file.
    storage : {'sqlite3', 'mcap', 'rosbag1'}
        Storage format.

    Raises
    ------
    UsageError
        For an unknown storage.
    BagError
        When rosbags refuses the path (it exists).

    Examples
    --------
    >>> with BagWriter('run1', 'mcap') as bag:                         # doctest: +SKIP
    ...     bag.write('/joint_states', t_ns, bag.joint_state(t_ns, names, positions))

    """

    def __init__(self, path, storage: str = 'sqlite3'):
        if storage not in STORAGES:
            raise UsageError(f'storage must be one of {", ".join(STORAGES)}, got {storage!r}')
        self.path = Path(path)
        self.storage = storage
        if storage == 'rosbag1':
            from rosbags.rosbag1 import Writer
            self.typestore = _typestore(True)
            from rosbags.rosbag1 import WriterError
            try:
                self._writer = Writer(self.path)
            except WriterError as err:
                raise BagError(f'cannot write bag {self.path}: {err}') from None
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer
            self.typestore = _typestore(False)
            plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
            from rosbags.rosbag2 import WriterError
            try:
                self._writer = Writer(self.path, version=9, storage_plugin=plugin)
            except WriterError as err:
                raise BagError(f'cannot write bag {self.path}: {err}') from None
        self._connections = {}
        self._types = self.typestore.types

    def __enter__(self):
        from rosbags.rosbag1 import WriterError as Rosbag1WriterError
        from rosbags.rosbag2 import WriterError as Rosbag2WriterError
        try:
            self._writer.open()
        except (Rosbag1WriterError, Rosbag2WriterError) as err:
            raise BagError(f'cannot write bag {self.path}: {err}') from None
        return self

    def __exit__(self, *exc):
        self._writer.close()

    def write(self, topic: str, stamp_ns: int, message) -> None:
        """Write ``message`` on ``topic`` with receive time ``stamp_ns`` (ns)."""
        msgtype = message.__msgtype__
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._writer.add_connection(topic, msgtype, typestore=self.typestore)
            self._connections[topic] = connection
        if self.storage == 'rosbag1':
            data = self.typestore.serialize_ros1(message, msgtype)
        else:
            data = self.typestore.serialize_cdr(message, msgtype)
        self._writer.write(connection, int(stamp_ns), data)

    # Message builders -------------------------------------------------------------------

    def header(self, stamp_ns: int, frame_id: str = ''):
        """std_msgs/Header of the bag's ROS version."""
        sec, nanosec = split_stamp(stamp_ns)
        stamp = self._types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec)
        kwargs = {'seq': 0} if self.storage == 'rosbag1' else {}
        return self._types['std_msgs/msg/Header'](stamp=stamp, frame_id=frame_id, **kwargs)

    def joint_state(self, stamp_ns: int, names, positions=(), velocities=(), frame_id=''):
        """sensor_msgs/JointState."""
        return self._types['sensor_msgs/msg/JointState'](
            header=self.header(stamp_ns, frame_id), name=list(names),
            position=np.asarray(positions, dtype=np.float64),
            velocity=np.asarray(velocities, dtype=np.float64),
            effort=np.zeros(0, dtype=np.float64))

    def pose(self, x: float, y: float, yaw: float, z: float = 0.0):
        """geometry_msgs/Pose of a planar pose."""
        types = self._types
        return types['geometry_msgs/msg/Pose'](
            position=types['geometry_msgs/msg/Point'](x=float(x), y=float(y), z=float(z)),
            orientation=types['geometry_msgs/msg/Quaternion'](
                **dict(zip('xyzw', quaternion_from_yaw(yaw)))))

    def pose_stamped(self, stamp_ns: int, x: float, y: float, yaw: float, frame_id='map'):
        """geometry_msgs/PoseStamped."""
        return self._types['geometry_msgs/msg/PoseStamped'](
            header=self.header(stamp_ns, frame_id), pose=self.pose(x, y, yaw))

    def pose_with_covariance_stamped(self, stamp_ns: int, x, y, yaw, frame_id='map',
                                     covariance=None):
        """geometry_msgs/PoseWithCovarianceStamped."""
        types = self._types
        cov = np.zeros(36) if covariance is None else np.asarray(covariance, float).ravel()
        return types['geometry_msgs/msg/PoseWithCovarianceStamped'](
            header=self.header(stamp_ns, frame_id),
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=self.pose(x, y, yaw), covariance=cov))

    def odometry(self, stamp_ns: int, x, y, yaw, v_x=0.0, v_y=0.0, w=0.0,
                 frame_id='odom', child_frame_id='base_link'):
        """nav_msgs/Odometry with a planar pose and body twist."""
        types = self._types
        vec = types['geometry_msgs/msg/Vector3']
        twist = types['geometry_msgs/msg/Twist'](linear=vec(x=float(v_x), y=float(v_y), z=0.0),
                                                 angular=vec(x=0.0, y=0.0, z=float(w)))
        return types['nav_msgs/msg/Odometry'](
            header=self.header(stamp_ns, frame_id), child_frame_id=child_frame_id,
            pose=types['geometry_msgs/msg/PoseWithCovariance'](
                pose=self.pose(x, y, yaw), covariance=np.zeros(36)),
            twist=types['geometry_msgs/msg/TwistWithCovariance'](
                twist=twist, covariance=np.zeros(36)))

    def tf_message(self, stamp_ns: int, parent: str, child: str, x, y, yaw):
        """tf2_msgs/TFMessage with one planar transform."""
        types = self._types
        p = self.pose(x, y, yaw)
        transform = types['geometry_msgs/msg/Transform'](
            translation=types['geometry_msgs/msg/Vector3'](x=p.position.x, y=p.position.y,
                                                           z=p.position.z),
            rotation=p.orientation)
        stamped = types['geometry_msgs/msg/TransformStamped'](
            header=self.header(stamp_ns, parent), child_frame_id=child, transform=transform)
        return types['tf2_msgs/msg/TFMessage'](transforms=[stamped])

    def imu(self, stamp_ns: int, w_z: float, frame_id: str = 'imu_link',
            rate_variance: float = 0.0, yaw: float | None = None,
            yaw_variance: float = 1e-4, omega=None, quaternion=None):
        """
        sensor_msgs/Imu with the gyro's z rate (and, with ``yaw``, an orientation).

        Without ``yaw`` the orientation is not provided; linear acceleration never is: their
        covariances' first element is -1 (the message's convention).
        ``angular_velocity_covariance`` is diagonal with ``rate_variance`` (rad^2/s^2).
        ``omega`` ``(x, y, z)`` (rad/s) replaces ``(0, 0, w_z)`` and ``quaternion`` ``(x, y,
        z, w)`` the orientation of ``yaw``: an IMU mounted otherwise, or tilted.
        """
        types = self._types
        vec = types['geometry_msgs/msg/Vector3']
        unknown = np.zeros(9)
        unknown[0] = -1.0
        cov = np.zeros(9)
        cov[[0, 4, 8]] = rate_variance
        quat = types['geometry_msgs/msg/Quaternion']
        if yaw is None and quaternion is None:
            orientation = quat(x=0.0, y=0.0, z=0.0, w=0.0)
            orientation_cov = unknown.copy()
        else:
            orientation = self.pose(0.0, 0.0, yaw).orientation if quaternion is None else \
                quat(**dict(zip('xyzw', map(float, quaternion))))
            orientation_cov = np.zeros(9)
            orientation_cov[[0, 4, 8]] = yaw_variance
        wx, wy, wz = (0.0, 0.0, w_z) if omega is None else omega
        return types['sensor_msgs/msg/Imu'](
            header=self.header(stamp_ns, frame_id), orientation=orientation,
            orientation_covariance=orientation_cov,
            angular_velocity=vec(x=float(wx), y=float(wy), z=float(wz)),
            angular_velocity_covariance=cov,
            linear_acceleration=vec(x=0.0, y=0.0, z=0.0),
            linear_acceleration_covariance=unknown.copy())

    def nav_sat_fix(self, stamp_ns: int, latitude: float, longitude: float, altitude: float,
                    status: int = 0, position_variance: float = 0.0, frame_id: str = 'gps'):
        """sensor_msgs/NavSatFix (GPS service) with a diagonal known covariance, m^2."""
        types = self._types
        cov = np.zeros(9)
        cov[[0, 4, 8]] = position_variance
        return types['sensor_msgs/msg/NavSatFix'](
            header=self.header(stamp_ns, frame_id),
            status=types['sensor_msgs/msg/NavSatStatus'](status=int(status), service=1),
            latitude=float(latitude), longitude=float(longitude), altitude=float(altitude),
            position_covariance=cov, position_covariance_type=2)

    def float64(self, value: float):
        """std_msgs/Float64."""
        return self._types['std_msgs/msg/Float64'](data=float(value))

    def int32(self, value: int):
        """std_msgs/Int32 (the value is wrapped into int32 range, as a counter would)."""
        value = (int(value) + 2**31) % 2**32 - 2**31
        return self._types['std_msgs/msg/Int32'](data=value)

    def int64(self, value: int):
        """std_msgs/Int64."""
        return self._types['std_msgs/msg/Int64'](data=int(value))

    def twist(self, v_x: float, w: float, v_y: float = 0.0):
        """geometry_msgs/Twist (cmd_vel)."""
        vec = self._types['geometry_msgs/msg/Vector3']
        return self._types['geometry_msgs/msg/Twist'](
            linear=vec(x=float(v_x), y=float(v_y), z=0.0), angular=vec(x=0.0, y=0.0, z=float(w)))

    def twist_stamped(self, stamp_ns: int, v_x: float, w: float, v_y: float = 0.0,
                      frame_id: str = 'base_link'):
        """geometry_msgs/TwistStamped (cmd_vel of a stamped-twist base)."""
        return self._types['geometry_msgs/msg/TwistStamped'](
            header=self.header(stamp_ns, frame_id), twist=self.twist(v_x, w, v_y))
