"""
Track encoders in, steps of nominal track travel out: the encoder side of any node.

:class:`EncoderInput` subscribes in the mode ``input_mode`` chooses (``joint_states``,
``track_speeds``, ``encoder_ticks``) and leaves the arithmetic and the checks to
:class:`tracked_kinematics.core.encoders.IncrementTracker`. See docs/nodes/odometry_node.md
("Encoder input").
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
import importlib
import struct
import time
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from tracked_kinematics.core.encoder_modes import encoder_decoder
from tracked_kinematics.core.encoders import IncrementTracker, Status
from tracked_kinematics.core.integration import stamp_ns
from tracked_kinematics.ros.input_topic import (CHECK_PERIOD, InputTopic, steady_timer,
                                                WARN_PERIOD)

__all__ = ['check_encoder_values', 'EncoderInput', 'JointStateReader', 'WARN_PERIOD']

_STEP = Status.STEP
# JointState messages taken from the queue in one turn of the executor when they wait there
# (the node fell behind): about 2 ms of work here.
DRAIN = 50
_SIDES = ('left', 'right')


def check_encoder_values(values: Mapping[str, Any]) -> None:
    """Check the encoder parameters as a whole; ValueError when a joint is listed on both sides."""
    both = set(values.get('left_joints', ())) & set(values.get('right_joints', ()))
    if both:
        raise ValueError(f'left_joints and right_joints both list {sorted(both)}')


# CDR as rmw_fastrtps writes it on this machine: little-endian XCDR1 (its encapsulation
# header), 4-byte lengths and counts, alignment counted from the end of that header.
_CDR_LE = b'\x00\x01\x00\x00'
_HEAD = 4
_LE_STAMP = struct.Struct('<iI')
_LE_COUNT = struct.Struct('<I')


def _aligned(offset: int, size: int) -> int:
    return offset + (-(offset - _HEAD) % size)


def _doubles(count: int) -> struct.Struct:
    return struct.Struct(f'<{count}d')


class JointStateReader:
    """
    Read the fields of a serialised sensor_msgs/JointState in place, once its layout is known.

    The first message of a layout (encoding, frame id, names, array lengths) is read by rclpy and
    its layout checked against the CDR rules; later ones are read with :func:`struct.unpack_from`.
    Why and how: docs/nodes/odometry_node.md ("Encoder input").
    """

    def __init__(self):
        self._layout = None

    def read(self, data: bytes):
        """
        Return ``(sec, nanosec, names, positions, velocities)`` of a JointState, or None.

        ``names`` is not to be changed.
        """
        layout = self._layout
        if layout is not None:
            size, fixed, names, positions, positions_at, velocities, velocities_at = layout
            if len(data) == size and all(data.startswith(part, at) for at, part in fixed):
                sec, nanosec = _LE_STAMP.unpack_from(data, _HEAD)
                return (sec, nanosec, names, positions.unpack_from(data, positions_at),
                        velocities.unpack_from(data, velocities_at))
        try:
            msg = deserialize_message(data, JointState)
        except Exception:  # noqa: BLE001 -- malformed bytes: the caller reports them
            return None
        self._layout = _layout(data, msg)
        stamp = msg.header.stamp
        return stamp.sec, stamp.nanosec, list(msg.name), msg.position, msg.velocity


class _Elsewhere(Exception):
    """A field is not where the CDR rules put it, or does not hold what rclpy read."""


def _count_end(data: bytes, offset: int, count: int) -> int:
    """Check the 4-byte count or length at ``offset`` (aligned); return where it ends."""
    offset = _aligned(offset, 4)
    if _LE_COUNT.unpack_from(data, offset)[0] != count:
        raise _Elsewhere
    return offset + 4


def _string_end(data: bytes, offset: int, text: str) -> int:
    encoded = text.encode() + b'\0'
    offset = _count_end(data, offset, len(encoded))
    if data[offset:offset + len(encoded)] != encoded:
        raise _Elsewhere
    return offset + len(encoded)


def _layout(data: bytes, msg):
    """Return where the fields of ``msg`` lie in ``data``; None unless CDR's rules hold."""
    if not data.startswith(_CDR_LE):
        return None
    parts = [(0, _HEAD)]  # (start, end) in data

    def part(start, end):
        if start == parts[-1][1]:
            parts[-1] = (parts[-1][0], end)
        else:
            parts.append((start, end))
        return end

    try:
        if _LE_STAMP.unpack_from(data, _HEAD) != (msg.header.stamp.sec,
                                                  msg.header.stamp.nanosec):
            return None
        offset = _HEAD + 8  # after header.stamp
        offset = part(_aligned(offset, 4), _string_end(data, offset, msg.header.frame_id))
        offset = part(_aligned(offset, 4), _count_end(data, offset, len(msg.name)))
        for name in msg.name:
            offset = part(_aligned(offset, 4), _string_end(data, offset, name))
        places = []
        for values in (msg.position, msg.velocity, msg.effort):
            offset = part(_aligned(offset, 4), _count_end(data, offset, len(values)))
            if values:  # the elements are aligned to 8, an empty array takes no padding
                offset = _aligned(offset, 8)
            end = offset + 8 * len(values)
            if data[offset:end] != _doubles(len(values)).pack(*values):
                return None
            places.append(offset)
            offset = end
    except (_Elsewhere, struct.error, UnicodeError):
        return None
    positions_at, velocities_at, _ = places
    return (len(data), tuple((start, data[start:end]) for start, end in parts),
            list(msg.name), _doubles(len(msg.position)), positions_at,
            _doubles(len(msg.velocity)), velocities_at)


def _stamp_key(data: bytes) -> int:
    """Stamp of a serialised JointState, ns: what tells its samples apart in a QoS switch."""
    if data.startswith(_CDR_LE):
        return stamp_ns(*_LE_STAMP.unpack_from(data, _HEAD))
    try:
        stamp = deserialize_message(data, JointState).header.stamp
    except Exception:  # noqa: BLE001 -- malformed: skipped with a warning when passed on
        return -1
    return stamp_ns(stamp.sec, stamp.nanosec)


def _message_class(type_name: str):
    """Return the rclpy message class of ``'pkg/msg/Name'``."""
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


# What a sample that was not a plain step did, as the log says it (str.format fields: dt,
# d_left, d_right, left, right, what, mode, max_dt, max_speed).
_NOTES = {
    Status.LONG_STEP: '{dt:.6g} s without encoder data (more than max_dt {max_dt:g} s): the '
                      'travel across the gap ({d_left:.6g}, {d_right:.6g} m) is exact and was '
                      'integrated as one step',
    Status.RESUMED: 'encoder jump skipped: the counters or positions restarted ({mode}); '
                    'integration resumed from the sample after the jump',
    Status.IMPLAUSIBLE: 'implausible encoder input skipped in {mode}: {what}, faster than '
                        'max_plausible_speed {max_speed:g} m/s (a glitch, a counter restart or '
                        'garbage); integration continues from the next plausible sample',
    Status.NON_FINITE: 'non-finite encoder reading (left {left}, right {right}) in {mode}: '
                       'message skipped',
    Status.TIME_BACK: 'encoder time did not advance ({dt:+.6g} s; sim time reset or bag '
                      'loop?): integration restarted from this message, pose kept',
    Status.GAP: '{dt:.6g} s without encoder data (max_dt {max_dt:g} s) and only velocities to '
                'bridge it: integration restarted from this message, the gap is not integrated',
    Status.KIND_CHANGED: 'joint_states switched between positions and velocities: '
                         'integration restarted from this message',
}


class EncoderInput:
    """
    Subscribe to the track encoders of the selected mode and report travel steps.

    Parameters
    ----------
    values : mapping
        Values of :data:`tracked_kinematics.params.ENCODER_INPUT_PARAMS` and ``sprocket_radius``.
    callback : callable
        ``callback(stamp_s, d_left, d_right, dt)``: nominal travel of each track (m) over a
        step of ``dt`` s ending at ``stamp_s``.
    check_timer : bool
        Run :meth:`check` once a second on a timer of its own; False when the owner calls it.

    Attributes
    ----------
    stamp, stamp_fields, stamp_ns
        Exact stamp of the sample of the latest step: Time, ``(sec, nanosec)``, ns.
    received : int
        Encoder messages received (of any side, valid or not).
    counts : collections.Counter
        Samples seen per :class:`~tracked_kinematics.core.encoders.Status` (and
        ``'missing_joints'``, ``'no_readings'``, ``'zero_stamp'``, ``'unreadable'``).

    """

    def __init__(self, node, values: Mapping[str, Any],
                 callback: Callable[[float, float, float, float], None],
                 check_timer: bool = True):
        self._node = node
        self._logger = node.get_logger()
        self._callback = callback
        self.mode = values['input_mode']
        self.tracker = IncrementTracker()
        self.received = 0
        self.counts: Counter = Counter()
        self.stamp_fields = (0, 0)
        self.stamp_ns = 0
        self._stamp = None
        self._names = None
        self._index = None
        self._missing: list[str] = []
        self._pending = [None, None]
        self._side_counts = [0, 0]
        self._noted: dict = {}   # status -> steady time of its last log line
        self.decoder = None
        self.configure(values)
        decoder = self.decoder
        msg_type = _message_class(decoder.message_types[0])
        if decoder.per_side:
            value = decoder.value
            self.inputs = tuple(
                InputTopic(node, msg_type, topic, lambda msg, i=i: self._on_side(i, value(msg)))
                for i, topic in enumerate(decoder.topics))
        else:
            # JointState: read as bytes in place (JointStateReader), the only one-topic mode.
            self._reader = JointStateReader()
            self.inputs = (InputTopic(node, msg_type, decoder.topics[0], self._on_joint_state,
                                      order_key=_stamp_key, raw=True, drain=DRAIN),)
        self.topics = tuple(topic.topic_name for topic in self.inputs)
        self._timer = steady_timer(node, CHECK_PERIOD, self.check) if check_timer else None

    @property
    def stamp(self) -> Time:
        """Exact stamp of the sample of the latest step (a message made when first asked)."""
        if self._stamp is None:
            sec, nanosec = self.stamp_fields
            self._stamp = Time(sec=sec, nanosec=nanosec)
        return self._stamp

    def configure(self, values: Mapping[str, Any]) -> None:
        """Apply (new) parameter values from the next message on."""
        self.tracker.max_dt = values['max_dt']
        self.tracker.max_speed = values['max_plausible_speed']
        old, self.decoder = self.decoder, encoder_decoder({**values, 'input_mode': self.mode})
        self._factor, self._bits = self.decoder.factor, self.decoder.bits
        if old is not None and getattr(old, 'joints', None) != getattr(self.decoder, 'joints',
                                                                       None):
            self._names = None  # resolve the indices again
            self.tracker.reset()

    def describe(self) -> str:
        """Return one line for the start-up log: mode, topics, joints or ticks, QoS."""
        return (f'input {self.mode} on {", ".join(self.topics)}{self.decoder.describe()}, '
                f'steps faster than {self.tracker.max_speed:g} m/s skipped')

    def check(self) -> None:
        """Check the input once a second: publishers (QoS, types) and silent sides."""
        for topic in self.inputs:
            topic.check()
        if not self.decoder.per_side:
            return
        counts, self._side_counts = self._side_counts, [0, 0]
        for side in (0, 1):
            if counts[side] == 0 and counts[1 - side] > 0:
                self._logger.warning(
                    f'no message on {self.topics[side]} for {CHECK_PERIOD:g} s while '
                    f'{self.topics[1 - side]} had {counts[1 - side]}: without both sides there '
                    f'is no step (is the {_SIDES[side]} encoder publishing, on this topic, as '
                    f'{self.inputs[side].type_name}?)', throttle_duration_sec=WARN_PERIOD)

    # --- joint_states ---------------------------------------------------------------------

    def _resolve(self, names) -> None:
        self._names = list(names)
        self._index = self.decoder.index(self._names)
        self._missing = self.decoder.missing(self._names)

    def _on_joint_state(self, data: bytes) -> None:
        self.received += 1
        fields = self._reader.read(data)
        if fields is None:
            self.counts['unreadable'] += 1
            self._logger.warning(
                'joint_states message that is no serialised sensor_msgs/JointState (a '
                'non-ROS writer?): skipped', throttle_duration_sec=WARN_PERIOD)
            return
        sec, nanosec, names, positions, velocities = fields
        if names != self._names:
            self._resolve(names)
        if self._index is None:
            self.counts['missing_joints'] += 1
            self._logger.warning(
                f'joint_states lacks the joints {self._missing} (it has {self._names}); '
                'set left_joints / right_joints: message skipped',
                throttle_duration_sec=WARN_PERIOD)
            return
        reading = self.decoder.reading(self._index, len(names), positions, velocities)
        if reading is None:
            self.counts['no_readings'] += 1
            self._logger.warning(
                'joint_states carries neither positions nor velocities for all its joints: '
                'message skipped', throttle_duration_sec=WARN_PERIOD)
            return
        now_ns = stamp_ns(sec, nanosec)
        if now_ns == 0:
            self.counts['zero_stamp'] += 1
            self._logger.warning(
                'joint_states has no header.stamp (zero): message skipped; the driver must '
                'stamp its messages', throttle_duration_sec=WARN_PERIOD)
            return
        self._step(now_ns, *reading, sec, nanosec)

    # --- track_speeds and encoder_ticks ---------------------------------------------------

    def _on_side(self, side: int, value) -> None:
        self.received += 1
        self._side_counts[side] += 1
        pending = self._pending
        pending[side] = value
        if pending[0] is None or pending[1] is None:
            return
        left, right = pending
        self._pending = [None, None]
        now = self._node.get_clock().now()
        self._step(now.nanoseconds, self.decoder.kind, left, right, *now.seconds_nanoseconds())

    # --- common -----------------------------------------------------------------------------

    def _step(self, now_ns: int, kind: str, left, right, sec: int, nanosec: int) -> None:
        status, d_left, d_right, dt = self.tracker.update(
            now_ns, kind, left, right, self._factor, self._bits)
        self.counts[status] += 1
        if status == _STEP:
            self._set_stamp(now_ns, sec, nanosec)
            self._callback(now_ns * 1e-9, d_left, d_right, dt)
            return
        if status in Status.STEPS:
            self._note(status, kind, left, right, d_left, d_right, dt)
            self._set_stamp(now_ns, sec, nanosec)
            self._callback(now_ns * 1e-9, d_left, d_right, dt)
            return
        if status != Status.DUPLICATE:
            self._note(status, kind, left, right, d_left, d_right, dt)

    def _set_stamp(self, now_ns: int, sec: int, nanosec: int) -> None:
        self.stamp_ns = now_ns
        self.stamp_fields = (sec, nanosec)
        self._stamp = None

    def _note(self, status, kind, left, right, d_left, d_right, dt) -> None:
        """Log a sample that was not a plain step, once per WARN_PERIOD per kind."""
        now = time.monotonic()
        last = self._noted.get(status)
        if last is not None and now - last < WARN_PERIOD:
            return
        text = self._note_text(status, kind, left, right, d_left, d_right, dt)
        if text is None:
            return
        self._noted[status] = now
        if status == Status.LONG_STEP:
            self._logger.info(text)
        else:
            self._logger.warning(text)

    def _note_text(self, status, kind, left, right, d_left, d_right, dt) -> str | None:
        """Return the log line of a sample that was not a plain step (None: nothing to say)."""
        template = _NOTES.get(status)
        if template is None:
            return None
        what = (f'track speeds {d_left:.6g}, {d_right:.6g} m/s' if kind == 'velocity' else
                f'a step of {d_left:.6g}, {d_right:.6g} m in {dt:.6g} s (readings {left!r}, '
                f'{right!r})')
        return template.format(dt=dt, d_left=d_left, d_right=d_right, left=left, right=right,
                               what=what, mode=self.mode, max_dt=self.tracker.max_dt,
                               max_speed=self.tracker.max_speed)
