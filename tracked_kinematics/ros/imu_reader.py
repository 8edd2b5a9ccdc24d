"""
The stamp and z rate of a serialised sensor_msgs/Imu, read in place.

rclpy's conversion of an Imu (three 9-element covariance arrays) costs about 25 us; odometry_node
reads two numbers of it, at up to a few hundred hertz. The first message of each size is read by
rclpy and the offset of ``angular_velocity.z`` checked against it; later ones of that size are
read with :func:`struct.unpack_from`, as :class:`.encoder_input.JointStateReader` does.
"""

from __future__ import annotations

import math
import struct

from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu

_CDR_LE = b'\x00\x01\x00\x00'   # little-endian XCDR1, rmw_fastrtps' encapsulation
_HEAD = 4
_STAMP = struct.Struct('<iI')
_COUNT = struct.Struct('<I')
_DOUBLE = struct.Struct('<d')
# From the 8-aligned orientation to angular_velocity.z: orientation (4 doubles), its
# covariance (9), angular_velocity.x and .y.
_TO_RATE_Z = 8 * (4 + 9 + 2)


def stamp_key(msg) -> int:
    """Return a deserialised Imu's stamp in ns (what tells its samples apart)."""
    stamp = msg.header.stamp
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def raw_stamp_key(data: bytes) -> int:
    """Return a serialised Imu's stamp in ns, or -1 when it cannot be read."""
    if data.startswith(_CDR_LE) and len(data) >= _HEAD + _STAMP.size:
        sec, nanosec = _STAMP.unpack_from(data, _HEAD)
        return sec * 1_000_000_000 + nanosec
    try:
        return stamp_key(deserialize_message(data, Imu))
    except Exception:  # noqa: BLE001 -- malformed: skipped when passed on
        return -1


class ImuReader:
    """
    Read ``(stamp_s, angular_velocity.z)`` of serialised Imu messages.

    ``stamp_s`` counts from ``origin`` (whole seconds of the epoch; the first message's when
    None): epoch seconds as a float keep only 0.24 us, which the gyro's 0.01-s spans feel.
    """

    def __init__(self):
        self._offsets: dict[int, int] = {}   # message size -> offset of angular_velocity.z
        self.origin: int | None = None

    def _seconds(self, sec: int, nanosec: int) -> float:
        if self.origin is None:
            self.origin = sec
        return (sec - self.origin) + nanosec * 1e-9

    def read(self, data: bytes):
        """Return ``(stamp in s, z rate in rad/s)``, or None for bytes that are no Imu."""
        offset = self._offsets.get(len(data))
        if offset is not None and data.startswith(_CDR_LE):
            sec, nanosec = _STAMP.unpack_from(data, _HEAD)
            return self._seconds(sec, nanosec), _DOUBLE.unpack_from(data, offset)[0]
        try:
            msg = deserialize_message(data, Imu)
        except Exception:  # noqa: BLE001 -- malformed bytes: the caller reports them
            return None
        stamp = msg.header.stamp
        rate = msg.angular_velocity.z
        offset = self._offset(data)
        if offset is not None:
            found = _DOUBLE.unpack_from(data, offset)[0]
            if found == rate or (math.isnan(found) and math.isnan(rate)):
                self._offsets[len(data)] = offset
        return self._seconds(stamp.sec, stamp.nanosec), rate

    @staticmethod
    def _offset(data: bytes):
        """Return where the CDR rules put angular_velocity.z, or None."""
        if not data.startswith(_CDR_LE) or len(data) < 16:
            return None
        length = _COUNT.unpack_from(data, 12)[0]
        start = 16 + length
        start += -(start - _HEAD) % 8
        offset = start + _TO_RATE_Z
        return offset if offset + 8 <= len(data) else None
