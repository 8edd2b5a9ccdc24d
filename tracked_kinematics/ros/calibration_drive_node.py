"""
calibration_drive: drive a calibration protocol on cmd_vel, safely, then fit the terrain.

A thin adapter around :mod:`tracked_kinematics.core.plan.calibration_protocol` and the safety
:class:`~tracked_kinematics.core.plan.supervisor.Supervisor`; the finisher that writes the
files comes from the console script (the ``ros`` ring imports no ``offline`` code).
See docs/nodes/calibration_drive.md.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Mapping
import json
import math
import threading
import time
from typing import Any

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType
from rcl_interfaces.srv import SetParametersAtomically
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, Joy
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger
from tracked_kinematics.core.clock_watch import ClockWatch
from tracked_kinematics.core.imu_frame import heading_rate, mount_rotation
from tracked_kinematics.core.integration import stamp_ns, yaw_from_quaternion
from tracked_kinematics.core.plan.calibration_protocol import (
    FenceOdometry, protocol, total_duration)
from tracked_kinematics.core.plan.supervisor import (
    Inputs, pose_jump, Supervisor, SupervisorConfig)
from tracked_kinematics.core.recording import from_stamped_rows, Recording
from tracked_kinematics.params import icr_from_values
from tracked_kinematics.params.node_tables import CALIBRATION_POSE_TYPES, NODE_PARAMS
from tracked_kinematics.ros.calibration_health import watch_calibration_inputs
from tracked_kinematics.ros.encoder_input import check_encoder_values, EncoderInput, WARN_PERIOD
from tracked_kinematics.ros.input_topic import (CHECK_PERIOD, InputTopic, steady_timer,
                                                type_name)
from tracked_kinematics.ros.parameters import TableNode

NODE_NAME = 'calibration_drive'
POSE_TYPES = dict(zip(CALIBRATION_POSE_TYPES,
                      (Odometry, PoseStamped, PoseWithCovarianceStamped), strict=True))
#: Highest rate of the status topic, Hz (and on every state change).
STATUS_RATE = 2.0
#: Largest track speed of a vehicle that stands still (the gyro then measures its bias), m/s.
STILL_SPEED = 0.005
#: With the IMU the geofence is kept in dead reckoning (gyro heading, encoder distance), a few
#: per cent off at 3 m: more margin than the pose reference's 0.85 / 0.93 of the radius.
IMU_FENCE = {'plan_fraction': 0.8, 'guard_fraction': 0.87}
#: Statuses of a fit ended by a signal (identify_icr's for SIGHUP, SIGINT, SIGTERM).
INTERRUPTED = (129, 130, 143)
#: How long the node waits for the nodes of push_to to answer, s.
PUSH_TIMEOUT = 5.0
#: Period of the check that every input topic has one publisher, s (steady clock).
PUBLISHER_CHECK_PERIOD = 0.25
#: How long a fault found in one sample (a gyro spike, a pose jump) stays in force, s.
FAULT_HOLD = 2.0
#: The loop's lateness is the worst of this last stretch of ticks, s (steady clock).
LATENESS_WINDOW = 2.0
#: The pose's age counts into the lateness up to this, s (beyond: another clock).
MAX_POSE_AGE = 0.5
#: How long the deadman link's clock offset is remembered, s (steady clock).
OFFSET_WINDOW = 30.0
#: Steady time the ROS clock may stand still while the sensors deliver, s.
CLOCK_STALL = 0.5
#: The topic of the simulated time (use_sim_time): one publisher, as every input.
CLOCK_TOPIC = '/clock'
#: Gyro plausibility: the largest rate is this many times max_yaw_rate (at least 2 rad/s).
GYRO_RANGE_FACTOR = 5.0


PARAMS = NODE_PARAMS[NODE_NAME]


def validate(values: Mapping[str, Any]) -> None:
    """Check the parameters as a whole; ValueError for a bad model, encoders or no deadman."""
    icr_from_values(values)
    check_encoder_values(values)
    if not values['deadman_topic'] and not values['joy_topic']:
        raise ValueError('give deadman_topic or joy_topic: the drive needs a deadman')


def _seconds(stamp) -> int:
    return stamp_ns(stamp.sec, stamp.nanosec)


class LinkAge:
    """
    Age of a message at its arrival, from its DDS source timestamp, clock skew removed.

    The skew is the smallest arrival-less-stamp of the last :data:`OFFSET_WINDOW` s, so a message
    delivered late is old however fresh its arrival (docs/nodes/calibration_drive.md).
    """

    def __init__(self):
        self._offsets = deque()   # (steady s, offset s), offsets increasing: a sliding min

    def age(self, source_ns: int, steady: float) -> float:
        """Return the age of a message published at ``source_ns`` (0: unknown), s."""
        if not source_ns:
            return 0.0
        offset = time.time_ns() * 1e-9 - source_ns * 1e-9
        offsets = self._offsets
        while offsets and offsets[-1][1] >= offset:
            offsets.pop()
        offsets.append((steady, offset))
        while len(offsets) > 1 and offsets[0][0] < steady - OFFSET_WINDOW:
            offsets.popleft()
        return max(0.0, offset - offsets[0][1])


class CalibrationDriveNode(TableNode):
    """
    The calibration drive: a :class:`~.parameters.TableNode` of :data:`PARAMS`.

    Parameters
    ----------
    finisher : callable, optional
        ``finisher(values)``, called at start, checks the output paths and returns
        ``finish(recording, topics, log) -> (status, fitted values or None)``, run when the
        protocol is done. None: nothing is written (tests).
    on_exit : callable, optional
        ``on_exit(status)``, called when the node is done (the console script exits there).
    **kwargs
        Passed to :class:`rclpy.node.Node`.

    """

    def __init__(self, finisher: Callable | None = None,
                 on_exit: Callable[[int], None] | None = None, **kwargs):
        # Kept for _start, which the base class calls once the parameters are checked.
        self._finisher, self._on_exit = finisher, on_exit
        super().__init__(NODE_NAME, PARAMS, validate, **kwargs)

    def _abandon(self) -> None:
        # Refused parameters or outputs: the half-built node sends no zero command.
        self._zero_sent = True

    def _start(self, values: Mapping[str, Any]) -> None:
        self.encoder = None
        self._finish = self._finisher(values) if self._finisher is not None else None
        self.exit_status: int | None = None
        icr = icr_from_values(values)
        self.steps = protocol(values['duration'], values['max_speed'], values['max_yaw_rate'],
                              values['geofence_radius'])
        self.supervisor = Supervisor(self.steps, SupervisorConfig(
            geofence_radius=values['geofence_radius'], max_speed=values['max_speed'],
            max_yaw_rate=values['max_yaw_rate'], deadman_timeout=values['deadman_timeout'],
            encoder_timeout=values['encoder_timeout'],
            reference_timeout=values['reference_timeout'], auto_start=values['auto_start'],
            track_width=values['track_width'], reference=values['reference'],
            **(IMU_FENCE if values['reference'] == 'imu' else {})))
        self._reference = values['reference']
        # The gyro read as odometry_node reads it: the heading rate in base_frame.
        self._mount = tuple(map(tuple, mount_rotation(
            *(values[f'imu_mount.{axis}'] for axis in ('roll', 'pitch', 'yaw'))).tolist()))
        self._imu_frame = None         # frame_id of the first Imu, for the bag
        gyro_range = values['max_gyro_rate'] or max(
            2.0, GYRO_RANGE_FACTOR * values['max_yaw_rate'])
        self._fence = FenceOdometry(icr.scale_left, icr.scale_right, max_rate=gyro_range,
                                    max_jump=0.5 * gyro_range)
        self._steady_clock = Clock(clock_type=ClockType.STEADY_TIME)
        self._period = 1.0 / values['rate']
        self._reset_state(values)
        self._connect(values)
        deadman = (f'{self._deadman_topics[0]}' if values['deadman_topic'] else '') + (
            f' {self._deadman_topics[-1]} button {values["deadman_button"]}'
            if values['joy_topic'] else '')
        source = self._inputs[0].topic_name
        mount = tuple(values[f'imu_mount.{axis}'] for axis in ('roll', 'pitch', 'yaw'))
        if self._reference == 'imu':
            source += ' (imu_mount ' + ' '.join(f'{v:g}' for v in mount) + ' rad)'
        self.get_logger().info(
            f'calibration drive: {len(self.steps)} steps, {total_duration(self.steps):.0f} s '
            f'of motion, geofence {values["geofence_radius"]:g} m, caps '
            f'{values["max_speed"]:g} m/s and {values["max_yaw_rate"]:g} rad/s; reference '
            f'{self._reference} on {source}; {self.encoder.describe()}; deadman '
            f'{deadman.strip()}; '
            + ('starts when the deadman is held' if values['auto_start']
               else 'call ~/start to begin'))

    def _reset_state(self, values: Mapping[str, Any]) -> None:
        """Set the drive's bookkeeping to its start: no tick, input, fault or row yet."""
        self._ticks = deque()          # (steady, lateness) of the recent ticks
        self._last_tick = None         # (steady, ros) of the last timer tick
        self._clock_watch = ClockWatch(CLOCK_STALL)
        self._clock_latest = self._clock_advanced = None   # ROS time, and steady when seen
        self._clock_refusals = 0       # clock_refusals() when last looked at
        self._faults = {}              # name -> (text, steady time it ends or None)
        self._links = {}
        self._encoder_steady = self._reference_steady = None
        self._last_pose = None         # (stamp s, pose) of the last accepted pose
        self._pose_stamp = None        # stamp of the geofence pose, ROS s
        self._radius = values['sprocket_radius']
        # Every configured deadman must be held (with both a topic and a button: both).
        self._deadmen = {source: (False, None, None) for source, topic in
                         (('topic', values['deadman_topic']), ('joy', values['joy_topic']))
                         if topic}
        self._encoder_t = self._reference_t = None
        self._still = False
        self._pose = None
        self._travel = [0.0, 0.0]
        self._travel_t = None
        self._rows = {'encoder': [], 'pose': [], 'imu': [], 'cmd': []}
        self._phase = 'drive'         # drive -> fitting -> pushing -> done
        self._result = None
        self._pending_push = {}
        self._push_deadline = None
        self._last_status_ns = None
        self._last_state = None
        self._zero_sent = False
        self._lock = threading.Lock()

    def _connect(self, values: Mapping[str, Any]) -> None:
        """Create the publishers, the inputs, the deadman subscriptions, services and timers."""
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self._cmd_pub = self.create_publisher(Twist, 'cmd_vel', reliable)
        self._status_pub = self.create_publisher(String, '~/status', reliable)
        self.encoder = EncoderInput(self, values, self._on_step)
        self._inputs = []
        if self._reference == 'pose':
            self._inputs.append(InputTopic(self, POSE_TYPES[values['pose_type']],
                                           values['pose_topic'], self._on_pose))
        else:
            self._inputs.append(InputTopic(self, Imu, values['imu_topic'], self._on_imu))
        # The deadman's own subscriptions take the message info (its publication time);
        # best effort matches reliable and best-effort publishers alike.
        deadman_qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        self._deadman_topics, deadman_types = [], []
        if values['deadman_topic']:
            sub = self.create_subscription(Bool, values['deadman_topic'], self._on_deadman,
                                           deadman_qos)
            self._deadman_topics.append(sub.topic_name)
            deadman_types.append(type_name(Bool))
        if values['joy_topic']:
            sub = self.create_subscription(Joy, values['joy_topic'], self._on_joy, deadman_qos)
            self._deadman_topics.append(sub.topic_name)
            deadman_types.append(type_name(Joy))
        self._check_timer = steady_timer(self, CHECK_PERIOD, self._check_inputs)
        self.health, self._deadman_counts = watch_calibration_inputs(
            self, self.encoder.inputs, self._inputs[0], zip(self._deadman_topics, deadman_types))
        self._publisher_timer = steady_timer(self, PUBLISHER_CHECK_PERIOD,
                                             self._check_publishers)
        self.create_service(Trigger, '~/start', self._service(self.supervisor.start))
        self.create_service(Trigger, '~/pause', self._service(self.supervisor.pause))
        self.create_service(Trigger, '~/stop', self._service(self.supervisor.stop))
        # On the steady clock: a /clock that stops must not stop the zero commands.
        self._timer = steady_timer(self, self._period, self._on_timer)

    def _apply(self, values: Mapping[str, Any]) -> None:
        """Take runtime changes of the terrain and encoder values into use (the rest is fixed)."""
        icr = icr_from_values(values)
        self._fence.scales = (icr.scale_left, icr.scale_right)
        self._radius = values['sprocket_radius']
        if self.encoder is not None:
            self.encoder.configure(values)

    # --- inputs -------------------------------------------------------------------------

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _steady(self) -> float:
        return self._steady_clock.now().nanoseconds * 1e-9

    def _check_inputs(self) -> None:
        for topic in self._inputs:
            topic.check()

    def _fault(self, name: str, text: str, hold: float | None = FAULT_HOLD) -> None:
        """Set a fault (it stops the drive) for ``hold`` s, or until cleared (None)."""
        if text:
            if name not in self._faults:
                self.get_logger().error(text)
            self._faults[name] = (text, None if hold is None else self._steady() + hold)
        else:
            self._faults.pop(name, None)

    def _fault_text(self) -> str:
        now = self._steady()
        for name, (text, until) in list(self._faults.items()):
            if until is not None and now > until:
                del self._faults[name]
        return '; '.join(text for text, _ in self._faults.values())

    def _check_publishers(self) -> None:
        """Rule 6: one publisher per input topic (/clock too, in sim time); more is a fault."""
        topics = (*self.encoder.topics, self._inputs[0].topic_name, *self._deadman_topics)
        if self.get_parameter('use_sim_time').value:
            topics += (CLOCK_TOPIC,)
        crowded = []
        for topic in topics:
            try:
                count = self.count_publishers(topic)
            except Exception:  # noqa: BLE001 -- the graph is gone during shutdown
                return
            if count > 1:
                crowded.append(f'{count} publishers on {topic}')
        self._fault('publishers', '; '.join(crowded) + ': the drive takes one source per '
                    'input' if crowded else '', hold=None)

    def _on_step(self, stamp_s: float, d_left: float, d_right: float, dt: float) -> None:
        self._encoder_t = self._now()
        self._encoder_steady = self._steady()
        self._travel[0] += d_left
        self._travel[1] += d_right
        self._travel_t = stamp_s
        self._rows['encoder'].append((_seconds(self.encoder.stamp), *self._travel))
        self._still = dt > 0.0 and max(abs(d_left), abs(d_right)) <= STILL_SPEED * dt
        if self._reference == 'imu':
            self._fence.add_travel(d_left, d_right)
            self._pose = self._fence.pose
            self._pose_stamp = stamp_s

    def _on_pose(self, msg) -> None:
        pose = msg.pose if isinstance(msg, PoseStamped) else msg.pose.pose
        q = pose.orientation
        values = (pose.position.x, pose.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))
        t = _seconds(msg.header.stamp)
        if t == 0 or not all(map(math.isfinite, values)):
            self.get_logger().warning('pose without a stamp or not finite: skipped',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        if self._last_pose is not None:
            cfg = self.supervisor.config
            self._fault('pose', pose_jump(self._last_pose[1], values,
                                          t * 1e-9 - self._last_pose[0], cfg.max_speed,
                                          cfg.max_yaw_rate))
        self._last_pose = (t * 1e-9, values)
        self._reference_t = self._now()
        self._reference_steady = self._steady()
        self._pose = values
        self._pose_stamp = t * 1e-9
        self._rows['pose'].append((t, *values))

    def _on_imu(self, msg) -> None:
        t = _seconds(msg.header.stamp)
        w, q = msg.angular_velocity, msg.orientation
        omega, quaternion = (w.x, w.y, w.z), (q.x, q.y, q.z, q.w)
        cov0 = float(msg.orientation_covariance[0])
        rate, _ = heading_rate(omega, self._mount, quaternion, cov0 != -1.0)
        if t == 0:
            self.get_logger().warning('imu sample without a stamp: skipped',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        problem = self._fence.add_gyro(t * 1e-9, rate, self._still)
        if problem:
            # Refused before the dead reckoning takes it; the drive stops.
            self._fault('gyro', f'implausible gyro on {self._inputs[0].topic_name}: {problem}')
            self._tick_now()
            return
        if self._imu_frame is None:
            self._imu_frame = msg.header.frame_id
        self._reference_t = self._now()
        self._reference_steady = self._steady()
        self._pose = self._fence.pose
        # The rate used, and the message as it came (the bag is the raw record).
        self._rows['imu'].append((t, float(rate), *quaternion, cov0, *omega))

    # Two parameters without defaults: rclpy then passes the message info (a callback that
    # can be called with the message alone gets the message alone).
    def _on_deadman(self, msg, info) -> None:
        self._deadman_counts[0].tick()
        self._set_deadman('topic', bool(msg.data), info)

    def _on_joy(self, msg, info) -> None:
        self._deadman_counts[-1].tick()
        index = self.params['deadman_button']
        self._set_deadman('joy', index < len(msg.buttons) and msg.buttons[index] == 1, info)

    def _set_deadman(self, source: str, held: bool, info=None) -> None:
        """Take a deadman message; its time is its publication's, on the steady clock."""
        was = self._deadman_state()[0]
        steady = self._steady()
        source_ns = (info or {}).get('source_timestamp', 0)
        age = self._links.setdefault(source, LinkAge()).age(source_ns, steady)
        self._deadmen[source] = (held, self._now(), steady - age)
        if was != held:
            self._tick_now()   # acted on now, not at the next tick

    def _deadman_state(self):
        """Return (held, when, when_steady): every deadman held, its oldest message's times."""
        states = list(self._deadmen.values())
        if any(when is None for _, when, _ in states):
            return False, None, None
        return (all(held for held, _, _ in states), min(when for _, when, _ in states),
                min(steady for _, _, steady in states))

    def _lateness(self, steady: float) -> float:
        """How late the loop runs: the worst recent tick, plus the geofence pose's age, s."""
        while self._ticks and self._ticks[0][0] < steady - LATENESS_WINDOW:
            self._ticks.popleft()
        late = max((lateness for _, lateness in self._ticks), default=0.0)
        if self._pose_stamp is not None:
            age = self._now() - self._pose_stamp
            late += min(max(age, 0.0), MAX_POSE_AGE) if math.isfinite(age) else MAX_POSE_AGE
        return late

    def _inputs_now(self) -> Inputs:
        held, when, when_steady = self._deadman_state()
        not_ready = '' if self._reference != 'imu' or self._fence.settled else (
            f'measuring the gyro bias: the vehicle must stand still for '
            f'{self._fence.settle:g} s first')
        if not self._cmd_pub.get_subscription_count():
            not_ready = (f'nobody subscribes {self._cmd_pub.topic_name} (start '
                         'cmd_vel_translator)')
        steady = self._steady()
        return Inputs(self._now(), held, when, self._encoder_t, self._reference_t, self._pose,
                      not_ready, steady=steady, deadman_steady=when_steady,
                      encoder_steady=self._encoder_steady,
                      reference_steady=self._reference_steady, travel=tuple(self._travel),
                      travel_t=self._travel_t,
                      lateness=self._lateness(steady), fault=self._fault_text())

    def _service(self, call):
        def handle(request, response):
            with self._lock:
                response.success, response.message = call(self._inputs_now())
                self.get_logger().info(f'{call.__name__}: {response.message}')
                self._tick()
            return response
        return handle

    # --- the drive ----------------------------------------------------------------------

    def _watch_clock(self, steady: float) -> None:
        """Rule 6: a ROS clock that is invalid, goes back, or stalls while data flow stops."""
        ros = self.ros_time()
        if ros is not None and (self._clock_latest is None or ros != self._clock_latest):
            self._clock_latest, self._clock_advanced = ros, steady
        refusals, why = self.clock_refusals()
        if refusals != self._clock_refusals:
            # One refused message is enough: a healthy clock never sends one, and the next
            # valid message ends clock_fault() before the next tick could see it.
            self._clock_refusals = refusals
            self._fault('clock refused', why)
        fault = self.clock_fault() or self._clock_watch.update(ros, steady)
        if 'went back' in fault:
            self._fault('clock went back', fault)    # reported once: held a while
            fault = ''
        elif 'not advanced' in fault:
            # Only while the sensors deliver after the clock stopped: a paused or loaded
            # simulation stops both (its /clock and its sensors come together).
            flowing = [t for t in (self._encoder_steady, self._reference_steady)
                       if t is not None and self._clock_advanced is not None
                       and t - self._clock_advanced > 0.5 * CLOCK_STALL]
            if not flowing:
                fault = ''
        self._fault('clock', fault, hold=None)

    def _on_timer(self) -> None:
        steady, ros = self._steady(), self._now()
        self._watch_clock(steady)
        if self._last_tick is not None:
            # The world's time between ticks is the longer of the two clocks' (a simulation
            # faster than real time moves more per tick).
            interval = max(steady - self._last_tick[0], ros - self._last_tick[1])
            self._ticks.append((steady, max(0.0, interval - self._period)))
        self._last_tick = (steady, ros)
        with self._lock:
            self._tick()

    def _tick_now(self) -> None:
        """Apply the rules now (a deadman change, a fault), outside the timer's rhythm."""
        with self._lock:
            self._tick()

    def _tick(self) -> None:
        out = self.supervisor.update(self._inputs_now())
        self._publish(out.v, out.w)
        if out.state != self._last_state:
            self._last_state = out.state
            text = out.state + (f': {out.reason}' if out.reason else '')
            if out.state in ('paused', 'stopped'):
                self.get_logger().warning(text)
            else:
                self.get_logger().info(text)
            self._publish_status(out)
        else:
            now = self.get_clock().now().nanoseconds
            if self._last_status_ns is None or now - self._last_status_ns >= 1e9 / STATUS_RATE \
                    or now < self._last_status_ns:
                self._publish_status(out)
        if out.state == 'finished':
            self._after_drive()

    def _publish(self, v: float, w: float) -> None:
        msg = Twist()
        msg.linear.x, msg.angular.z = float(v), float(w)
        self._cmd_pub.publish(msg)
        self._rows['cmd'].append((self.get_clock().now().nanoseconds, msg.linear.x,
                                  msg.angular.z))

    def status(self) -> dict:
        """Return the status as published on ``~/status``."""
        out = self.supervisor.last
        step = self.steps[out.step] if out.step < len(self.steps) else None
        held = self._deadman_state()[0]
        return {
            'state': out.state, 'reason': out.reason, 'phase': self._phase,
            'step': out.step, 'steps': out.steps, 'step_kind': step.kind if step else None,
            'step_elapsed': round(out.step_elapsed, 3),
            'step_duration': step.duration if step else None,
            'command': [out.v, out.w], 'deadman': held,
            'distance': None if out.distance is None else round(out.distance, 3),
            'geofence_radius': self.supervisor.config.geofence_radius,
            'recorded': {k: len(v) for k, v in self._rows.items()},
            'exit_status': self.exit_status,
        }

    def _publish_status(self, out=None) -> None:
        self._last_status_ns = self.get_clock().now().nanoseconds
        self._status_pub.publish(String(data=json.dumps(self.status())))

    # --- the end ------------------------------------------------------------------------

    def recording(self) -> Recording:
        """Return what was recorded so far, as arrays."""
        return from_stamped_rows(**self._rows)

    def topics(self) -> dict:
        """Return the resolved topic names of the recording (for the bag)."""
        return {'joint_names': [self.params['left_joints'][0], self.params['right_joints'][0]],
                'joint_states': f'{self.get_namespace().rstrip("/")}/joint_states',
                'reference': self._inputs[0].topic_name,
                'cmd_vel': self._cmd_pub.topic_name, 'reference_kind': self._reference,
                'imu_frame_id': self._imu_frame or '',
                'steps': [{'kind': s.kind, 'v': s.v, 'w': s.w, 'duration': s.duration}
                          for s in self.steps],
                'events': [{'t': t, 'state': state, 'reason': reason}
                           for t, state, reason in self.supervisor.events]}

    def _after_drive(self) -> None:
        if self._phase == 'drive':
            self._phase = 'fitting'
            self._publish(0.0, 0.0)
            self.stop_now()
            self._publish_status()
            if self._finish is None:
                self._result = (0, None)
            else:
                self._result = self._run_finish(self.recording(), self.topics())
        if self._phase == 'fitting':
            status, fitted = self._result
            if status == 0 and fitted and self.params['push_to']:
                self._phase = 'pushing'
                self._push(fitted)
            else:
                self._done(status)
        elif self._phase == 'pushing':
            late = self.get_clock().now().nanoseconds > self._push_deadline
            if not self._pending_push or late:
                for target in self._pending_push:
                    self.get_logger().warning(f'{target} did not answer the push in time')
                self._done(0)

    def _run_finish(self, recording, topics):
        """Write the results in this callback; a cancelled fit writes nothing."""
        self.get_logger().info(
            f'protocol done: fitting {len(recording.enc_t)} encoder steps and '
            f'{sum(len(t) for t in (recording.gt_t, recording.gyro_t) if t is not None)} '
            'reference samples')
        try:
            status, fitted = self._finish(recording, topics, self.get_logger())
        except (ValueError, OSError) as err:   # the package's errors, a full disk
            self.get_logger().error(f'writing the results failed: {err}')
            return 2, None
        if status in INTERRUPTED:
            # A signal during the fit: a node ends cleanly on a signal (exit 0).
            self.get_logger().warning('interrupted while fitting: nothing written')
            return 0, None
        return status, fitted

    def cancel(self) -> None:
        """End a fit under way (the console script calls this on SIGINT or SIGTERM)."""
        cancel = getattr(self._finish, 'cancel', None)
        if cancel is not None:
            cancel()

    def _push(self, fitted: Mapping[str, float]) -> None:
        request = SetParametersAtomically.Request()
        for name in ('icr.y_left', 'icr.y_right', 'icr.x', 'scale.left', 'scale.right'):
            param = ParameterMsg(name=name)
            param.value.type = ParameterType.PARAMETER_DOUBLE
            param.value.double_value = float(fitted[name])
            request.parameters.append(param)
        self._push_deadline = self.get_clock().now().nanoseconds + int(PUSH_TIMEOUT * 1e9)
        for target in self.params['push_to']:
            client = self.create_client(
                SetParametersAtomically, f'/{target.strip("/")}/set_parameters_atomically')
            if not client.wait_for_service(timeout_sec=1.0):
                self.get_logger().warning(f'cannot push the fit: {client.srv_name} is not '
                                          'available')
                continue
            self._pending_push[target] = client
            future = client.call_async(request)
            future.add_done_callback(lambda f, target=target: self._pushed(target, f))

    def _pushed(self, target, future) -> None:
        self._pending_push.pop(target, None)
        result = future.result()
        if result is None or not result.result.successful:
            reason = 'no answer' if result is None else result.result.reason
            self.get_logger().warning(f'{target} refused the fitted values: {reason}')
        else:
            self.get_logger().info(f'pushed the fitted icr.* and scale.* to {target}')

    def _done(self, status: int) -> None:
        if self._phase == 'done':
            return
        self._phase = 'done'
        self.exit_status = status
        self._publish_status()
        self.get_logger().info(f'calibration drive done (exit status {status})')
        if self._on_exit is not None:
            self._on_exit(status)

    def stop_now(self) -> None:
        """Publish a zero command and wait (briefly) until the subscribers have it."""
        if self._zero_sent or not self.context.ok():
            return
        self._zero_sent = True
        try:
            self._cmd_pub.publish(Twist())
            self._cmd_pub.wait_for_all_acked(Duration(seconds=0.5))
        except Exception:  # noqa: BLE001 -- a context shut down under us: nothing to send
            pass

    def destroy_node(self):
        """Publish a zero command, then destroy the node."""
        self.stop_now()
        return super().destroy_node()
