"""tracked_simulator on a real rclpy graph (issue 22): sensors, time, setpoints, terrains."""

import math
import time
import uuid

from geometry_msgs.msg import PoseStamped, Twist
from helpers.ros_helpers import ConsoleScript, spin_until
from nav_msgs.msg import Odometry
import numpy as np
import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64, String
from tracked_kinematics.core.integration import yaw_from_quaternion
from tracked_kinematics.params import read_params_file
from tracked_kinematics.ros.cmd_vel_translator import CmdVelTranslator
from tracked_kinematics.ros.odometry_node import OdometryNode
from tracked_kinematics.ros.parameters import ParameterError
from tracked_kinematics.ros.tracked_simulator import TrackedSimulator
from tracked_kinematics.share import config_file

pytestmark = pytest.mark.ros

TIMEOUT = 10.0  # s, deadline of every wait on the graph (a loaded 2-core machine)
# Keep the last few messages only: a probe that falls behind a fast simulation then sees the
# latest state, not a backlog of old ones (it spins in the simulator's process).
DEPTH = 20
RTF = 5.0


def _seconds(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


class Probe:
    """The rest of the graph: setpoint publishers and recorders of everything published."""

    def __init__(self, context, namespace=''):
        self.node = Node('simulator_probe', context=context, namespace=namespace or None)
        node = self.node
        self.joints, self.imu, self.truth, self.lidar, self.terrain = [], [], [], [], []
        self.clock = []  # (wall time of receipt, simulated time)
        node.create_subscription(JointState, 'joint_states', self.joints.append, DEPTH)
        node.create_subscription(Imu, 'imu/data', self.imu.append, DEPTH)
        node.create_subscription(Odometry, 'ground_truth/odom', self.truth.append, DEPTH)
        node.create_subscription(PoseStamped, 'lidar/pose', self.lidar.append, DEPTH)
        node.create_subscription(
            Clock, '/clock', lambda m: self.clock.append((time.monotonic(), _seconds(m.clock))),
            DEPTH)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        node.create_subscription(String, 'tracked_simulator/terrain',
                                 lambda m: self.terrain.append(m.data), latched)
        self.left = node.create_publisher(Float64, 'left_track/setpoint', 10)
        self.right = node.create_publisher(Float64, 'right_track/setpoint', 10)
        self.cmd = node.create_publisher(Twist, 'cmd_vel', 10)

    def send(self, left, right):
        self.left.publish(Float64(data=float(left)))
        self.right.publish(Float64(data=float(right)))

    def pose(self):
        """Return the last true pose as (x, y, yaw), or None."""
        if not self.truth:
            return None
        p = self.truth[-1].pose.pose
        return (p.position.x, p.position.y,
                float(yaw_from_quaternion(0.0, 0.0, p.orientation.z, p.orientation.w)))

    def speed(self):
        """Return the last true (v_x, w), or None."""
        if not self.truth:
            return None
        twist = self.truth[-1].twist.twist
        return twist.linear.x, twist.angular.z

    def sim_time(self):
        return self.clock[-1][1] if self.clock else 0.0


def drive(executor, probe, left, right, until, timeout=TIMEOUT):
    """Publish the setpoints at every spin until ``until()`` holds; return whether it did."""
    def condition():
        probe.send(left, right)
        return until()
    return spin_until(executor, condition, timeout)


def wait_sim(executor, probe, seconds, left=None, right=None):
    """Spin (sending setpoints when given) until ``seconds`` of simulated time have passed."""
    start = probe.sim_time()
    if left is None:
        return spin_until(executor, lambda: probe.sim_time() >= start + seconds, TIMEOUT)
    return drive(executor, probe, left, right, lambda: probe.sim_time() >= start + seconds)


@pytest.fixture
def namespace():
    """Give the test a namespace of its own: no stray publisher of a neighbour reaches it."""
    return f'/sim_{uuid.uuid4().hex[:12]}'


@pytest.fixture
def graph(ros_context, executor, namespace):
    """Build a simulator with parameter overrides and a probe, both on the executor."""
    made = []

    def make(**params):
        params.setdefault('real_time_factor', RTF)
        overrides = [Parameter(name, value=value) for name, value in params.items()]
        node = TrackedSimulator(context=ros_context, parameter_overrides=overrides,
                                namespace=namespace)
        made.append(node)
        executor.add_node(node)
        probe = Probe(ros_context, namespace)
        made.append(probe.node)
        executor.add_node(probe.node)
        assert spin_until(executor, lambda: probe.truth and probe.joints and probe.clock
                          and probe.left.get_subscription_count() > 0
                          and probe.right.get_subscription_count() > 0, TIMEOUT)
        return node, probe

    yield make
    for node in reversed(made):
        executor.remove_node(node)
        node.destroy_node()


def all_finite(probe):
    """Every number the simulator published so far is finite."""
    values = []
    for msg in probe.joints:
        values += list(msg.position) + list(msg.velocity)
    for msg in probe.imu:
        values.append(msg.angular_velocity.z)
    for msg in probe.truth:
        p, t = msg.pose.pose, msg.twist.twist
        values += [p.position.x, p.position.y, p.orientation.z, p.orientation.w,
                   t.linear.x, t.linear.y, t.angular.z]
    return len(values) > 0 and bool(np.all(np.isfinite(values)))


def test_sensors_arrive_with_their_names_frames_and_rates(graph, executor):
    node, probe = graph(encoder_rate=50.0, gyro_rate=100.0, ground_truth_rate=25.0)
    assert wait_sim(executor, probe, 2.0, 0.3, 0.3)
    joint = probe.joints[-1]
    assert list(joint.name) == ['left_sprocket_joint', 'right_sprocket_joint']
    assert len(joint.position) == 2 and len(joint.velocity) == 2
    imu = probe.imu[-1]
    assert imu.orientation_covariance[0] == -1.0
    assert imu.header.frame_id == 'base_link'
    truth = probe.truth[-1]
    assert (truth.header.frame_id, truth.child_frame_id) == ('odom', 'base_link')
    # Stamps in simulated time, at the sensors' rates (each publisher keeps its order).
    for msgs, rate in ((probe.joints, 50.0), (probe.imu, 100.0), (probe.truth, 25.0)):
        stamps = np.array([_seconds(m.header.stamp) for m in msgs])
        gaps = np.diff(stamps)
        assert np.all(gaps > 0)
        np.testing.assert_allclose(np.median(gaps), 1.0 / rate, rtol=1e-6)
    assert probe.lidar == []  # lidar_pose is off by default
    assert all_finite(probe)


def test_clock_runs_faster_than_real_time(graph, executor):
    asked = 10.0
    _, probe = graph(real_time_factor=asked)
    assert wait_sim(executor, probe, 1.0)
    wall0, sim0 = probe.clock[-1]
    assert wait_sim(executor, probe, 10.0)
    wall1, sim1 = probe.clock[-1]
    factor = (sim1 - sim0) / (wall1 - wall0)
    # A loaded machine (and this probe, in the same process) may slow the simulation down
    # (the benchmark measures 10.0x from a probe of its own), never speed it up.
    assert 1.5 < factor < asked * 1.1, factor


def test_setpoints_move_the_true_pose(graph, executor):
    _, probe = graph()
    assert probe.pose() == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)  # at rest, no command
    assert drive(executor, probe, 0.5, 0.5, lambda: probe.pose()[0] > 1.0)
    x, y, yaw = probe.pose()
    assert abs(y) < 0.2 * x and abs(yaw) < 0.2
    # An arc to the left: the heading grows.
    assert drive(executor, probe, 0.2, 0.6, lambda: probe.pose()[2] > yaw + 1.0)
    assert probe.speed()[1] > 0.2
    # The encoders saw it: the right sprocket turned further than the left one.
    joint = probe.joints[-1]
    assert joint.position[1] > joint.position[0] > 0.0
    assert joint.velocity[1] > joint.velocity[0] > 0.0
    assert all_finite(probe)


def test_a_stale_setpoint_stops_the_robot(graph, executor):
    _, probe = graph(setpoint_timeout=0.3)
    assert drive(executor, probe, 0.6, 0.6, lambda: probe.speed()[0] > 0.4)
    last_sent = probe.sim_time()
    # No more setpoints: the tracks stop (after the timeout, through the drive train).
    assert spin_until(executor, lambda: abs(probe.speed()[0]) < 1e-3, TIMEOUT)
    assert probe.sim_time() - last_sent > 0.3
    stopped = probe.pose()
    assert wait_sim(executor, probe, 1.0)
    assert probe.pose()[:2] == pytest.approx(stopped[:2], abs=1e-3)


def test_hostile_setpoints_are_ignored_or_clamped(graph, executor):
    node, probe = graph(setpoint_timeout=30.0)
    cruise = 0.4 * (1.0072 + 1.0275) / 2  # auriga_alpha's encoder scales

    def cruising():
        return probe.speed()[0] == pytest.approx(cruise, rel=0.02)
    assert drive(executor, probe, 0.4, 0.4, cruising)  # steady (the probe may lag a bit)
    # NaN and infinities are ignored: the last good setpoint holds, the robot drives on.
    for bad in (math.nan, math.inf, -math.inf):
        assert wait_sim(executor, probe, 1.0, bad, bad)
        assert cruising(), probe.speed()
    # A huge one is clamped; the drives limit it to the vehicle's top speed.
    top = 1.0 / 0.1  # auriga_alpha: 1 m/s, sprocket radius 0.1 m

    def at_top():
        velocity = probe.joints[-1].velocity
        return (velocity[0] == pytest.approx(top, rel=0.01)
                and velocity[1] == pytest.approx(-top, rel=0.01))
    assert drive(executor, probe, 1e300, -1e300, at_top)
    assert wait_sim(executor, probe, 1.0, 1e300, -1e300)
    assert at_top(), probe.joints[-1].velocity  # and it stays there
    assert all_finite(probe)


def test_terrain_switch_at_runtime(graph, executor):
    node, probe = graph()
    assert spin_until(executor, lambda: probe.terrain == ['hard_floor'], TIMEOUT)
    assert wait_sim(executor, probe, 3.0, 0.2, 0.6)  # a steady arc
    w_floor = probe.speed()[1]
    result = node.set_parameters([Parameter('terrain', value='grass')])[0]
    assert result.successful, result.reason
    # The new terrain's table is computed in a thread (0.2-0.5 s of CPU on a quiet machine,
    # far more beside other jobs): a generous deadline for the condition.
    assert drive(executor, probe, 0.2, 0.6, lambda: probe.terrain[-1:] == ['grass'],
                 timeout=120.0)
    assert wait_sim(executor, probe, 3.0, 0.2, 0.6)
    v_grass, w_grass = probe.speed()
    assert w_grass < 0.9 * w_floor and v_grass > 0.3  # grass slips more in a turn
    # Unknown terrains and invalid factors are refused; the terrain stays.
    refused = node.set_parameters([Parameter('terrain', value='moon')])[0]
    assert not refused.successful and 'hard_floor' in refused.reason
    assert not node.set_parameters([Parameter('real_time_factor', value=0.0)])[0].successful
    assert not node.set_parameters([Parameter('seed', value=3)])[0].successful  # read-only
    assert wait_sim(executor, probe, 1.0, 0.2, 0.6)
    assert probe.speed()[1] == pytest.approx(w_grass, rel=0.05)
    assert node.get_parameter('terrain').value == 'grass'


def test_real_time_factor_changes_at_runtime(graph, executor):
    node, probe = graph(real_time_factor=2.0)
    assert node.set_parameters([Parameter('real_time_factor', value=8.0)])[0].successful
    assert wait_sim(executor, probe, 1.0)
    wall0, sim0 = probe.clock[-1]
    assert wait_sim(executor, probe, 8.0)
    wall1, sim1 = probe.clock[-1]
    assert (sim1 - sim0) / (wall1 - wall0) > 2.5  # faster than the 2x it started at


@pytest.mark.parametrize('stamp', ['measurement', 'receipt'])
def test_lidar_pose_is_delayed_noisy_and_near_the_truth(graph, executor, stamp):
    delay = 0.2
    _, probe = graph(lidar_pose=True, lidar_pose_delay=delay, lidar_pose_jump_rate=0.0,
                     lidar_pose_position_noise=0.01, ground_truth_rate=100.0,
                     lidar_pose_stamp=stamp)
    truth, lidar = {}, []   # every message, however late the probe spins
    probe.node.create_subscription(
        Odometry, 'ground_truth/odom', lambda m: truth.setdefault(
            round(_seconds(m.header.stamp), 6), m.pose.pose.position.x), 5000)
    probe.node.create_subscription(PoseStamped, 'lidar/pose', lidar.append, 5000)
    assert wait_sim(executor, probe, 6.0, 0.5, 0.5)
    assert len(lidar) >= 20
    # The probe may lag the simulation: let the truth catch up with the last lidar pose.
    last = _seconds(lidar[-1].header.stamp)
    assert spin_until(executor, lambda: truth and max(truth) >= last, TIMEOUT)
    # The pose measured at s - delay (receipt) or at s (measurement), against the truth.
    shift = delay if stamp == 'receipt' else 0.0
    errors, late = [], []
    for msg in lidar:
        assert msg.header.frame_id == 'odom'
        s = _seconds(msg.header.stamp)
        measured = round(s - shift, 6)
        if measured in truth and round(s, 6) in truth and truth[measured] > 0.5:
            errors.append(msg.pose.position.x - truth[measured])
            late.append(msg.pose.position.x - truth[round(s, 6)])
    assert len(errors) >= 10
    assert 0.001 < np.std(errors) < 0.03 and abs(np.mean(errors)) < 0.01
    if stamp == 'receipt':  # the stamp is the publication: the pose trails it
        assert np.mean(late) < -0.5 * delay * 0.4


def test_the_same_seed_gives_the_same_readings(ros_context, executor, namespace):
    """At rest (no setpoints), the encoder and gyro noise depend on the seed alone."""
    def readings(seed):
        node = TrackedSimulator(context=ros_context, namespace=namespace, parameter_overrides=[
            Parameter('seed', value=seed), Parameter('real_time_factor', value=RTF)])
        probe = Probe(ros_context, namespace)
        got = {}
        probe.node.create_subscription(JointState, 'joint_states', lambda m: got.setdefault(
            round(_seconds(m.header.stamp), 6), tuple(m.velocity) + tuple(m.position)), 5000)
        probe.node.create_subscription(Imu, 'imu/data', lambda m: got.setdefault(
            -round(_seconds(m.header.stamp), 6), (m.angular_velocity.z,)), 5000)
        for each in (node, probe.node):
            executor.add_node(each)
        try:
            # Until 4 s of simulated time: the first ones may go before discovery ends.
            assert spin_until(executor, lambda: got and max(got) > 4.0, TIMEOUT)
        finally:
            for each in (probe.node, node):
                executor.remove_node(each)
                each.destroy_node()
        return got

    first, again, other = readings(4), readings(4), readings(5)
    common = sorted(set(first) & set(again) & set(other))
    assert len(common) > 100
    assert [first[k] for k in common] == [again[k] for k in common]
    assert all(first[k] != other[k] for k in common)


@pytest.mark.parametrize('params, reason', [
    ({'terrain': 'moon'}, 'terrain'),
    ({'vehicle': 'no_such_vehicle'}, 'vehicle'),
    ({'rate': 0.0}, 'rate'),
    ({'real_time_factor': math.nan}, 'real_time_factor'),
    ({'gyro_noise': -1.0}, 'gyro_noise'),
])
def test_invalid_parameters_are_refused_at_start(ros_context, params, reason):
    overrides = [Parameter(name, value=value) for name, value in params.items()]
    with pytest.raises(ParameterError, match=reason):
        TrackedSimulator(context=ros_context, parameter_overrides=overrides)


def test_stepping_that_keeps_failing_stops_the_node(capfd, namespace):
    # A step that raises is logged and retried; a second of them stops the node (exit 1).
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = TrackedSimulator(context=context, namespace=namespace)

        def broken(count):
            raise RuntimeError('injected step fault')

        node._steps = broken
        deadline = time.monotonic() + TIMEOUT
        while context.ok() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not context.ok() and isinstance(node.failure, RuntimeError)
        err = capfd.readouterr().err
        assert "simulation step failed: RuntimeError('injected step fault')" in err
        assert 'the simulation has failed for 1 s' in err and 'stopping the node' in err
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_closed_loop_with_cmd_vel_translator(graph, executor, ros_context, namespace):
    """cmd_vel -> translator (simulated time) -> setpoints -> simulator -> the true pose."""
    _, probe = graph()
    terrain = read_params_file(config_file('auriga_alpha_hard_floor.yaml'))
    overrides = [Parameter(name, value=value) for name, value in terrain.items()]
    overrides += [Parameter('use_sim_time', value=True), Parameter('rate', value=100.0),
                  Parameter('cmd_timeout', value=2.0)]
    translator = CmdVelTranslator(context=ros_context, parameter_overrides=overrides,
                                  namespace=namespace)
    executor.add_node(translator)
    try:
        command = Twist()
        command.linear.x, command.angular.z = 0.4, 0.3

        def moved():
            probe.cmd.publish(command)
            return probe.pose()[0] > 1.0 and probe.pose()[2] > 0.3
        assert spin_until(executor, moved, 3 * TIMEOUT)
        # The translator's ICRs are the terrain file's: the true turn is about the one asked.
        v_x, w = probe.speed()
        assert v_x == pytest.approx(0.4, rel=0.15) and w == pytest.approx(0.3, rel=0.15)
    finally:
        executor.remove_node(translator)
        translator.destroy_node()


@pytest.mark.parametrize('wrap', [False, True])
def test_odometry_node_follows_the_simulated_encoders(graph, executor, ros_context, namespace,
                                                      wrap):
    """joint_states -> odometry_node (simulated time) -> odom, against the true pose."""
    _, probe = graph(encoder_wrap=wrap)
    terrain = read_params_file(config_file('auriga_alpha_hard_floor.yaml'))
    overrides = [Parameter(name, value=value) for name, value in terrain.items()
                 if name not in ('terrain', 'source')]
    overrides.append(Parameter('use_sim_time', value=True))
    odometry = OdometryNode(context=ros_context, parameter_overrides=overrides,
                            namespace=namespace)
    odom = []
    probe.node.create_subscription(Odometry, 'odom', odom.append, DEPTH)
    executor.add_node(odometry)
    try:
        assert spin_until(executor, lambda: len(odom) > 0, TIMEOUT)
        start, start_odom = probe.pose(), odom[-1].pose.pose.position
        assert drive(executor, probe, 0.3, 0.7, lambda: probe.pose()[2] > start[2] + 2.0)
        # Stop, and wait until the odometry has caught up with the robot at rest.
        assert drive(executor, probe, 0.0, 0.0, lambda: max(map(abs, probe.speed())) < 1e-5)
        rest = _seconds(probe.truth[-1].header.stamp)
        assert spin_until(executor, lambda: _seconds(odom[-1].header.stamp) > rest + 0.1,
                          TIMEOUT)
        truth = probe.pose()
        pose = odom[-1].pose.pose
        assert _seconds(odom[-1].header.stamp) < 1e5  # stamped in simulated time
        moved = math.hypot(truth[0] - start[0], truth[1] - start[1])
        error = math.hypot(pose.position.x - start_odom.x - (truth[0] - start[0]),
                           pose.position.y - start_odom.y - (truth[1] - start[1]))
        # The paper's model (chi 0.540) on the simulated vehicle (chi 0.509): close, not exact.
        assert moved > 1.0 and error < 0.15 * moved
        yaw = float(yaw_from_quaternion(0.0, 0.0, pose.orientation.z, pose.orientation.w))
        assert abs(math.remainder(yaw - truth[2], 2 * math.pi)) < 0.2 * (truth[2] - start[2])
    finally:
        executor.remove_node(odometry)
        odometry.destroy_node()


def test_console_script_runs_and_exits_on_sigint(ros_context, executor, tmp_path):
    params = tmp_path / 'sim.yaml'
    params.write_text('/**:\n  ros__parameters:\n    real_time_factor: 5.0\n'
                      '    terrain: grass\n    seed: 3\n')
    namespace = f'/sim_{uuid.uuid4().hex[:12]}'
    probe = Probe(ros_context, namespace)
    executor.add_node(probe.node)
    try:
        with ConsoleScript('tracked_simulator', '--ros-args', '--params-file', params,
                           '-r', f'__ns:={namespace}', tmp_path=tmp_path) as script:
            assert spin_until(executor, lambda: len(probe.joints) >= 5
                              and probe.left.get_subscription_count() > 0
                              and probe.pose() is not None, 30.0), \
                script.output
            assert drive(executor, probe, 0.5, 0.5, lambda: probe.pose()[0] > 0.5), \
                script.output
            probe.send(math.nan, 1e300)  # ignored, clamped: said in a warning
            assert spin_until(executor, lambda: 'ignored a non-finite setpoint' in script.output
                              and 'clamped a setpoint' in script.output, TIMEOUT), \
                script.output
            assert probe.terrain[-1:] == ['grass']
            wall0, sim0 = probe.clock[-1]
            assert wait_sim(executor, probe, 5.0)
            wall1, sim1 = probe.clock[-1]
            assert (sim1 - sim0) / (wall1 - wall0) > 1.5
            assert script.stop() == 0
        assert 'simulating auriga_alpha' in script.output and 'on grass' in script.output
        assert 'Traceback' not in script.output
    finally:
        executor.remove_node(probe.node)
        probe.node.destroy_node()


@pytest.mark.parametrize('args, reason', [
    (['-p', 'terrain:=moon'], 'terrain'),
    (['-p', 'vehicle:=/nonexistent/robot.yaml'], 'vehicle'),
    (['-p', 'real_time_factor:=1000.0'], 'real_time_factor'),
])
def test_console_script_refuses_invalid_parameters(tmp_path, args, reason):
    with ConsoleScript('tracked_simulator', '--ros-args', *args, tmp_path=tmp_path) as script:
        assert script.wait(30.0) == 2
    fatal = [line for line in script.output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1 and reason in fatal[0], script.output
    assert 'Traceback' not in script.output


def test_hostile_clock_kills_no_node_of_the_loop(graph, executor, ros_context, namespace):
    """Issue 27: /clock at sec = -1, frozen and rewound beside the simulator's own: all live."""
    from std_msgs.msg import Float64MultiArray
    from tracked_kinematics.ros.icr_estimator import IcrEstimatorNode
    sim, probe = graph()
    terrain = read_params_file(config_file('auriga_alpha_hard_floor.yaml'))
    terrain = {k: v for k, v in terrain.items() if k not in ('terrain', 'source')}

    def overrides(**extra):
        return [Parameter(k, value=v) for k, v in {**terrain, 'use_sim_time': True,
                                                   **extra}.items()]
    nodes = [CmdVelTranslator(context=ros_context, namespace=namespace,
                              parameter_overrides=overrides(cmd_timeout=0.5)),
             OdometryNode(context=ros_context, namespace=namespace,
                          parameter_overrides=overrides()),
             IcrEstimatorNode(context=ros_context, namespace=namespace,
                              parameter_overrides=overrides(pose_topic='ground_truth/odom'))]
    odom, icr = [], []
    probe.node.create_subscription(Odometry, 'odom', odom.append, DEPTH)
    probe.node.create_subscription(Float64MultiArray, 'icr_estimate', icr.append, DEPTH)
    hostile = probe.node.create_publisher(Clock, '/clock', 10)
    for node in nodes:
        executor.add_node(node)
    try:
        command = Twist()
        command.linear.x, command.angular.z = 0.3, 0.2
        assert spin_until(executor, lambda: probe.cmd.publish(command) or len(odom) > 5,
                          3 * TIMEOUT)
        frozen = probe.sim_time()
        for seconds in (-1, int(frozen), int(frozen) - 5, -1, int(frozen)):
            msg = Clock()
            msg.clock.sec = seconds
            end = time.monotonic() + 0.5
            counts = len(odom), len(probe.joints)

            def attacked():
                hostile.publish(msg)
                probe.cmd.publish(command)
                return time.monotonic() > end
            assert spin_until(executor, attacked, TIMEOUT)
            # Everyone is alive and publishes finite values.
            assert spin_until(executor, lambda: len(odom) > counts[0]
                              and len(probe.joints) > counts[1], TIMEOUT)
        assert all(node.context.ok() for node in nodes) and sim.failure is None
        assert nodes[0].failure is None
        for msg in odom:
            pose = msg.pose.pose.position
            assert all(map(math.isfinite, (pose.x, pose.y, msg.twist.twist.linear.x)))
        for msg in probe.joints:
            assert all(map(math.isfinite, list(msg.position) + list(msg.velocity)))
        assert all(math.isfinite(x) for msg in icr for x in msg.data)
    finally:
        for node in nodes:
            executor.remove_node(node)
            node.destroy_node()
