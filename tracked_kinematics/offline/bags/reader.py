"""
Read encoder travel, ground-truth poses and setpoints from rosbags into plain arrays.

rosbag2 directories (sqlite3, mcap) and ROS 1 ``.bag`` files are read with
``rosbags.highlevel.AnyReader``, one bag at a time, streaming only the topics asked for.
Each message is reduced to a few numbers appended to growing numpy buffers, so memory grows
with the number of samples (tens of bytes each), never with the size of the bag.

One message loop (:func:`_read`) serves every reader: it feeds the encoder messages to
their decoder and the others to the decoder of the second stream, the ground truth for
:func:`read_bag`, the commands for :func:`read_drive_bag`, both for
:func:`read_evaluation_bag`. What the streams are and how
they are chosen: :mod:`.sources`.
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from pathlib import Path
import struct

import numpy as np
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.encoders import (
    counter_increments, travel_from_ticks, travel_from_velocities, unwrap_if_wrapped)
from tracked_kinematics.core.errors import SensorDataError
from tracked_kinematics.core.identify import DriveData, Recording
from tracked_kinematics.core.integration import compose, stamp_ns, yaw_from_quaternion
from tracked_kinematics.offline.errors import BagError

from .sources import (CMD_VEL_TYPES, CommandSource, EncoderSource, GROUND_TRUTH_TYPES,
                      GroundTruthSource, SETPOINT_TOPICS, TICK_BITS)


class _Columns:
    """Growing float64 columns, doubled in place: appends are amortised O(1)."""

    def __init__(self, width: int, capacity: int = 1024):
        self._data = np.empty((capacity, width))
        self.n = 0

    def append(self, row) -> None:
        if self.n == len(self._data):
            self._data = np.concatenate([self._data, np.empty_like(self._data)])
        self._data[self.n] = row
        self.n += 1

    def extend(self, rows) -> None:
        while self.n + len(rows) > len(self._data):
            self._data = np.concatenate([self._data, np.empty_like(self._data)])
        self._data[self.n:self.n + len(rows)] = rows
        self.n += len(rows)

    @property
    def array(self) -> np.ndarray:
        return self._data[:self.n]


def _stamp(header, receive_ns: int, ref_ns: int) -> float:
    """Header stamp in ns after ``ref_ns`` (receive time when the stamp was never filled)."""
    ns = stamp_ns(header.stamp.sec, header.stamp.nanosec)
    return float((ns if ns > 0 else receive_ns) - ref_ns)


def _yaw(q) -> float:
    return yaw_from_quaternion(q.x, q.y, q.z, q.w)


def _sort_unique(columns: np.ndarray) -> np.ndarray:
    """Rows sorted by their first column (time), the first of equal times kept."""
    if len(columns) == 0:
        return columns
    columns = columns[np.argsort(columns[:, 0], kind='stable')]
    keep = np.concatenate([[True], np.diff(columns[:, 0]) > 0])
    return columns[keep]


def _strip(frame: str) -> str:
    return frame.lstrip('/')


class _Progress:
    """A progress bar on stderr when it is a terminal (tqdm), else nothing."""

    def __init__(self, total: int, description: str, enabled: bool):
        self._bar = None
        self._pending = 0
        if enabled:
            try:
                from tqdm import tqdm
            except ImportError:  # optional: progress is a nicety
                return
            self._bar = tqdm(total=total, desc=description, unit='msg', unit_scale=True,
                             leave=False)

    def step(self) -> None:
        if self._bar is not None:
            self._pending += 1
            if self._pending == 2000:
                self._bar.update(self._pending)
                self._pending = 0

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _open(path: Path) -> AnyReader:
    if not path.exists():
        raise BagError(f'bag not found: {path}')
    return AnyReader([path])


def _topic_list(reader: AnyReader) -> str:
    topics = sorted((c.topic, c.msgtype) for c in reader.connections)
    return ', '.join(f'{t} ({m})' for t, m in dict(topics).items()) or 'none'


def _connections(reader: AnyReader, path: Path, topic: str, allowed, what: str):
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise BagError(f'{path}: no topic {topic} for the {what}; topics present: '
                       f'{_topic_list(reader)}')
    bad = sorted({c.msgtype for c in conns if c.msgtype not in allowed})
    if bad:
        raise BagError(f'{path}: topic {topic} has type {", ".join(bad)}, the {what} need '
                       f'{" or ".join(allowed)}')
    return conns


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


class _SideStream:
    """Per-side Float64 speeds or Int32/Int64 tick counters -> cumulative travel."""

    def __init__(self, source: EncoderSource, path: Path, ref_ns: int):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.columns = {source.left_topic: _Columns(2), source.right_topic: _Columns(2)}
        self.bits = {}
        self.first = {}

    def add(self, topic, msgtype, msg, receive_ns) -> None:
        self.bits[topic] = TICK_BITS.get(msgtype, 0)
        # Counters relative to their first value, so that floats hold them exactly.
        first = self.first.setdefault(topic, msg.data if self.bits[topic] else 0)
        self.columns[topic].append((float(receive_ns - self.ref_ns), float(msg.data - first)))

    def _side(self, topic):
        data = self.columns[topic].array
        if len(data) < 2:
            raise BagError(f'{self.path}: fewer than two messages on {topic}')
        order = np.argsort(data[:, 0], kind='stable')
        t = data[order, 0]
        values = data[order, 1]
        keep = np.concatenate([[True], np.diff(t) > 0])
        t, values = t[keep], values[keep]
        if self.source.mode == 'track_speeds':
            travel = travel_from_velocities(values, t * 1e-9)
        else:
            travel = travel_from_ticks(counter_increments(values.astype(np.int64),
                                                          self.bits[topic]),
                                       self.source.ticks_per_revolution,
                                       self.source.sprocket_radius)
        return t, np.concatenate([[0.0], np.cumsum(travel)])

    def travel(self):
        """Return common times (ns) and the cumulative nominal travel of each side (m)."""
        (t_l, c_l), (t_r, c_r) = (self._side(self.source.left_topic),
                                  self._side(self.source.right_topic))
        lo, hi = max(t_l[0], t_r[0]), min(t_l[-1], t_r[-1])
        t = np.union1d(t_l, t_r)
        t = t[(t >= lo) & (t <= hi)]
        return t, np.interp(t, t_l, c_l), np.interp(t, t_r, c_r)


class _GroundTruth:
    """Pose messages -> time, x, y, yaw of base_link."""

    def __init__(self, source: GroundTruthSource, path: Path, ref_ns: int):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.columns = _Columns(4)
        self.pairs: set[tuple[str, str]] = set()
        self._parent = _strip(source.parent_frame) or None

    def connections(self, reader: AnyReader):
        """Return the bag connections of the ground-truth topic (checked)."""
        return _connections(reader, self.path, self.source.topic, GROUND_TRUTH_TYPES,
                            'ground truth')

    def add(self, conn, msg, receive_ns) -> None:
        msgtype = conn.msgtype
        if msgtype == 'tf2_msgs/msg/TFMessage':
            child = _strip(self.source.child_frame)
            for tf in msg.transforms:
                parent = _strip(tf.header.frame_id)
                self.pairs.add((parent, _strip(tf.child_frame_id)))
                if _strip(tf.child_frame_id) != child:
                    continue
                if self._parent is None:
                    self._parent = parent
                if parent == self._parent:
                    tr = tf.transform
                    self.columns.append((_stamp(tf.header, receive_ns, self.ref_ns),
                                         tr.translation.x, tr.translation.y, _yaw(tr.rotation)))
            return
        pose = msg.pose.pose if msgtype in ('nav_msgs/msg/Odometry',
                                            'geometry_msgs/msg/PoseWithCovarianceStamped') \
            else msg.pose
        self.columns.append((_stamp(msg.header, receive_ns, self.ref_ns), pose.position.x,
                             pose.position.y, _yaw(pose.orientation)))

    def poses(self):
        """Return the times (ns), x, y, yaw of base_link."""
        src = self.source
        child = _strip(src.child_frame)
        parents = sorted({p for p, c in self.pairs if c == child})
        pairs = ', '.join(f'{p} -> {c}' for p, c in sorted(self.pairs))
        if len(parents) > 1 and not src.parent_frame:
            raise BagError(
                f'{self.path}: several transforms to {child} on {src.topic} ({", ".join(parents)}'
                ' are parents); choose one with --ground-truth-parent-frame')
        data = self.columns.array
        data = _sort_unique(data[np.all(np.isfinite(data), axis=1)])
        if len(data) < 2:
            what = f'transforms {src.parent_frame or "?"} -> {child}' if self.pairs else 'poses'
            raise BagError(f'{self.path}: fewer than two ground-truth {what} on {src.topic}'
                           + (f'; transforms present: {pairs}' if self.pairs else ''))
        t, x, y, yaw = data.T
        ox, oy, oyaw = src.offset
        if ox or oy or oyaw:
            # base_link = body (+) offset^-1
            back_x = -(math.cos(oyaw) * ox + math.sin(oyaw) * oy)
            back_y = -(-math.sin(oyaw) * ox + math.cos(oyaw) * oy)
            x, y, yaw = compose(x, y, yaw, back_x, back_y, -oyaw)
        return t, x, y, np.angle(np.exp(1j * yaw))


class _Commands:
    """
    Setpoints per side, or cmd_vel through the ideal inverse -> track commands held until next.

    Which stream is chosen when the bag is opened (:class:`CommandSource` ``kind``); with
    ``required`` a bag without it is an error, else it simply has no commands.
    """

    def __init__(self, source: CommandSource, path: Path, ref_ns: int, required: bool = True):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.required = required
        self.kind = None      # 'setpoints' or 'cmd_vel' once chosen
        self.sides = {topic: _Columns(2) for topic in source.setpoint_topics}
        self.twists = _Columns(3)

    def _choose(self, reader: AnyReader) -> str | None:
        src = self.source
        if src.kind != 'auto':
            return None if src.kind == 'none' else src.kind
        present = {c.topic for c in reader.connections}
        if all(topic in present for topic in src.setpoint_topics):
            return 'setpoints'
        if src.cmd_vel_topic in present:
            return 'cmd_vel'
        if self.required:
            missing = next(t for t in src.setpoint_topics if t not in present)
            raise BagError(f'{self.path}: no topic {missing} for the setpoints (nor '
                           f'{src.cmd_vel_topic} for cmd_vel); topics present: '
                           f'{_topic_list(reader)}')
        return None

    def connections(self, reader: AnyReader):
        """Return the bag connections of the command topics (checked)."""
        self.kind = self._choose(reader)
        if self.kind == 'setpoints':
            return [c for topic in self.source.setpoint_topics
                    for c in _connections(reader, self.path, topic, ('std_msgs/msg/Float64',),
                                          'setpoints')]
        if self.kind == 'cmd_vel':
            if not math.isfinite(self.source.track_width) or self.source.track_width <= 0:
                raise BagError(f'{self.path}: the commands on {self.source.cmd_vel_topic} are '
                               'body twists; turning them into track speeds needs the track '
                               'width (--track-width or --params)')
            return _connections(reader, self.path, self.source.cmd_vel_topic, CMD_VEL_TYPES,
                                'commands')
        return []

    def add(self, conn, msg, receive_ns) -> None:
        if self.kind == 'setpoints':
            self.sides[conn.topic].append((float(receive_ns - self.ref_ns), float(msg.data)))
            return
        twist = msg
        t = float(receive_ns - self.ref_ns)
        if conn.msgtype == 'geometry_msgs/msg/TwistStamped':
            twist = msg.twist
            t = _stamp(msg.header, receive_ns, self.ref_ns)
        self.twists.append((t, float(twist.linear.x), float(twist.angular.z)))

    def commands(self):
        """
        Return the times (ns) and the commanded track speeds (m/s), each held until the next.

        None when the bag has no commands (and none were required).
        """
        if self.kind == 'cmd_vel':
            data = self.twists.array
            data = _sort_unique(data[np.all(np.isfinite(data), axis=1)])
            if len(data) < 2:
                raise BagError(f'{self.path}: fewer than two finite messages on '
                               f'{self.source.cmd_vel_topic}')
            # The ideal inverse: V_l = v - w B / 2, V_r = v + w B / 2 (nominal track speeds).
            half = 0.5 * self.source.track_width
            return data[:, 0], np.column_stack([data[:, 1] - half * data[:, 2],
                                                data[:, 1] + half * data[:, 2]])
        if self.kind != 'setpoints':
            return None
        # Setpoints of both sides on the union of their stamps.
        topics = self.source.setpoint_topics
        data = [_sort_unique(self.sides[topic].array) for topic in topics]
        for topic, side in zip(topics, data):
            if len(side) < 2:
                raise BagError(f'{self.path}: fewer than two messages on {topic}')
        command_t = np.union1d(data[0][:, 0], data[1][:, 0])
        command_t = command_t[command_t >= max(data[0][0, 0], data[1][0, 0])]
        held = [side[np.searchsorted(side[:, 0], command_t, side='right') - 1, 1]
                for side in data]
        return command_t, np.column_stack(held)


class _GroundTruthAndCommands:
    """The ground truth and, when the bag has them, the commands: evaluate_model's stream."""

    def __init__(self, sources, path: Path, ref_ns: int):
        ground_truth, commands = sources
        self.ground_truth = _GroundTruth(ground_truth, path, ref_ns)
        self.commands = _Commands(commands, path, ref_ns, required=commands.kind != 'auto')
        self._command_ids: set = set()

    def connections(self, reader: AnyReader):
        """Return the connections of both streams (checked)."""
        ground_truth = self.ground_truth.connections(reader)
        commands = [c for c in self.commands.connections(reader) if c not in ground_truth]
        self._command_ids = {id(c) for c in commands}
        return ground_truth + commands

    def add(self, conn, msg, receive_ns) -> None:
        if id(conn) in self._command_ids:
            self.commands.add(conn, msg, receive_ns)
        else:
            self.ground_truth.add(conn, msg, receive_ns)


def _guarded(path: Path, read, *args):
    """Open a bag and ``read(reader, path, *args)`` it; any reader failure is a BagError."""
    try:
        reader = _open(path)
        with reader:
            return read(reader, path, *args)
    except (BagError, SensorDataError):   # already one line about the bag's content
        raise
    except Exception as err:  # noqa: BLE001 -- rosbags and sqlite raise many kinds
        detail = ' '.join(str(err).split()) or type(err).__name__
        raise BagError(f'cannot read bag {path}: {detail} (truncated or corrupt?)') from None


def _encoder_stream(reader, path, encoders, ref_ns):
    """Return the decoder of the encoder messages and the bag connections it reads."""
    if encoders.mode == 'joint_states':
        enc = _JointStates(encoders, path, ref_ns, reader.is2)
        return enc, _connections(reader, path, encoders.topic, ('sensor_msgs/msg/JointState',),
                                 'encoders')
    enc = _SideStream(encoders, path, ref_ns)
    allowed = (('std_msgs/msg/Float64',) if encoders.mode == 'track_speeds'
               else tuple(TICK_BITS))
    return enc, [c for topic in encoders.topics()
                 for c in _connections(reader, path, topic, allowed, 'encoders')]


def _feed(enc, reader, conn, receive_ns, raw) -> None:
    """Pass one encoder message to its decoder (JointStates decode their columns lazily)."""
    if isinstance(enc, _JointStates):
        enc.add_raw(raw, receive_ns, lambda data, t=conn.msgtype: reader.deserialize(data, t))
    else:
        enc.add(conn.topic, conn.msgtype, reader.deserialize(raw, conn.msgtype), receive_ns)


def _read(reader, path, encoders, kind, source, progress):
    """
    Stream the encoder messages and those of one other stream: the one message loop.

    Parameters
    ----------
    reader : AnyReader
        The open bag.
    path : Path
        Its path, for the messages.
    encoders : EncoderSource
        Where the encoders are.
    kind : type
        Decoder of the other stream, made as ``kind(source, path, reader.start_time)``; it
        gives the bag connections it reads (checked) by ``connections(reader)`` and takes
        each message by ``add(connection, message, receive_ns)``.
    source
        What the other stream is (a :class:`GroundTruthSource`, the setpoint topics).
    progress : bool
        Show a progress bar on stderr.

    Returns
    -------
    tuple
        The encoder decoder and the other decoder, fed with every message.

    """
    ref_ns = reader.start_time
    enc, enc_conns = _encoder_stream(reader, path, encoders, ref_ns)
    other = kind(source, path, ref_ns)
    other_conns = other.connections(reader)
    other_ids = {id(c) for c in other_conns}
    conns = enc_conns + [c for c in other_conns if c not in enc_conns]
    bar = _Progress(sum(c.msgcount for c in conns), path.name, progress)
    try:
        for conn, receive_ns, raw in reader.messages(connections=conns):
            if id(conn) in other_ids:
                other.add(conn, reader.deserialize(raw, conn.msgtype), receive_ns)
            else:
                _feed(enc, reader, conn, receive_ns, raw)
            bar.step()
    finally:
        bar.close()
    return enc, other


def read_bag(path, encoders: EncoderSource, ground_truth: GroundTruthSource,
             progress: bool = False) -> Recording:
    """
    Read one bag into a :class:`Recording`.

    Times are seconds from the first sample of either stream.

    Raises
    ------
    BagError
        For a missing or unreadable bag, a missing topic, joint or transform, or too few
        samples; the message is one line.

    """
    return _guarded(Path(path), _read_recording, encoders, ground_truth, progress)


def _read_recording(reader, path, encoders, ground_truth, progress) -> Recording:
    enc, gt = _read(reader, path, encoders, _GroundTruth, ground_truth, progress)
    enc_t, left, right = enc.travel()
    gt_t, x, y, yaw = gt.poses()
    t0 = min(enc_t[0], gt_t[0])
    return Recording((enc_t - t0) * 1e-9, left, right, (gt_t - t0) * 1e-9, x, y, yaw,
                     name=str(path))


def read_bags(paths, encoders: EncoderSource, ground_truth: GroundTruthSource,
              progress: bool = False) -> list[Recording]:
    """Read several bags, one :class:`Recording` each (see :func:`read_bag`)."""
    return [read_bag(p, encoders, ground_truth, progress) for p in paths]


def read_drive_bag(path, encoders: EncoderSource, setpoint_topics=SETPOINT_TOPICS,
                   progress: bool = False, commands: CommandSource | None = None) -> DriveData:
    """
    Read the commanded and measured track speeds of one bag, to identify its drive train.

    Commands: std_msgs/Float64 setpoints per side (m/s of nominal track speed, as
    cmd_vel_translator publishes them), timed by the bag's receive time; or, with
    ``commands`` of kind ``cmd_vel`` (or ``auto`` on a bag without setpoints), the body twists
    of a geometry_msgs/Twist or TwistStamped topic through the ideal inverse ``v -/+ w B / 2``
    (TwistStamped timed by its stamp). Measured speeds: the joint velocities times the
    sprocket radius when the JointStates carry them, else the encoder travel differentiated
    between samples (stamped at the midpoints).

    Parameters
    ----------
    path : path-like
        rosbag2 directory or ROS 1 ``.bag`` file.
    encoders : EncoderSource
        Where the track encoders are.
    setpoint_topics : pair of str
        Left and right setpoint topics (when ``commands`` is not given).
    progress : bool
        Show a progress bar on stderr.
    commands : CommandSource, optional
        Where the commands are; default the setpoints on ``setpoint_topics``.

    Returns
    -------
    DriveData
        Times in seconds from the bag's start.

    Raises
    ------
    BagError
        For a missing or unreadable bag, a missing topic or joint, or too few messages.

    """
    if commands is None:
        commands = CommandSource('setpoints', tuple(setpoint_topics))
    elif commands.kind == 'none':
        raise ValueError('a drive-train bag needs commands')
    return _guarded(Path(path), _read_drive, encoders, commands, progress)


def _read_drive(reader, path, encoders, commands, progress) -> DriveData:
    enc, setpoints = _read(reader, path, encoders, _Commands, commands, progress)
    speeds = enc.velocities() if encoders.mode == 'joint_states' else None
    if speeds is None:
        t, left, right = enc.travel()
        dt = np.diff(t) * 1e-9
        if not np.all(dt > 0) or len(t) < 2:
            raise BagError(f'{path}: fewer than two encoder samples')
        speeds = (0.5 * (t[1:] + t[:-1]), np.diff(left) / dt, np.diff(right) / dt)
    speed_t, v_left, v_right = speeds
    command_t, values = setpoints.commands()
    return DriveData(command_t * 1e-9, values, np.asarray(speed_t) * 1e-9,
                     np.column_stack([v_left, v_right]), name=str(path))


def read_evaluation_bag(path, encoders: EncoderSource, ground_truth: GroundTruthSource,
                        commands: CommandSource = CommandSource('auto'),
                        progress: bool = False):
    """
    Read the encoders, the ground truth and, when the bag has them, the commands of one bag.

    One pass over the bag (evaluate_model). Times are seconds from the first sample of the
    encoders or the ground truth, as :func:`read_bag`.

    Returns
    -------
    recording : Recording
    commands : tuple or None
        ``(t, values, kind)``: times (s), ``(N, 2)`` nominal track commands (m/s) held until
        the next, and ``'setpoints'`` or ``'cmd_vel'``; None when the bag has none (with
        ``commands.kind`` ``auto`` or ``none``).

    Raises
    ------
    BagError
        As :func:`read_bag`; for commands of a kind asked for that the bag lacks; for cmd_vel
        without a track width.

    """
    return _guarded(Path(path), _read_evaluation, encoders, (ground_truth, commands), progress)


def _read_evaluation(reader, path, encoders, sources, progress):
    enc, other = _read(reader, path, encoders, _GroundTruthAndCommands, sources, progress)
    enc_t, left, right = enc.travel()
    gt_t, x, y, yaw = other.ground_truth.poses()
    t0 = min(enc_t[0], gt_t[0])
    recording = Recording((enc_t - t0) * 1e-9, left, right, (gt_t - t0) * 1e-9, x, y, yaw,
                          name=str(path))
    found = other.commands.commands()
    if found is None:
        return recording, None
    command_t, values = found
    return recording, ((command_t - t0) * 1e-9, values, other.commands.kind)
