"""
Decode sensor_msgs/JointState encoder messages: per-side mean joint position and velocity.

Most messages are not deserialised one by one: :class:`_Layout` finds the byte offsets of the
numbers in the first message, and every later message with the same layout is decoded in
batches with numpy (rclpy-free; checked against the deserialised message once per topic).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import struct

import numpy as np
from tracked_kinematics.core.encoder_modes import JointStatesDecoder
from tracked_kinematics.core.integration import stamp_ns
from tracked_kinematics.offline.errors import BagError

from .columns import Columns, header_stamp, sort_unique
from .sources import EncoderSource


@dataclass(frozen=True)
class _Layout:
    """
    Byte layout of a serialised JointState whose frame id and joint names repeat.

    Drivers publish the same joints in every message, so all messages of a topic have the
    same length and the numbers sit at the same offsets: they can be read for many messages
    at once with numpy instead of deserialising each. ``checks`` are the byte ranges (frame
    id, joint names, array lengths) that must repeat for a message to share the layout.
    """

    length: int
    stamp: int
    checks: tuple
    position: int | None
    velocity: int | None
    count: int

    @classmethod
    def of(cls, raw, ros2: bool):
        """Parse the layout of one serialised JointState (None if not little-endian CDR)."""
        raw = bytes(raw)
        if ros2 and raw[:2] != b'\x00\x01':
            return None
        base = 4 if ros2 else 0
        pos = base
        checks = []

        def counted(item_size=1, item_align=1):
            # A length-prefixed field: returns its length, records its bytes as a check.
            nonlocal pos
            if ros2:
                pos += -(pos - base) % 4
            start = pos
            (n,) = struct.unpack_from('<I', raw, pos)
            pos += 4
            if ros2 and n and item_align > 1:
                pos += -(pos - base) % item_align
            data_at = pos
            pos += n * item_size
            checks.append((start, raw[start:data_at if item_size == 8 else pos]))
            return n, data_at

        stamp = base + (0 if ros2 else 4)
        pos = stamp + 8
        counted()                                  # frame_id
        names, _ = counted(item_size=0)            # the name sequence's length
        for _ in range(names):
            counted()
        arrays = [counted(8, 8) for _ in range(3)]  # position, velocity, effort
        if pos != len(raw):
            return None
        (n_pos, at_pos), (n_vel, at_vel) = arrays[0], arrays[1]
        return cls(len(raw), stamp, tuple(checks), at_pos if n_pos == names else None,
                   at_vel if n_vel == names else None, names)

    def matches(self, raw) -> bool:
        """Whether a serialised message has this layout."""
        return len(raw) == self.length and all(raw[o:o + len(b)] == b for o, b in self.checks)

    def decode(self, raws, receive_ns, ref_ns, index) -> np.ndarray:
        """Rows ``(t, pos_l, pos_r, vel_l, vel_r)`` of many messages, as :class:`JointStates`."""
        rows = np.frombuffer(b''.join(raws), dtype=np.uint8).reshape(-1, self.length)

        def column(offset, dtype, width=1):
            size = np.dtype(dtype).itemsize * width
            return np.ascontiguousarray(rows[:, offset:offset + size]).view(dtype).reshape(
                len(rows), width)

        stamp = stamp_ns(column(self.stamp, '<i4')[:, 0], column(self.stamp + 4, '<u4')[:, 0])
        stamp = np.where(stamp > 0, stamp, np.asarray(receive_ns, dtype=np.int64)) - ref_ns
        out = np.full((len(rows), 5), np.nan)
        out[:, 0] = stamp
        for offset, first in ((self.position, 1), (self.velocity, 3)):
            if offset is not None:
                out[:, first], out[:, first + 1] = JointStatesDecoder.side_means(
                    column(offset, '<f8', self.count), index)
        return out


class JointStates:
    """JointState messages -> time, per-side mean position and velocity, for the decoder."""

    BATCH = 20_000

    def __init__(self, source: EncoderSource, path: Path, ref_ns: int, ros2: bool):
        self.source = source
        self.decoder = source.decoder()
        self.path = path
        self.ref_ns = ref_ns
        self.ros2 = ros2
        self.columns = Columns(5)
        self.names_seen: set[str] = set()
        self._index_cache: dict[tuple, tuple | None] = {}
        self._layout = None
        self._layout_index = None
        self._batch = []
        self._batch_ns = []

    def _index(self, names):
        key = tuple(names)
        if key not in self._index_cache:
            found = self._index_cache[key] = self.decoder.index(key)
            if found is None:
                self.names_seen.update(key)
        return self._index_cache[key]

    def feed(self, reader, conn, receive_ns, raw) -> None:
        """Take one serialised message: batched when it has the known layout."""
        if self._layout and self._layout.matches(raw):
            self._batch.append(raw)
            self._batch_ns.append(receive_ns)
            if len(self._batch) == self.BATCH:
                self.flush()
            return
        msg = reader.deserialize(raw, conn.msgtype)
        row = self._row(msg, receive_ns)
        if row is None:
            return
        self.columns.append(row)
        if self._layout is None:
            layout = _Layout.of(raw, self.ros2)
            index = self._index(msg.name)
            if layout is not None:
                decoded = layout.decode([bytes(raw)], [receive_ns], self.ref_ns, index)[0]
                if np.allclose(decoded, row, equal_nan=True, rtol=1e-12, atol=0.0):
                    self._layout, self._layout_index = layout, index
            if self._layout is None:
                self._layout = False   # never try again: every message goes the slow way

    def flush(self) -> None:
        """Decode the batched messages."""
        if self._batch:
            self.columns.extend(self._layout.decode(self._batch, self._batch_ns, self.ref_ns,
                                                    self._layout_index))
            self._batch, self._batch_ns = [], []

    def _row(self, msg, receive_ns):
        index = self._index(msg.name)
        if index is None:
            return None
        return [header_stamp(msg.header, receive_ns, self.ref_ns),
                *self.decoder.row(index, len(msg.name), msg.position, msg.velocity)]

    def _samples(self):
        """Return the rows sorted by time, raising the missing-joint error when there are none."""
        if self._layout:
            self.flush()
        data = sort_unique(self.columns.array)
        if len(data) == 0:
            src = self.source
            missing = [j for j in src.left_joints + src.right_joints if j not in self.names_seen]
            raise BagError(
                f'{self.path}: joint {", ".join(missing) or "?"} not in {src.topic}; joint '
                f'names present: {", ".join(sorted(self.names_seen)) or "none"}')
        return data.T

    def travel(self):
        """Return the times (ns) and cumulative nominal travel of each side (m)."""
        travel = self.decoder.travel(*self._samples())
        if travel is None:
            raise BagError(f'{self.path}: the JointState messages on {self.source.topic} carry '
                           'neither positions nor velocities for the joints')
        return travel

    def velocities(self):
        """Return times (ns) and nominal track speeds (m/s) from the joint velocities, or None."""
        t, _, _, vel_l, vel_r = self._samples()
        return self.decoder.speeds(t, vel_l, vel_r)
