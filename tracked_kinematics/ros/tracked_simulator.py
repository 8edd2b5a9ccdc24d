"""
tracked_simulator: the package's simulator as a live robot, in simulated time.

The chain of ``simulate_bag`` (:class:`~tracked_kinematics.core.sim.live.LiveSimulator`)
stepped in a thread paced on the steady clock as setpoints come in, publishing /clock and a
real robot's sensors. See docs/nodes/tracked_simulator.md and docs/simulator.md.
"""

from __future__ import annotations

from collections.abc import Mapping
import math
import threading
import time
from typing import Any

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64, String
from tracked_kinematics.core.command import TRACK_SPEED_ENVELOPE
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.integration import quaternion_from_yaw, seconds_to_stamp
from tracked_kinematics.core.sim.live import LiveSimulator, SetpointHold
from tracked_kinematics.core.sim.live_sensors import (EncoderReadout, PoseModel, PoseStream,
                                                      Schedule)
from tracked_kinematics.core.sim.sensors import GyroModel, GyroStream
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.core.sim.terrains import Terrain, TERRAINS
from tracked_kinematics.params.node_tables import SIMULATOR_PARAMS
from tracked_kinematics.params.vehicles import load_vehicle, VehicleFile
from tracked_kinematics.ros.health import Health
from tracked_kinematics.ros.loop_thread import LoopNode
from tracked_kinematics.ros.main import run

NODE_NAME = 'tracked_simulator'

MAX_LAG = 0.25  # s of wall time behind schedule after which the backlog is dropped
WARN_PERIOD = 1.0  # s, throttle of the warnings on recurring bad input
LAG_WARN_PERIOD = 10.0  # s, throttle of the "cannot keep up" warning


class Terrains:
    """The terrains of one vehicle (a VehicleFile) and their tables, built on first use."""

    def __init__(self, spec: VehicleFile):
        self.spec = spec
        vehicle = spec.robot.vehicle
        own = Terrain(spec.terrain, vehicle.mu_x, vehicle.mu_y,
                      f'the friction of the vehicle file {spec.path}')
        self.known = {**TERRAINS, own.name: own}

    def check(self, name: str) -> None:
        """Raise ValueError naming the known terrains when ``name`` is not one."""
        if name not in self.known:
            raise ValueError(f'terrain {name!r} is not known (one of: '
                             f'{", ".join(sorted(self.known))})')

    def table(self, name: str) -> TwistTable:
        """Return the dynamics of the vehicle on terrain ``name`` (built once: TwistTable.of)."""
        self.check(name)
        return TwistTable.of(self.known[name].apply(self.spec.robot.vehicle))


def _stamp(msg_stamp, t: float) -> None:
    msg_stamp.sec, msg_stamp.nanosec = seconds_to_stamp(t)


class TrackedSimulator(LoopNode):
    """
    Step the simulated vehicle at a fixed rate in simulated time; publish its sensors.

    A :class:`~tracked_kinematics.ros.loop_thread.LoopNode` of :data:`SIMULATOR_PARAMS`;
    ``ParameterError`` when the parameters given at start are invalid (also an unknown vehicle
    or terrain).
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, SIMULATOR_PARAMS, self._validate, **kwargs)

    # Start ----------------------------------------------------------------------------------

    def _validate(self, values: Mapping[str, Any]) -> None:
        """Check the vehicle (loaded once: it is read-only) and the terrain name."""
        if getattr(self, '_terrains', None) is None:
            try:
                spec = load_vehicle(values['vehicle'])
            except (FileNotFoundError, InvalidParameters) as err:
                raise ValueError(f'vehicle: {err}') from None
            self._terrains = Terrains(spec)
        self._terrains.check(values['terrain'])

    def _start(self, values: Mapping[str, Any]) -> None:
        # The vehicle and its terrains were loaded by the check of the parameters.
        spec = self._terrains.spec
        robot = spec.robot
        self._lock = threading.Lock()
        self._terrain = self._wanted_terrain = values['terrain']
        self._builders: list[threading.Thread] = []
        self._dt = 1.0 / values['rate']
        self._sim = LiveSimulator(robot, self._dt, self._terrains.table(self._terrain))
        timeout = values['setpoint_timeout'] or math.inf
        self._holds = (SetpointHold(timeout, TRACK_SPEED_ENVELOPE),
                       SetpointHold(timeout, TRACK_SPEED_ENVELOPE))

        # Random sources: one stream per sensor, so that switching one on or off leaves the
        # others' noise as it was.
        enc_rng, gyro_rng, lidar_rng = (np.random.default_rng(s) for s in
                                        np.random.SeedSequence(values['seed']).spawn(3))
        enc = robot.encoders

        def chosen(name, own):
            return own if values[name] == -1.0 else values[name]

        self._encoders = EncoderReadout(
            enc.sprocket_radius, chosen('encoder_ticks_per_revolution', enc.ticks_per_revolution),
            chosen('encoder_position_noise', enc.position_noise),
            chosen('encoder_velocity_noise', enc.velocity_noise), values['encoder_wrap'],
            enc_rng)
        self._gyro = GyroStream(GyroModel(
            rate=values['gyro_rate'], bias=values['gyro_bias'], noise_std=values['gyro_noise'],
            bias_walk=values['gyro_bias_walk'], latency=values['gyro_latency']), gyro_rng)
        self._lidar = None
        if values['lidar_pose']:
            self._lidar = PoseStream(PoseModel(
                rate=values['lidar_pose_rate'], delay=values['lidar_pose_delay'],
                position_noise=values['lidar_pose_position_noise'],
                yaw_noise=values['lidar_pose_yaw_noise'],
                jump_rate=values['lidar_pose_jump_rate'],
                jump_size=values['lidar_pose_jump_size'],
                jump_yaw=values['lidar_pose_jump_yaw']), lidar_rng)
        self._lidar_on_receipt = values['lidar_pose_stamp'] == 'receipt'
        self._encoder_due = Schedule(values['encoder_rate'], self._dt)
        self._truth_due = Schedule(values['ground_truth_rate'], self._dt)

        self._make_messages(values)
        self._clock_pub = self.create_publisher(Clock, '/clock', 10)
        self._joint_pub = self.create_publisher(JointState, 'joint_states', 10)
        self._imu_pub = self.create_publisher(Imu, 'imu/data', 10)
        self._odom_pub = self.create_publisher(Odometry, 'ground_truth/odom', 10)
        self._pose_pub = (self.create_publisher(PoseStamped, 'lidar/pose', 10)
                          if self._lidar is not None else None)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._terrain_pub = self.create_publisher(String, '~/terrain', latched)
        self._terrain_pub.publish(String(data=self._terrain))
        # Health on /diagnostics; no setpoint is normal (the robot stands still).
        self.health = Health(self)
        for side, topic in enumerate(('left_track/setpoint', 'right_track/setpoint')):
            count = self.health.watch_topic(topic, ['std_msgs/msg/Float64'], needed=False)
            self.create_subscription(
                Float64, topic, count.counted(lambda msg, side=side: self._on_setpoint(side, msg)),
                10)

        self._rtf = values['real_time_factor']
        self._clock_period = 1.0 / values['clock_rate']
        self._start_loop(self._loop, 'simulation', 'simulation step', 'the simulation',
                         WARN_PERIOD)

        vehicle = robot.vehicle
        self.get_logger().info(
            f'simulating {spec.name} ({spec.path}) on {self._terrain} (mu_x '
            f'{self._terrains.known[self._terrain].mu_x:g}, mu_y '
            f'{self._terrains.known[self._terrain].mu_y:g}): track width '
            f'{vehicle.track_width:g} m, sprocket radius {enc.sprocket_radius:g} m, up to '
            f'{vehicle.max_track_speed:g} m/s; {values["rate"]:g} Hz steps at '
            f'{self._rtf:g}x real time, seed {values["seed"]}'
            + ('; lidar/pose on' if self._lidar is not None else ''))
        if self.get_parameter('use_sim_time').value:
            self.get_logger().warning(
                'use_sim_time is true, but this node makes the simulated time: it paces its '
                'steps on the wall clock and publishes /clock itself (give use_sim_time to '
                'the other nodes only)')

    def _make_messages(self, values: Mapping[str, Any]) -> None:
        """Build the messages the simulation fills and publishes at every step (reused)."""
        self._clock_msg = Clock()
        self._joint_msg = JointState(name=[values['left_joint'], values['right_joint']])
        self._odom_msg = Odometry()
        self._odom_msg.header.frame_id = values['odom_frame']
        self._odom_msg.child_frame_id = values['base_frame']
        self._imu_msg = Imu()
        self._imu_msg.header.frame_id = values['imu_frame']
        self._imu_msg.orientation_covariance[0] = -1.0
        self._imu_msg.linear_acceleration_covariance[0] = -1.0
        noise2 = values['gyro_noise'] ** 2
        for k in (0, 4, 8):
            self._imu_msg.angular_velocity_covariance[k] = noise2
        self._pose_msg = PoseStamped()
        self._pose_msg.header.frame_id = values['lidar_pose_frame']

    # Setpoints ------------------------------------------------------------------------------

    def _on_setpoint(self, side: int, msg: Float64) -> None:
        with self._lock:
            problem = self._holds[side].take(msg.data, self._sim.t, time.monotonic())
        # One call site per side: rclpy throttles a warning by where it is logged.
        if problem and side == 0:
            self.get_logger().warning(f'left_track/setpoint: {problem}',
                                      throttle_duration_sec=WARN_PERIOD)
        elif problem:
            self.get_logger().warning(f'right_track/setpoint: {problem}',
                                      throttle_duration_sec=WARN_PERIOD)

    # Stepping -------------------------------------------------------------------------------

    def _loop(self) -> None:
        """Take the steps that are due, then sleep until the next one; until stopped."""
        worker = self._loop_thread
        wall0, sim0 = time.monotonic(), 0.0
        while not worker.stop.is_set():
            try:
                with self._lock:
                    rtf = self._rtf
                    if self._rescheduled:
                        self._rescheduled = False
                        wall0, sim0 = time.monotonic(), self._sim.t
                now = time.monotonic()
                due = int(math.floor((sim0 + (now - wall0) * rtf - self._sim.t) / self._dt
                                     + 1e-9))
                lag = due * self._dt / rtf
                if lag > MAX_LAG:
                    self.get_logger().warning(
                        f'cannot keep up with real_time_factor {rtf:g}: {lag:.2f} s behind '
                        'schedule; running on from here (the simulation slows down)',
                        throttle_duration_sec=LAG_WARN_PERIOD)
                    due = max(1, int(MAX_LAG * rtf / self._dt))
                    wall0, sim0 = now, self._sim.t + due * self._dt
                if due > 0:
                    self._steps(due)
                worker.succeeded()
                next_wall = wall0 + (self._sim.t + self._dt - sim0) / rtf
                wait = max(self._clock_period, next_wall - time.monotonic())
                if worker.wake.wait(wait):
                    worker.wake.clear()
            except Exception as err:  # noqa: BLE001 -- keep the simulation alive, say why
                if worker.failed(err):
                    break
                worker.wake.wait(0.01)

    _rescheduled = False

    def _steps(self, count: int) -> None:
        """Take ``count`` steps, then publish /clock (first) and the sensors."""
        pending = []
        with self._lock:
            wall = time.monotonic()
            t0, dt = self._sim.t, self._dt
            left, right = self._holds
            commands = [(left.current(t0 + k * dt, wall), right.current(t0 + k * dt, wall))
                        for k in range(count)]
            steps = self._sim.step_many(commands)
        times = steps.t.tolist()
        for k, t in enumerate(times):
            if self._encoder_due.due(t):
                pending.append((self._publish_joints, (t, *self._encoders.read(
                    steps.travel[k], steps.nominal[k]))))
            if self._truth_due.due(t):
                pending.append((self._publish_truth, (steps.state(k),)))
            if self._lidar is not None:
                for measured, pose in self._lidar.push(t, steps.pose[k]):
                    pending.append((self._publish_lidar,
                                    (t if self._lidar_on_receipt else measured, pose)))
        stamps, z_rates = self._gyro.push(steps.t - dt, steps.twist[:, 2])
        _stamp(self._clock_msg.clock, self._sim.t)
        self._clock_pub.publish(self._clock_msg)
        for publish, args in pending:
            publish(*args)
        for stamp, z_rate in zip(stamps.tolist(), z_rates.tolist()):
            self._publish_gyro(stamp, z_rate)

    def _publish_joints(self, t: float, position, velocity) -> None:
        msg = self._joint_msg
        _stamp(msg.header.stamp, t)
        msg.position = position.tolist()
        msg.velocity = velocity.tolist()
        self._joint_pub.publish(msg)

    def _publish_truth(self, state) -> None:
        msg = self._odom_msg
        _stamp(msg.header.stamp, state.t)
        x, y, theta = state.pose
        pose = msg.pose.pose
        pose.position.x, pose.position.y = x, y
        _, _, pose.orientation.z, pose.orientation.w = quaternion_from_yaw(theta)
        twist = msg.twist.twist
        twist.linear.x, twist.linear.y, twist.angular.z = state.twist
        self._odom_pub.publish(msg)

    def _publish_gyro(self, stamp: float, z_rate: float) -> None:
        msg = self._imu_msg
        _stamp(msg.header.stamp, stamp)
        msg.angular_velocity.z = z_rate
        self._imu_pub.publish(msg)

    def _publish_lidar(self, stamp: float, pose) -> None:
        msg = self._pose_msg
        _stamp(msg.header.stamp, stamp)
        msg.pose.position.x, msg.pose.position.y = float(pose[0]), float(pose[1])
        _, _, msg.pose.orientation.z, msg.pose.orientation.w = quaternion_from_yaw(
            float(pose[2]))
        self._pose_pub.publish(msg)

    # Parameters and shutdown ------------------------------------------------------------------

    def _apply(self, values: Mapping[str, Any]) -> None:
        timeout = values['setpoint_timeout'] or math.inf
        with self._lock:
            for hold in self._holds:
                hold.timeout = timeout
            if values['real_time_factor'] != self._rtf:
                self._rtf = values['real_time_factor']
                self._rescheduled = True
                self._loop_thread.wake.set()
        terrain = values['terrain']
        if terrain != self._wanted_terrain:
            # The new dynamics take a fraction of a second to tabulate: in a thread, so that
            # neither the steps nor the setpoints wait; the old terrain holds until then.
            self._wanted_terrain = terrain
            builder = threading.Thread(target=self._switch_terrain, args=(terrain,),
                                       name='terrain', daemon=True)
            self._builders = [b for b in self._builders if b.is_alive()] + [builder]
            builder.start()

    def _switch_terrain(self, terrain: str) -> None:
        """Tabulate the dynamics of ``terrain``, then use them from the next step (thread)."""
        try:
            table = self._terrains.table(terrain)
            with self._lock:
                if terrain != self._wanted_terrain or self._loop_thread.stop.is_set():
                    return  # superseded by a later change, or shutting down
                self._terrain = terrain
                self._sim.set_table(table)
                t = self._sim.t
            known = self._terrains.known[terrain]
            self.get_logger().info(
                f'terrain {terrain} (mu_x {known.mu_x:g}, mu_y {known.mu_y:g}) from '
                f't = {t:.3f} s')
            self._terrain_pub.publish(String(data=terrain))
        except Exception as err:  # noqa: BLE001 -- the old terrain stays; say why
            if not self._loop_thread.stop.is_set():
                self.get_logger().error(f'cannot switch to terrain {terrain}: {err!r}')

    def destroy_node(self):
        """Stop the stepping and terrain threads, then destroy the node."""
        self._stop_loop()
        for thread in self._builders:
            if thread.is_alive() and thread is not threading.current_thread():
                thread.join(5.0)
        super().destroy_node()


def main(args=None):
    """Run the node: exit 0 after a signal, 2 when it cannot start, 1 when it gave up."""
    raise SystemExit(run(TrackedSimulator, NODE_NAME, args, SIMULATOR_PARAMS, __doc__))
