"""
cmd_vel_translator: body twist commands to track speed setpoints through the tread ICRs.

Converts messages, keeps time and publishes at a fixed rate from a thread paced on the steady
clock; the maths is :mod:`tracked_kinematics.core.command`. Topics, the timeout and stamp
rule, clock faults and the output guard: docs/nodes/cmd_vel_translator.md.
"""

from __future__ import annotations

from collections.abc import Mapping
import math
import threading
import time
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from std_msgs.msg import Float64, Float64MultiArray
from tracked_kinematics.core.clock_watch import ClockWatch
from tracked_kinematics.core.command import (CommandLimiter, CommandLimits, exceeds_envelope,
                                             setpoint_problem, setpoint_twist,
                                             TRACK_SPEED_ENVELOPE)
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.params import icr_from_values, LIMIT_FIELDS, limits_from_values
from tracked_kinematics.params.node_tables import CMD_VEL_TYPE_NAMES, TRANSLATOR_PARAMS
from tracked_kinematics.ros.health import Health
from tracked_kinematics.ros.loop_thread import LoopNode
from tracked_kinematics.ros.main import run

NODE_NAME = 'cmd_vel_translator'

# cmd_vel_type -> message class; the ROS type names the graph reports.
CMD_VEL_TYPES = dict(zip(CMD_VEL_TYPE_NAMES, (Twist, TwistStamped), strict=True))
_TYPE_NAMES = {Twist: 'geometry_msgs/msg/Twist', TwistStamped: 'geometry_msgs/msg/TwistStamped'}
_TYPES_BY_NAME = {name: cls for cls, name in _TYPE_NAMES.items()}

GRAPH_POLL_PERIOD = 0.5  # s between looks at the cmd_vel publishers
WARN_PERIOD = 1.0  # s, throttle of the warnings on recurring bad input
GRAPH_WARN_PERIOD = 10.0  # s, throttle of the warnings on the graph
FUTURE_STAMP = 1.0  # s a TwistStamped may be ahead of the node's clock without a warning
# Slowest simulation (x real time) whose commands the steady-clock bound never times out
# early: under simulated time a command is stale after cmd_timeout / SLOWEST_SIM_RATE of
# steady time without a new one, whatever /clock says.
SLOWEST_SIM_RATE = 0.02
FAULT_WARN_PERIOD = 5.0  # s between warnings of one clock fault that lasts


def forced_type(values: Mapping[str, Any]):
    """
    Return the message class ``cmd_vel_type`` / ``use_stamped`` force, None for auto.

    ValueError when the two contradict each other.
    """
    kind = values.get('cmd_vel_type', 'auto')
    if values.get('use_stamped', False):
        if kind == 'twist':
            raise ValueError('use_stamped true contradicts cmd_vel_type twist (use_stamped is '
                             'an alias of cmd_vel_type twist_stamped)')
        kind = 'twist_stamped'
    return CMD_VEL_TYPES.get(kind)


def model_from_values(values: Mapping[str, Any]) -> tuple[IcrParams, CommandLimits]:
    """Return the kinematic model and command limits (ValueError in ROS names)."""
    forced_type(values)
    return icr_from_values(values), limits_from_values(values)


def _timeout(value: float) -> float:
    """Return the limiter's timeout for ``cmd_timeout``: 0 is none (inf)."""
    return math.inf if value == 0.0 else value


def _describe_limits(limits: CommandLimits) -> str:
    set_limits = []
    for name, field in LIMIT_FIELDS.items():
        value = getattr(limits, field)
        accel = field.replace('decel', 'accel')
        if math.isfinite(value) and (accel == field or value != getattr(limits, accel)):
            set_limits.append(f'{name} {value:g}')
    return ', '.join(set_limits) or 'none'


def _describe_timeout(timeout: float) -> str:
    return f'cmd_timeout {timeout:g} s' if math.isfinite(timeout) else 'no cmd_timeout'


class CmdVelTranslator(LoopNode):
    """
    Subscribe to twist commands, publish limited track speed setpoints at a fixed rate.

    A :class:`~tracked_kinematics.ros.loop_thread.LoopNode` of :data:`TRANSLATOR_PARAMS`;
    ``ParameterError`` when the parameters given at start are invalid.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, TRANSLATOR_PARAMS, model_from_values, **kwargs)

    def _start(self, values: Mapping[str, Any]) -> None:
        icr, limits = model_from_values(values)
        self._limiter = CommandLimiter(icr, limits, _timeout(values['cmd_timeout']))
        self._lock = threading.Lock()  # the limiter is shared by the executor and publisher
        self._radius = values['sprocket_radius']
        self._period = 1.0 / values['rate']
        self._t0 = self.get_clock().now().nanoseconds
        self._watch = ClockWatch(values['clock_stall_timeout'])
        self._fault_kind = ''  # the clock fault in force, without its numbers ('' healthy)
        self._fault_warned = -math.inf  # steady time of its last warning
        self._last_steady = time.monotonic()  # of the last publish
        self._was_stale = True
        self._lateral_noted = False
        self._zero_stamp_noted = False

        self._left_msg, self._right_msg = Float64(), Float64()  # reused: fewer allocations
        self._joint_msg = Float64MultiArray()
        self._out_msg = TwistStamped()
        self._left_pub = self.create_publisher(Float64, 'left_track/setpoint', 10)
        self._right_pub = self.create_publisher(Float64, 'right_track/setpoint', 10)
        joint_topic = values['joint_velocity_topic']
        self._joint_pub = (self.create_publisher(Float64MultiArray, joint_topic, 10)
                           if joint_topic else None)
        self._out_pub = (self.create_publisher(TwistStamped, '~/cmd_vel_out', 10)
                         if values['publish_limited_velocity'] else None)
        self._out_wanted = False  # someone subscribes to ~/cmd_vel_out (graph poll)

        # cmd_vel: a forced type, or the one its publishers use (Twist while there are none).
        self._forced = forced_type(values)
        self.health = Health(self)  # /diagnostics; a quiet cmd_vel is normal: not needed
        self._cmd_count = self.health.watch_topic('cmd_vel', _TYPES_BY_NAME, needed=False)
        self._sub = None
        self._sub_type = None
        self._subscribe(self._forced or Twist)
        self._topic = self._sub.topic_name
        self._wanted_type = None
        if self._forced is None:
            wanted = self._publisher_type(self._graph())
            if wanted is not None and wanted is not self._sub_type:
                self._resubscribe(wanted)
        self._switch = self.create_guard_condition(self._apply_wanted_type)

        self._last_publish = time.monotonic()
        # The publishing thread; its wake event is a stop or a new rate (reschedule at once).
        self._start_loop(self._publish_loop, 'setpoint_publisher', 'publishing setpoints',
                         'publishing setpoints', WARN_PERIOD)

        how = (f'forced by {"use_stamped" if values["use_stamped"] else "cmd_vel_type"}'
               if self._forced else 'following its publishers')
        self.get_logger().info(
            f'ICR model chi = {icr.chi:.3f}, e = {icr.eccentricity:.3f}, scales '
            f'({icr.scale_left:g}, {icr.scale_right:g}); publishing setpoints at '
            f'{1.0 / self._period:g} Hz, {_describe_timeout(self._limiter.timeout)}, limits: '
            f'{_describe_limits(limits)} (envelope {TRACK_SPEED_ENVELOPE:g} m/s); '
            f'{self._topic}: {_TYPE_NAMES[self._sub_type]} ({how})'
            + (f'; limited command on {self._out_pub.topic_name}' if self._out_pub else '')
            + (f'; sprocket speeds (rad/s) on {self._joint_pub.topic_name}'
               if self._joint_pub else ''))
        if not math.isfinite(self._limiter.timeout):
            self._warn_no_timeout()

    # Commands -----------------------------------------------------------------------------

    def _now(self) -> float:
        """Node clock time since start, s."""
        return (self.get_clock().now().nanoseconds - self._t0) * 1e-9

    def _subscribe(self, msg_type) -> None:
        callback = self._on_twist_stamped if msg_type is TwistStamped else self._on_twist
        self._sub = self.create_subscription(msg_type, 'cmd_vel',
                                             self._cmd_count.counted(callback), 10)
        self._sub_type = msg_type

    def _on_twist(self, msg: Twist) -> None:
        self._take(msg, None)

    def _on_twist_stamped(self, msg: TwistStamped) -> None:
        stamp = msg.header.stamp
        self._take(msg.twist, stamp.sec * 1_000_000_000 + stamp.nanosec)

    def _take(self, twist, stamp_ns: int | None) -> None:
        lin, ang = twist.linear, twist.angular
        if not all(map(math.isfinite, (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))):
            self.get_logger().warning(
                f'dropped a non-finite cmd_vel (linear {lin.x}, {lin.y}, {lin.z}; angular '
                f'{ang.x}, {ang.y}, {ang.z}); the last good command holds until cmd_timeout',
                throttle_duration_sec=WARN_PERIOD)
            return
        if lin.y != 0.0 and not self._lateral_noted:
            self._lateral_noted = True
            self.get_logger().warning(
                'cmd_vel has a lateral velocity (linear.y); a tracked vehicle cannot be '
                'commanded sideways, so linear.y is ignored (this note is shown once)')
        steady = time.monotonic()
        now_ns = self.get_clock().now().nanoseconds
        t = (now_ns - self._t0) * 1e-9
        if stamp_ns is not None:
            t -= self._stamp_age(now_ns, stamp_ns)
        with self._lock:
            icr = self._limiter.icr
            self._limiter.command(lin.x, ang.z, t, steady)
        if exceeds_envelope(lin.x, ang.z, icr):
            self.get_logger().warning(
                f'cmd_vel (v_x {lin.x:g} m/s, w {ang.z:g} rad/s) asks for track speeds beyond '
                f'the vehicle envelope ({TRACK_SPEED_ENVELOPE:g} m/s): scaled into it, the '
                'curvature kept', throttle_duration_sec=WARN_PERIOD)

    def _stamp_age(self, now_ns: int, stamp_ns: int) -> float:
        """Age (s, >= 0) of a TwistStamped by its stamp, to count from; says when it is odd."""
        if stamp_ns == 0:
            if not self._zero_stamp_noted:
                self._zero_stamp_noted = True
                self.get_logger().info(
                    'cmd_vel TwistStamped with a zero stamp: taken as sent now (as '
                    'diff_drive_controller does; this note is shown once)')
            return 0.0
        age = (now_ns - stamp_ns) * 1e-9
        timeout = self._limiter.timeout
        if age > timeout:
            self.get_logger().warning(
                f'cmd_vel TwistStamped is {age:.3g} s old by its header stamp (cmd_timeout '
                f'{timeout:g} s): stale, the vehicle stops. Do the clocks agree (use_sim_time, '
                'time sync)?', throttle_duration_sec=WARN_PERIOD)
        elif age < -FUTURE_STAMP:
            self.get_logger().warning(
                f"cmd_vel TwistStamped is stamped {-age:.3g} s ahead of this node's clock: "
                'its arrival time is used. Do the clocks agree (use_sim_time, time sync)?',
                throttle_duration_sec=WARN_PERIOD)
        return max(age, 0.0)

    # The cmd_vel type ---------------------------------------------------------------------

    def _graph(self):
        return self.get_publishers_info_by_topic(self._topic)

    def _publisher_type(self, infos):
        """Return the class to subscribe with (None: keep); warn about the rest."""
        by_type: dict[str, list[str]] = {}
        for info in infos:
            node = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
            by_type.setdefault(info.topic_type, []).append(node)
        logger = self.get_logger()
        for type_name, nodes in by_type.items():
            if type_name not in _TYPES_BY_NAME:
                logger.warning(
                    f'{self._topic} has a publisher of {type_name} ({", ".join(nodes)}); this '
                    'node takes geometry_msgs/msg/Twist or geometry_msgs/msg/TwistStamped: '
                    'its messages are not received', throttle_duration_sec=GRAPH_WARN_PERIOD)
        twists = [_TYPES_BY_NAME[name] for name in by_type if name in _TYPES_BY_NAME]
        if self._forced is not None:
            for cls in twists:
                if cls is not self._forced:
                    logger.warning(
                        f'{self._topic} is {_TYPE_NAMES[self._forced]} (cmd_vel_type / '
                        f'use_stamped) but {", ".join(by_type[_TYPE_NAMES[cls]])} publish '
                        f'{_TYPE_NAMES[cls]}: their commands are not received (cmd_vel_type '
                        'auto follows the publishers)', throttle_duration_sec=GRAPH_WARN_PERIOD)
            return None
        if len(twists) == 2:
            logger.warning(
                f'{self._topic} has publishers of both geometry_msgs/msg/Twist and '
                f'TwistStamped; following {_TYPE_NAMES[self._sub_type]}: the others are not '
                'received', throttle_duration_sec=GRAPH_WARN_PERIOD)
            return None
        return twists[0] if twists else None

    def _resubscribe(self, msg_type) -> None:
        """Subscribe to cmd_vel with another type (in the executor, or before spinning)."""
        old = self._sub_type
        self.destroy_subscription(self._sub)
        try:
            self._subscribe(msg_type)
        except Exception:
            self._subscribe(old)
            raise
        self.get_logger().info(
            f'{self._topic}: its publishers use {_TYPE_NAMES[msg_type]}: subscribed as such '
            f'(was {_TYPE_NAMES[old]})')

    def _apply_wanted_type(self) -> None:
        """Guard condition callback (executor): apply the type the graph poll asked for."""
        wanted, self._wanted_type = self._wanted_type, None
        if wanted is not None and wanted is not self._sub_type:
            try:
                self._resubscribe(wanted)
            except Exception as err:  # noqa: BLE001 -- keep the old type, retry on next poll
                self.get_logger().error(
                    f'cannot subscribe to {self._topic} as {_TYPE_NAMES[wanted]}: {err!r}',
                    throttle_duration_sec=GRAPH_WARN_PERIOD)

    def _poll_graph(self) -> None:
        """Look at the publishers of cmd_vel and the subscribers of ~/cmd_vel_out (thread)."""
        try:
            if self._out_pub is not None:
                self._out_wanted = self._out_pub.get_subscription_count() > 0
            wanted = self._publisher_type(self._graph())
        except Exception as err:  # noqa: BLE001 -- a graph query must not stop the setpoints
            if self.context.ok():
                self.get_logger().warning(f'cannot look at the graph: {err!r}',
                                          throttle_duration_sec=GRAPH_WARN_PERIOD)
            return
        if wanted is not None and wanted is not self._sub_type:
            self._wanted_type = wanted
            self._switch.trigger()

    # Publishing ---------------------------------------------------------------------------

    def _publish_loop(self) -> None:
        """Publish every period of the steady clock until the node or its context stops."""
        worker = self._loop_thread
        due = next_poll = time.monotonic()
        while True:
            try:
                delay = min(due, next_poll) - time.monotonic()
                if delay > 0.0:
                    if worker.wake.wait(min(delay, GRAPH_POLL_PERIOD)):
                        worker.wake.clear()
                        if worker.stop.is_set():
                            break
                        due = self._last_publish + self._period  # a new rate: at once
                    continue
                if worker.stop.is_set() or not self.context.ok():
                    break
                now = time.monotonic()
                if now >= next_poll:
                    next_poll = now + GRAPH_POLL_PERIOD
                    self._poll_graph()
                if now >= due:
                    self._last_publish = now
                    due += self._period
                    if due < now - self._period:  # fell behind (stalled): no burst
                        due = now
                    self._publish()
                    worker.succeeded()
            except Exception as err:  # noqa: BLE001 -- keep the stream alive, say why
                if worker.failed(err):
                    break
                due = time.monotonic() + self._period
        if worker.failure is None:  # one that gave up shut the context down itself
            self._wake_executor()

    def _wake_executor(self) -> None:
        """Wake the executor so that a spin loop sees a context a signal shut down."""
        try:
            self._switch.trigger()
        except Exception:  # noqa: BLE001 -- already destroyed: nothing to wake
            pass

    def _read_clock(self, steady: float) -> tuple[int | None, bool, str]:
        """Return the clock now (ns or None), whether simulated, and its fault."""
        try:
            clock = self.get_clock()
            now_ns = clock.now().nanoseconds
            sim = clock.ros_time_is_active
        except Exception as err:  # noqa: BLE001 -- a clock we cannot read: stop, say why
            return None, True, f'the ROS clock cannot be read ({err!r})'
        if not sim:
            return now_ns, False, ''
        refused = self.clock_fault()
        fault = self._watch.update(None if refused else now_ns * 1e-9, steady)
        return now_ns, True, (refused or fault)

    def _publish(self) -> None:
        steady = time.monotonic()
        dt_steady = min(max(steady - self._last_steady, 0.0), 2.0 * self._period)
        self._last_steady = steady
        now_ns, sim, fault = self._read_clock(steady)
        t = None if now_ns is None else (now_ns - self._t0) * 1e-9
        # A stall of this process must not turn into a jump: ramp over at most two periods.
        # (With simulated time a stall stops the clock too, so there is nothing to guard.)
        max_dt = math.inf if sim else 2.0 * self._period
        joint = self._joint_pub is not None
        out = self._out_pub is not None and self._out_wanted
        with self._lock:
            limiter = self._limiter
            # Real time: the steady clock bounds a command's age as the node's clock does
            # (which a jump of the system clock fools); simulated: only slower than
            # SLOWEST_SIM_RATE, the clock faults do the rest.
            limiter.steady_timeout = limiter.timeout / (SLOWEST_SIM_RATE if sim else 1.0)
            try:
                if fault:
                    # The node's clock is not to be trusted: no command, a ramp on steady time.
                    left, right = limiter.stop(dt_steady)
                else:
                    left, right = limiter.update(t, max_dt=max_dt, steady=steady)
                problem = setpoint_problem(left, right, limiter.icr, limiter.limits,
                                           limiter.envelope)
                if problem is None and joint:
                    joint_left, joint_right = left / self._radius, right / self._radius
                    if not (math.isfinite(joint_left) and math.isfinite(joint_right)):
                        problem = f'non-finite joint commands ({joint_left!r}, {joint_right!r})'
            except Exception as err:  # noqa: BLE001 -- the guard publishes zero, says why
                problem, left, right = f'computing them failed: {err!r}', math.nan, math.nan
            if problem is not None:
                limiter.force_stop()
                bad, left, right = (left, right), 0.0, 0.0
                joint_left = joint_right = 0.0
            v_x, w = setpoint_twist(left, right, limiter.icr) if out else (0.0, 0.0)
            stale = bool(fault) or limiter.is_stale(t, steady)
        if problem is not None:
            self.get_logger().warning(
                f'output guard: setpoints {bad[0]!r}, {bad[1]!r} not published ({problem}); '
                'published 0 instead', throttle_duration_sec=WARN_PERIOD)
        self._note_fault(fault, steady)
        if stale and not self._was_stale:
            self.get_logger().debug('no cmd_vel for cmd_timeout: ramping to zero')
        self._was_stale = stale
        self._left_msg.data, self._right_msg.data = left, right
        self._left_pub.publish(self._left_msg)
        self._right_pub.publish(self._right_msg)
        if joint:
            self._joint_msg.data = [joint_left, joint_right]
            self._joint_pub.publish(self._joint_msg)
        if out:
            msg = self._out_msg
            stamp_ns = now_ns if now_ns is not None and now_ns >= 0 else 0
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
            msg.twist.linear.x, msg.twist.angular.z = v_x, w
            self._out_pub.publish(msg)

    def _note_fault(self, fault: str, steady: float) -> None:
        """Warn at a new clock fault, then every FAULT_WARN_PERIOD; say when it is over."""
        if fault:
            kind = ''.join(c for c in fault if not c.isdigit())  # the numbers change
            if kind != self._fault_kind or steady - self._fault_warned >= FAULT_WARN_PERIOD:
                self._fault_kind, self._fault_warned = kind, steady
                self.get_logger().warning(
                    f'{fault}: the command is dropped and the setpoints ramp to zero; a new '
                    'cmd_vel is followed once the clock is healthy')
        elif self._fault_kind:
            self._fault_kind = ''
            self.get_logger().info('the ROS clock is healthy again: waiting for a new cmd_vel')

    # Parameters and shutdown ----------------------------------------------------------------

    def _warn_no_timeout(self) -> None:
        self.get_logger().warning(
            'cmd_timeout 0: no timeout; the last command holds until another comes, also '
            'when its publisher dies')

    def _apply(self, values: Mapping[str, Any]) -> None:
        icr, limits = model_from_values(values)
        timeout = _timeout(values['cmd_timeout'])
        with self._lock:
            had_timeout = math.isfinite(self._limiter.timeout)
            self._limiter.icr = icr
            self._limiter.limits = limits
            self._limiter.timeout = timeout
            self._watch.stall_timeout = values['clock_stall_timeout']
            self._radius = values['sprocket_radius']
            period = 1.0 / values['rate']
            rescheduled, self._period = period != self._period, period
        if rescheduled:
            self._loop_thread.wake.set()
        self.get_logger().info(
            f'parameters changed: chi = {icr.chi:.3f}, e = {icr.eccentricity:.3f}, '
            f'{values["rate"]:g} Hz, {_describe_timeout(timeout)}, limits: '
            f'{_describe_limits(limits)}')
        if had_timeout and not math.isfinite(timeout):
            self._warn_no_timeout()


def main(args=None):
    """Run the node: exit 0 after a signal, 2 when it cannot start, 1 when it gave up."""
    raise SystemExit(run(CmdVelTranslator, NODE_NAME, args, TRANSLATOR_PARAMS, __doc__))
