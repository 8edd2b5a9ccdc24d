"""
The stamp, angular velocity and orientation of a serialised sensor_msgs/Imu, read in place.

rclpy's conversion of an Imu (three 9-element covariance arrays) costs about 25 us; odometry_node
reads a few numbers of it, at up to a few hundred hertz. The first message of each size is read
by rclpy and the offsets checked against it; later ones of that size are read with
:func:`struct.unpack_from`, as :class:`.encoder_input.JointStateReader` does.
"""

from __future__ import annotations

import math
import struct
from typing import NamedTuple

from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu

_CDR_LE = b'\x00\x01\x00\x00'   # little-endian XCDR1, rmw_fastrtps' encapsulation
_HEAD = 4
_STAMP = struct.Struct('<iI')
_COUNT = struct.Struct('<I')
_DOUBLE = struct.Struct('<d')
_QUATERNION = struct.Struct('<4d')
_VECTOR = struct.Struct('<3d')
# From the 8-aligned orientation to angular_velocity.z: orientation (4 doubles), its
# covariance (9), angular_velocity.x and .y.
_TO_RATE_Z = 8 * (4 + 9 + 2)
# From the orientation to orientation_covariance[0], and to angular_velocity.x.
_TO_COVARIANCE = 8 * 4
_TO_RATE = 8 * (4 + 9)
# ... and to angular_velocity_covariance[0].
_TO_RATE_COVARIANCE = 8 * (4 + 9 + 3)


class ImuSample(NamedTuple):
    """What odometry_node reads of an Imu: the stamp (ns), the rates, the orientation."""

    stamp_ns: int
    omega: tuple           # angular_velocity (x, y, z), rad/s, in frame_id
    quaternion: tuple      # orientation (x, y, z, w)
    has_orientation: bool  # orientation_covariance[0] != -1 (REP-145: -1 means none)
    frame_id: str
    nanosec_valid: bool = True   # header.stamp.nanosec < 1e9 (else no valid time)
    has_rate: bool = True        # angular_velocity_covariance[0] != -1 (-1: no rates)


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
        self._starts: dict[int, int] = {}    # message size -> offset of the orientation
        self.origin: int | None = None

    def seconds(self, stamp_ns: int) -> float:
        """Return a stamp (ns) in s from ``origin`` (set from this stamp when None)."""
        sec, nanosec = divmod(stamp_ns, 1_000_000_000)
        return self._seconds(sec, nanosec)

    def read_sample(self, data: bytes) -> ImuSample | None:
        """Return the :class:`ImuSample` of a serialised Imu, or None for bytes that are no Imu."""
        start = self._starts.get(len(data))
        if start is not None and data.startswith(_CDR_LE):
            sec, nanosec = _STAMP.unpack_from(data, _HEAD)
            length = _COUNT.unpack_from(data, 12)[0]
            return ImuSample(sec * 1_000_000_000 + nanosec,
                             _VECTOR.unpack_from(data, start + _TO_RATE),
                             _QUATERNION.unpack_from(data, start),
                             _DOUBLE.unpack_from(data, start + _TO_COVARIANCE)[0] != -1.0,
                             data[16:15 + length].decode('utf-8', 'replace'),
                             nanosec < 1_000_000_000,
                             _DOUBLE.unpack_from(data, start + _TO_RATE_COVARIANCE)[0] != -1.0)
        try:
            msg = deserialize_message(data, Imu)
        except Exception:  # noqa: BLE001 -- malformed bytes: the caller reports them
            return None
        stamp, w, q = msg.header.stamp, msg.angular_velocity, msg.orientation
        sample = ImuSample(stamp.sec * 1_000_000_000 + stamp.nanosec, (w.x, w.y, w.z),
                           (q.x, q.y, q.z, q.w), msg.orientation_covariance[0] != -1.0,
                           msg.header.frame_id, stamp.nanosec < 1_000_000_000,
                           msg.angular_velocity_covariance[0] != -1.0)
        offset = self._offset(data)
        if offset is not None:
            start = offset - _TO_RATE_Z
            found = (_VECTOR.unpack_from(data, start + _TO_RATE)
                     + _QUATERNION.unpack_from(data, start)
                     + _DOUBLE.unpack_from(data, start + _TO_COVARIANCE)
                     + _DOUBLE.unpack_from(data, start + _TO_RATE_COVARIANCE))
            wanted = sample.omega + sample.quaternion + (msg.orientation_covariance[0],
                                                         msg.angular_velocity_covariance[0])
            length = _COUNT.unpack_from(data, 12)[0]
            if (all(a == b or (math.isnan(a) and math.isnan(b)) for a, b in zip(found, wanted))
                    and data[16:15 + length].decode('utf-8', 'replace') == sample.frame_id):
                self._starts[len(data)] = start
        return sample

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
