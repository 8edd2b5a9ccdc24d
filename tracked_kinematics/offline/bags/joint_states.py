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
from tracked_kinematics.core.encoders import travel_from_velocities, unwrap_if_wrapped
from tracked_kinematics.core.integration import stamp_ns
from tracked_kinematics.offline.errors import BagError

from .columns import _Columns, _sort_unique, _stamp
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

    def decode(self, raws, receive_ns, ref_ns, left, right) -> np.ndarray:
        """Rows ``(t, pos_l, pos_r, vel_l, vel_r)`` of many messages, as :class:`_JointStates`."""
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
                values = column(offset, '<f8', self.count)
                out[:, first] = values[:, left].mean(axis=1)
                out[:, first + 1] = values[:, right].mean(axis=1)
        return out


class _JointStates:
    """JointState messages -> time, per-side mean position and velocity."""

    BATCH = 20_000

    def __init__(self, source: EncoderSource, path: Path, ref_ns: int, ros2: bool):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.ros2 = ros2
        self.columns = _Columns(5)
        self.names_seen: set[str] = set()
        self._index_cache: dict[tuple, tuple | None] = {}
        self._layout = None
        self._layout_indices = None
        self._batch = []
        self._batch_ns = []

    def _indices(self, names):
        key = tuple(names)
        if key not in self._index_cache:
            where = {name: i for i, name in enumerate(key)}
            src = self.source
            try:
                found = ([where[j] for j in src.left_joints], [where[j] for j in src.right_joints])
            except KeyError:
                found = None
                self.names_seen.update(key)
            self._index_cache[key] = found
        return self._index_cache[key]

    def add_raw(self, raw, receive_ns, deserialize) -> None:
        """Take one serialised message: batched when it has the known layout."""
        if self._layout and self._layout.matches(raw):
            self._batch.append(raw)
            self._batch_ns.append(receive_ns)
            if len(self._batch) == self.BATCH:
                self.flush()
            return
        msg = deserialize(raw)
        row = self._row(msg, receive_ns)
        if row is None:
            return
        self.columns.append(row)
        if self._layout is None:
            layout = _Layout.of(raw, self.ros2)
            indices = self._indices(msg.name)
            if layout is not None:
                decoded = layout.decode([bytes(raw)], [receive_ns], self.ref_ns, *indices)[0]
                if np.allclose(decoded, row, equal_nan=True, rtol=1e-12, atol=0.0):
                    self._layout, self._layout_indices = layout, indices
            if self._layout is None:
                self._layout = False   # never try again: every message goes the slow way

    def flush(self) -> None:
        """Decode the batched messages."""
        if self._batch:
            self.columns.extend(self._layout.decode(self._batch, self._batch_ns, self.ref_ns,
                                                    *self._layout_indices))
            self._batch, self._batch_ns = [], []

    def _row(self, msg, receive_ns):
        indices = self._indices(msg.name)
        if indices is None:
            return None
        left, right = indices
        n = len(msg.name)
        nan = float('nan')
        row = [_stamp(msg.header, receive_ns, self.ref_ns), nan, nan, nan, nan]
        for values, first in ((msg.position, 1), (msg.velocity, 3)):
            if len(values) == n:
                row[first] = sum(float(values[i]) for i in left) / len(left)
                row[first + 1] = sum(float(values[i]) for i in right) / len(right)
        return row

    def travel(self):
        """Return the times (ns) and cumulative nominal travel of each side (m)."""
        if self._layout:
            self.flush()
        data = _sort_unique(self.columns.array)
        if len(data) == 0:
            src = self.source
            missing = [j for j in src.left_joints + src.right_joints if j not in self.names_seen]
            raise BagError(
                f'{self.path}: joint {", ".join(missing) or "?"} not in {src.topic}; joint '
                f'names present: {", ".join(sorted(self.names_seen)) or "none"}')
        t, pos_l, pos_r, vel_l, vel_r = data.T
        radius = self.source.sprocket_radius
        positions = np.isfinite(pos_l) & np.isfinite(pos_r)
        if np.count_nonzero(positions) >= 2 and np.count_nonzero(positions) >= 0.5 * len(t):
            t = t[positions]
            return (t, unwrap_if_wrapped(pos_l[positions]) * radius,
                    unwrap_if_wrapped(pos_r[positions]) * radius)
        ok = np.isfinite(vel_l) & np.isfinite(vel_r)
        t, vel_l, vel_r = t[ok], vel_l[ok], vel_r[ok]
        if len(t) < 2:
            raise BagError(f'{self.path}: the JointState messages on {self.source.topic} carry '
                           'neither positions nor velocities for the joints')
        seconds = t * 1e-9
        return t, *(np.concatenate([[0.0], np.cumsum(travel_from_velocities(v, seconds, radius))])
                    for v in (vel_l, vel_r))

    def velocities(self):
        """Return times (ns) and nominal track speeds (m/s) from the joint velocities, or None."""
        if self._layout:
            self.flush()
        data = _sort_unique(self.columns.array)
        if len(data) == 0:
            self.travel()   # raises the missing-joint error
        t, _, _, vel_l, vel_r = data.T
        ok = np.isfinite(vel_l) & np.isfinite(vel_r)
        if np.count_nonzero(ok) < 2 or np.count_nonzero(ok) < 0.5 * len(t):
            return None
        radius = self.source.sprocket_radius
        return t[ok], vel_l[ok] * radius, vel_r[ok] * radius
