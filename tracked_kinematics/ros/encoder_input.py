"""
Track encoders in, steps of nominal track travel out: the encoder side of any node.

:class:`EncoderInput` subscribes in one of three modes, chosen by the read-only parameter
``input_mode``, turns each message into readings and leaves the arithmetic and the checks
to :class:`tracked_kinematics.core.encoders.IncrementTracker`. The owner gets a callback
``callback(stamp_s, d_left_m, d_right_m, dt_s)`` for every step that passed all checks, and
a throttled warning is logged for every input that did not. Nothing here knows what the
travel is used for: odometry_node and the ICR estimator both use it.

Modes and topics (relative names, remap as usual):

``joint_states``
    ``joint_states`` (sensor_msgs/JointState). The joints of ``left_joints`` and
    ``right_joints`` are averaged per side; positions (rad, exact travel) when the message
    has finite ones for those joints, velocities (rad/s, trapezoidal rule) otherwise;
    times from ``header.stamp``.
``track_speeds``
    ``left_track/speed`` and ``right_track/speed`` (std_msgs/Float64, m/s of nominal track
    speed), paired by arrival, timed by the node's clock (so ``use_sim_time`` applies).
``encoder_ticks``
    ``left_track/ticks`` and ``right_track/ticks`` (std_msgs/Int32 or Int64 by
    ``ticks_type``), wrapping counters of ``ticks_per_revolution`` per sprocket turn,
    paired by arrival, timed by the node's clock.

Every input topic follows its publishers' QoS (:class:`~tracked_kinematics.ros.input_topic.
InputTopic`: reliable publishers lose no sample, sensor-data ones still match). Once a second
the input is checked: a side that stays silent in the per-side modes, and publishers of
another message type on an input topic, are named in a throttled warning.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
import math
import time
from typing import Any

from builtin_interfaces.msg import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Int32, Int64
from tracked_kinematics.core.encoders import IncrementTracker, Status
from tracked_kinematics.core.integration import stamp_ns
from tracked_kinematics.params import JOINT_STATES_TOPIC, SIDE_TOPICS
from tracked_kinematics.ros.input_topic import (CHECK_PERIOD, InputTopic, steady_timer,
                                                WARN_PERIOD)

__all__ = ['check_encoder_values', 'EncoderInput', 'WARN_PERIOD']

# Message type and bit width of each ticks_type.
_TICKS_MESSAGES = {'int32': (Int32, 32), 'int64': (Int64, 64)}
_STEP = Status.STEP
_SIDES = ('left', 'right')


def check_encoder_values(values: Mapping[str, Any]) -> None:
    """
    Check the encoder parameters as a whole.

    Raises
    ------
    ValueError
        When a joint is listed on both sides.

    """
    both = set(values.get('left_joints', ())) & set(values.get('right_joints', ()))
    if both:
        raise ValueError(f'left_joints and right_joints both list {sorted(both)}')


def _stamp_key(msg) -> int:
    stamp = msg.header.stamp
    return stamp_ns(stamp.sec, stamp.nanosec)


def _side_means(values, left_index, right_index):
    return (sum(values[i] for i in left_index) / len(left_index),
            sum(values[i] for i in right_index) / len(right_index))


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
    node : rclpy.node.Node
        Node that owns the subscriptions, the check timer and the logger.
    values : mapping
        Parameter values: those of :data:`tracked_kinematics.params.ENCODER_INPUT_PARAMS`
        and ``sprocket_radius``.
    callback : callable
        ``callback(stamp_s, d_left, d_right, dt)``: nominal travel of each track (m) over a
        step of ``dt`` s ending at ``stamp_s``.

    Attributes
    ----------
    mode : str
        The input mode (fixed for the node's life).
    stamp : builtin_interfaces.msg.Time
        Exact stamp of the sample of the latest step, for output headers.
    received : int
        Encoder messages received (of any side, valid or not).
    counts : collections.Counter
        Samples seen per :class:`~tracked_kinematics.core.encoders.Status` (and
        ``'missing_joints'``, ``'no_readings'``, ``'zero_stamp'``).
    inputs : tuple of InputTopic
        The input topics (one, or left and right).

    """

    def __init__(self, node, values: Mapping[str, Any],
                 callback: Callable[[float, float, float, float], None]):
        self._node = node
        self._logger = node.get_logger()
        self._callback = callback
        self.mode = values['input_mode']
        self.tracker = IncrementTracker()
        self.received = 0
        self.counts: Counter = Counter()
        self.stamp = Time()
        self._joints: tuple[list[str], list[str]] = ([], [])
        self._names = None
        self._index = None
        self._missing: list[str] = []
        self._pending = [None, None]
        self._side_counts = [0, 0]
        self._bits = 64
        self._noted: dict = {}   # status -> steady time of its last log line
        self.configure(values)
        if self.mode == 'joint_states':
            self.inputs = (InputTopic(node, JointState, JOINT_STATES_TOPIC,
                                      self._on_joint_state, order_key=_stamp_key),)
        else:
            if self.mode == 'track_speeds':
                msg_type = Float64
            else:
                msg_type, self._bits = _TICKS_MESSAGES[values['ticks_type']]
            self.inputs = tuple(
                InputTopic(node, msg_type, topic, lambda msg, i=i: self._on_side(i, msg.data))
                for i, topic in enumerate(SIDE_TOPICS[self.mode]))
        self.topics = tuple(topic.topic_name for topic in self.inputs)
        self._timer = steady_timer(node, CHECK_PERIOD, self.check)

    def configure(self, values: Mapping[str, Any]) -> None:
        """Apply (new) parameter values from the next message on."""
        radius = values['sprocket_radius']
        self.tracker.max_dt = values['max_dt']
        self.tracker.max_speed = values['max_plausible_speed']
        if self.mode == 'joint_states':
            self._factor = radius
            joints = (list(values['left_joints']), list(values['right_joints']))
            if joints != self._joints:
                self._joints = joints
                self._names = None  # resolve the indices again
                self.tracker.reset()
        elif self.mode == 'track_speeds':
            self._factor = 1.0
        else:
            self._factor = 2.0 * math.pi * radius / values['ticks_per_revolution']

    def describe(self) -> str:
        """Return one line for the start-up log: mode, topics, joints or ticks, QoS."""
        text = f'input {self.mode} on {", ".join(self.topics)}'
        if self.mode == 'joint_states':
            text += f' (left {self._joints[0]}, right {self._joints[1]})'
        elif self.mode == 'encoder_ticks':
            text += f' ({1.0 / self._factor:.6g} ticks per metre)'
        return text + (f', steps faster than {self.tracker.max_speed:g} m/s skipped')

    def check(self) -> None:
        """Check the input once a second: publishers (QoS, types) and silent sides."""
        for topic in self.inputs:
            topic.check()
        if self.mode == 'joint_states':
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
        where = {name: i for i, name in enumerate(self._names)}
        missing = [j for side in self._joints for j in side if j not in where]
        self._missing = missing
        self._index = None if missing else tuple(
            [where[j] for j in side] for side in self._joints)

    def _on_joint_state(self, msg) -> None:
        self.received += 1
        names = msg.name
        if names != self._names:
            self._resolve(names)
        if self._index is None:
            self.counts['missing_joints'] += 1
            self._logger.warning(
                f'joint_states lacks the joints {self._missing} (it has {self._names}); '
                'set left_joints / right_joints: message skipped',
                throttle_duration_sec=WARN_PERIOD)
            return
        left_index, right_index = self._index
        kind = None
        if len(msg.position) == len(names):
            kind = 'position'
            left, right = _side_means(msg.position, left_index, right_index)
        if ((kind is None or not (math.isfinite(left) and math.isfinite(right)))
                and len(msg.velocity) == len(names)):
            kind = 'velocity'
            left, right = _side_means(msg.velocity, left_index, right_index)
        if kind is None:
            self.counts['no_readings'] += 1
            self._logger.warning(
                'joint_states carries neither positions nor velocities for all its joints: '
                'message skipped', throttle_duration_sec=WARN_PERIOD)
            return
        stamp = msg.header.stamp
        now_ns = stamp_ns(stamp.sec, stamp.nanosec)
        if now_ns == 0:
            self.counts['zero_stamp'] += 1
            self._logger.warning(
                'joint_states has no header.stamp (zero): message skipped; the driver must '
                'stamp its messages', throttle_duration_sec=WARN_PERIOD)
            return
        self._step(now_ns, kind, left, right, stamp)

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
        kind = 'velocity' if self.mode == 'track_speeds' else 'ticks'
        self._step(now.nanoseconds, kind, left, right, now.to_msg())

    # --- common -----------------------------------------------------------------------------

    def _step(self, now_ns: int, kind: str, left, right, stamp) -> None:
        status, d_left, d_right, dt = self.tracker.update(
            now_ns, kind, left, right, self._factor, self._bits)
        self.counts[status] += 1
        if status == _STEP:
            self.stamp = stamp
            self._callback(now_ns * 1e-9, d_left, d_right, dt)
            return
        if status in Status.STEPS:
            self._note(status, kind, left, right, d_left, d_right, dt)
            self.stamp = stamp
            self._callback(now_ns * 1e-9, d_left, d_right, dt)
            return
        if status != Status.DUPLICATE:
            self._note(status, kind, left, right, d_left, d_right, dt)

    def _note(self, status, kind, left, right, d_left, d_right, dt) -> None:
        """
        Log what happened to a sample that was not a plain step, once per WARN_PERIOD per kind.

        A long step that was integrated exactly is information; every other kind a warning.
        """
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
