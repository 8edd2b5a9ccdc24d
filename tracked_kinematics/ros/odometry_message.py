"""
nav_msgs/Odometry, serialised by patching a template: the odometry node's hot path.

Filling a Python Odometry message and letting rclpy convert it costs about 50 us per
message here, half of the node's whole callback. The message's layout never changes while
the frame ids stay the same, so :class:`OdometrySerializer` serialises one template with
rclpy, finds where each field that changes lies in the bytes (by writing a distinct
sentinel value into each and searching for it), and from then on writes the numbers in
place with :func:`struct.pack_into`; the publisher sends the bytes as they are. The test
suite checks the result against rclpy's own serialisation of the same message.
"""

from __future__ import annotations

import struct

from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from tracked_kinematics.core.covariance import ros_covariance, ROS_LAYOUT

# Native byte order, as rclpy serialises (the CDR header records it).
_DOUBLE = struct.Struct('=d')
_PAIR = struct.Struct('=dd')
_STAMP = struct.Struct('=iI')


class OdometrySerializer:
    """
    Serialised nav_msgs/Odometry with fixed frame ids, written field by field.

    Parameters
    ----------
    frame_id, child_frame_id : str
        ``header.frame_id`` and ``child_frame_id``.

    Attributes
    ----------
    frames : tuple of str
        ``(frame_id, child_frame_id)``.

    Raises
    ------
    RuntimeError
        If a field cannot be located in the template (a layout this class does not know).

    """

    def __init__(self, frame_id: str, child_frame_id: str):
        self.frames = (frame_id, child_frame_id)
        msg = Odometry()
        msg.header.frame_id = frame_id
        msg.child_frame_id = child_frame_id
        sentinels = iter(range(1, 100))

        def mark():
            # Distinct doubles whose bytes cannot occur elsewhere in the template.
            return -1.2345678901234567e-300 * next(sentinels)

        msg.header.stamp.sec = 0x5A5A5A5A
        msg.header.stamp.nanosec = 0x3C3C3C3C
        doubles = {}
        pose = msg.pose.pose
        for name, owner, field in (('x', pose.position, 'x'), ('qz', pose.orientation, 'z'),
                                   ('vx', msg.twist.twist.linear, 'x'),
                                   ('wz', msg.twist.twist.angular, 'z')):
            doubles[name] = mark()
            setattr(owner, field, doubles[name])
        pose_covariance = ros_covariance((0.0,) * 6)
        twist_covariance = ros_covariance((0.0,) * 6)
        doubles['pose_cov'] = pose_covariance[0] = mark()
        doubles['twist_cov'] = twist_covariance[0] = mark()
        msg.pose.covariance = pose_covariance
        msg.twist.covariance = twist_covariance
        data = serialize_message(msg)
        offsets = {name: self._find(data, _DOUBLE.pack(value), name)
                   for name, value in doubles.items()}
        self._stamp = self._find(data, _STAMP.pack(0x5A5A5A5A, 0x3C3C3C3C), 'header.stamp')
        # Fields that follow each other in the message definition are contiguous doubles.
        self._position = offsets['x']           # position.x, position.y
        self._orientation = offsets['qz']       # orientation.z, orientation.w
        self._linear = offsets['vx']            # twist.linear.x, twist.linear.y
        self._angular = offsets['wz']           # twist.angular.z
        self._pose_cov = tuple((offsets['pose_cov'] + 8 * i, j) for i, j in ROS_LAYOUT)
        self._twist_cov = tuple((offsets['twist_cov'] + 8 * i, j) for i, j in ROS_LAYOUT)
        self._buffer = bytearray(data)
        for offset in (self._position, self._orientation, self._linear):
            _PAIR.pack_into(self._buffer, offset, 0.0, 0.0)
        _PAIR.pack_into(self._buffer, self._orientation, 0.0, 1.0)
        for offset, _ in self._pose_cov + self._twist_cov:
            _DOUBLE.pack_into(self._buffer, offset, 0.0)
        _DOUBLE.pack_into(self._buffer, self._angular, 0.0)

    @staticmethod
    def _find(data: bytes, pattern: bytes, name: str) -> int:
        offset = data.find(pattern)
        if offset < 0 or data.find(pattern, offset + 1) >= 0:
            raise RuntimeError(f'cannot locate {name} in a serialised nav_msgs/Odometry')
        return offset

    def serialize(self, sec: int, nanosec: int, x: float, y: float, qz: float, qw: float,
                  pose_covariance, twist, twist_covariance) -> bytes:
        """
        Return the serialised message with these values.

        Parameters
        ----------
        sec, nanosec : int
            ``header.stamp``.
        x, y : float
            Position, m.
        qz, qw : float
            Orientation (a yaw), ``x = y = 0``.
        pose_covariance, twist_covariance : tuple of float, 6
            Planar upper triangles ``(xx, xy, xt, yy, yt, tt)``; the other entries keep the
            layout of :func:`~tracked_kinematics.core.covariance.ros_covariance`.
        twist : tuple of float, 3
            ``(v_x, v_y, w)``.

        """
        buffer = self._buffer
        _STAMP.pack_into(buffer, self._stamp, sec, nanosec)
        _PAIR.pack_into(buffer, self._position, x, y)
        _PAIR.pack_into(buffer, self._orientation, qz, qw)
        _PAIR.pack_into(buffer, self._linear, twist[0], twist[1])
        _DOUBLE.pack_into(buffer, self._angular, twist[2])
        pack = _DOUBLE.pack_into
        for offset, j in self._pose_cov:
            pack(buffer, offset, pose_covariance[j])
        for offset, j in self._twist_cov:
            pack(buffer, offset, twist_covariance[j])
        return bytes(buffer)
