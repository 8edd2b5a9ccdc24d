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
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
import math
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Int32, Int64
from tracked_kinematics.core.encoders import IncrementTracker, Status
from tracked_kinematics.core.integration import stamp_ns
from tracked_kinematics.params import JOINT_STATES_TOPIC, SIDE_TOPICS

# Message type and bit width of each ticks_type.
_TICKS_MESSAGES = {'int32': (Int32, 32), 'int64': (Int64, 64)}

# Seconds between two warnings about the same kind of bad input.
WARN_PERIOD = 5.0


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


def _side_means(values, left_index, right_index):
    return (sum(values[i] for i in left_index) / len(left_index),
            sum(values[i] for i in right_index) / len(right_index))


class EncoderInput:
    """
    Subscribe to the track encoders of the selected mode and report travel steps.

    Parameters
    ----------
    node : rclpy.node.Node
        Node that owns the subscriptions and the logger.
    values : mapping
        Parameter values: those of :data:`tracked_kinematics.params.ENCODER_INPUT_PARAMS`
        and ``sprocket_radius``.
    callback : callable
        ``callback(stamp_s, d_left, d_right, dt)``: nominal travel of each track (m) over a
        step of ``dt`` s ending at ``stamp_s``.
    qos : rclpy.qos.QoSProfile
        Subscription QoS; sensor data (best effort) by default, like diff_drive_controller.

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

    """

    def __init__(self, node, values: Mapping[str, Any],
                 callback: Callable[[float, float, float, float], None],
                 qos=qos_profile_sensor_data):
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
        self._bits = 64
        self.configure(values)
        if self.mode == 'joint_states':
            self.topics = (node.create_subscription(
                JointState, JOINT_STATES_TOPIC, self._on_joint_state, qos).topic_name,)
            return
        if self.mode == 'track_speeds':
            msg_type = Float64
        else:
            msg_type, self._bits = _TICKS_MESSAGES[values['ticks_type']]
        self.topics = tuple(
            node.create_subscription(msg_type, topic,
                                     lambda msg, i=i: self._on_side(i, msg.data), qos).topic_name
            for i, topic in enumerate(SIDE_TOPICS[self.mode]))

    def configure(self, values: Mapping[str, Any]) -> None:
        """Apply (new) parameter values from the next message on."""
        radius = values['sprocket_radius']
        self.tracker.max_dt = values['max_dt']
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
        """Return one line for the start-up log: mode, topics, joints or ticks."""
        text = f'input {self.mode} on {", ".join(self.topics)}'
        if self.mode == 'joint_states':
            text += f' (left {self._joints[0]}, right {self._joints[1]})'
        elif self.mode == 'encoder_ticks':
            text += f' ({1.0 / self._factor:.6g} ticks per metre)'
        return text

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
        if status == Status.STEP:
            self.stamp = stamp
            self._callback(now_ns * 1e-9, d_left, d_right, dt)
        elif status == Status.NON_FINITE:
            self._logger.warning(
                f'non-finite encoder reading (left {left}, right {right}) in {self.mode}: '
                'message skipped', throttle_duration_sec=WARN_PERIOD)
        elif status == Status.TIME_BACK:
            self._logger.warning(
                f'encoder time did not advance ({dt:+.6g} s; sim time reset or bag loop?): '
                'integration restarted from this message, pose kept',
                throttle_duration_sec=WARN_PERIOD)
        elif status == Status.GAP:
            self._logger.warning(
                f'{dt:.6g} s without encoder data (max_dt {self.tracker.max_dt:g} s): '
                'integration restarted from this message, the gap is not integrated',
                throttle_duration_sec=WARN_PERIOD)
        elif status == Status.KIND_CHANGED:
            self._logger.warning(
                f'joint_states switched to {kind}s: integration restarted from this message',
                throttle_duration_sec=WARN_PERIOD)
