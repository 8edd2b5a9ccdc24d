"""
nav_msgs/Odometry, serialised by patching a template: the odometry node's hot path.

rclpy's conversion cost about half of the node's callback; :class:`OdometrySerializer`
serialises one template, locates each changing field, and writes the numbers in place with
:func:`struct.pack_into`. The tests compare it with rclpy's own serialisation.
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
_INT = struct.Struct('=i')
_UINT = struct.Struct('=I')
# Two values of each kind, distinct in every byte and with no zero byte: written into a field
# of the template, they can be told from anything else in the bytes.
_MARKS = tuple(struct.unpack('=d', bytes(range(start, start + 8)))[0] for start in (0x31, 0x41))
_INTS = (-0x5A5A5A5B, 0x3C3C3C3C)
_UINTS = (0xA5A5A5A5, 0x3C3C3C3C)


def _mark_first(with_covariance, value) -> None:
    covariance = ros_covariance((0.0,) * 6)
    covariance[0] = value
    with_covariance.covariance = covariance


class OdometrySerializer:
    """
    Serialised nav_msgs/Odometry with fixed frame ids (any text), written field by field.

    RuntimeError if a field cannot be located in the template.
    """

    def __init__(self, frame_id: str, child_frame_id: str):
        self.frames = (frame_id, child_frame_id)
        data = serialize_message(self._message())
        pose = (lambda m: m.pose.pose)
        fields = {
            # name: (setter of a value, format, two distinct values none of whose bytes is 0)
            'sec': (lambda m, v: setattr(m.header.stamp, 'sec', v), _INT, _INTS),
            'nanosec': (lambda m, v: setattr(m.header.stamp, 'nanosec', v), _UINT, _UINTS),
            'x': (lambda m, v: setattr(pose(m).position, 'x', v), _DOUBLE, _MARKS),
            'y': (lambda m, v: setattr(pose(m).position, 'y', v), _DOUBLE, _MARKS),
            'qz': (lambda m, v: setattr(pose(m).orientation, 'z', v), _DOUBLE, _MARKS),
            'qw': (lambda m, v: setattr(pose(m).orientation, 'w', v), _DOUBLE, _MARKS),
            'vx': (lambda m, v: setattr(m.twist.twist.linear, 'x', v), _DOUBLE, _MARKS),
            'vy': (lambda m, v: setattr(m.twist.twist.linear, 'y', v), _DOUBLE, _MARKS),
            'wz': (lambda m, v: setattr(m.twist.twist.angular, 'z', v), _DOUBLE, _MARKS),
            'pose_cov': (lambda m, v: _mark_first(m.pose, v), _DOUBLE, _MARKS),
            'twist_cov': (lambda m, v: _mark_first(m.twist, v), _DOUBLE, _MARKS),
        }
        offsets = {name: self._locate(name, *field) for name, field in fields.items()}
        self._check_contiguous(offsets)
        self._stamp = offsets['sec']             # sec, nanosec
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

    def _message(self) -> Odometry:
        """Return the template: frames set, covariances in the layout, everything else 0."""
        msg = Odometry()
        msg.header.frame_id, msg.child_frame_id = self.frames
        msg.pose.covariance = ros_covariance((0.0,) * 6)
        msg.twist.covariance = ros_covariance((0.0,) * 6)
        return msg

    def _locate(self, name: str, change, form: struct.Struct, values) -> int:
        """
        Return a field's offset: the one place holding each of two values written into it.

        Frame id text and CDR padding are the same in both templates: never mistaken.
        """
        serialised = []
        for value in values:
            msg = self._message()
            change(msg, value)
            serialised.append(serialize_message(msg))
        first, second = serialised
        pattern_a, pattern_b = (form.pack(value) for value in values)
        found = []
        offset = first.find(pattern_a)
        while offset >= 0:
            if second[offset:offset + form.size] == pattern_b:
                found.append(offset)
            offset = first.find(pattern_a, offset + 1)
        if len(found) != 1:
            raise RuntimeError(f'cannot locate {name} in a serialised nav_msgs/Odometry')
        return found[0]

    @staticmethod
    def _check_contiguous(offsets) -> None:
        """Check that the fields written as pairs follow each other, as the definition says."""
        for first, second, size in (('sec', 'nanosec', 4), ('x', 'y', 8), ('qz', 'qw', 8),
                                    ('vx', 'vy', 8)):
            if offsets[second] != offsets[first] + size:
                raise RuntimeError(f'unexpected layout of nav_msgs/Odometry ({first}, {second})')

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
            Planar upper triangles ``(xx, xy, xt, yy, yt, tt)``; the other entries as
            :func:`~tracked_kinematics.core.covariance.ros_covariance` lays them out.
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
