"""icr_estimator on real topics: estimation, prediction, bad poses, pushing, console script."""

import math

from geometry_msgs.msg import PoseStamped
from helpers.encoder_stream import Driver, joint_state, stamp, Stderr
from helpers.ros_helpers import ConsoleScript, spin_until
from nav_msgs.msg import Odometry, Path
import numpy as np
import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray
from tracked_kinematics.core.estimate import scenarios
from tracked_kinematics.ros.icr_estimator import IcrEstimatorNode
from tracked_kinematics.ros.odometry_node import OdometryNode
from tracked_kinematics.ros.parameters import ParameterError

pytestmark = pytest.mark.ros

RADIUS = 0.1
HALF = 0.5 * scenarios.PAPER_TRACK_WIDTH
BASE = {'track_width': scenarios.PAPER_TRACK_WIDTH, 'sprocket_radius': RADIUS,
        'icr.y_left': HALF, 'icr.y_right': -HALF, 'icr.x': 0.0,
        'left_joints': ['left'], 'right_joints': ['right'], 'publish_rate': 20.0}


def _quaternion(msg_orientation, yaw):
    msg_orientation.z = math.sin(0.5 * yaw)
    msg_orientation.w = math.cos(0.5 * yaw)


def odometry_pose(t, x, y, yaw, frame='map'):
    msg = Odometry()
    msg.header.stamp = stamp(t)
    msg.header.frame_id = frame
    msg.pose.pose.position.x = float(x)
    msg.pose.pose.position.y = float(y)
    _quaternion(msg.pose.pose.orientation, yaw)
    return msg


def imu_heading(t, yaw):
    msg = Imu()
    msg.header.stamp = stamp(t)
    _quaternion(msg.orientation, yaw)
    return msg


class Graph:
    """An in-process icr_estimator fed by a driver node that records its outputs."""

    def __init__(self, ros_context, executor, capfd, overrides=None, pose_type=Odometry):
        values = {**BASE, **(overrides or {})}
        self.node = IcrEstimatorNode(
            context=ros_context,
            parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
        executor.add_node(self.node)
        self.executor = executor
        self.stderr = Stderr(capfd)
        self.encoders = Driver(ros_context, executor, lambda: self.node.encoder.received)
        self.poses = Driver(ros_context, executor, lambda: self.node.counts['received'],
                            node=self.encoders.node)
        self.pose_type = pose_type
        self.icr, self.paths = [], []
        self.encoders.node.create_subscription(Float64MultiArray, 'icr_estimate',
                                               self.icr.append, 10)
        self.encoders.node.create_subscription(Path, 'predicted_path', self.paths.append, 10)

    def feed(self, scenario, until=math.inf, heading_only=False):
        """Send a scenario's encoders (as joint angles) and poses in time order."""
        angle_left = np.cumsum(scenario.enc_left) / RADIUS
        angle_right = np.cumsum(scenario.enc_right) / RADIUS
        k = 0
        for t, pose in zip(scenario.pose_t, scenario.poses):
            if t > until:
                break
            while k < len(scenario.enc_t) and scenario.enc_t[k] <= t + 1e-9:
                assert self.encoders.send(joint_state(
                    scenario.enc_t[k] + 100.0, [angle_left[k], angle_right[k]],
                    names=('left', 'right')))
                k += 1
            msg = imu_heading(t + 100.0, pose[2]) if heading_only else odometry_pose(
                t + 100.0, *pose)
            assert self.poses.send(msg, 'pose')

    def wait_outputs(self, path=True):
        icr, paths = len(self.icr), len(self.paths)
        assert spin_until(self.executor,
                          lambda: len(self.icr) > icr and (len(self.paths) > paths or not path))


@pytest.fixture
def graph(ros_context, executor, capfd):
    def make(overrides=None):
        return Graph(ros_context, executor, capfd, overrides)
    return make


@pytest.fixture(scope='module')
def scenario():
    return scenarios.abrupt_change(seed=4, encoder_rate=50.0, pose_rate=10.0, duration=7.0)


def test_estimates_the_icrs_and_predicts_the_path(graph, scenario):
    g = graph()
    g.feed(scenario)
    g.wait_outputs()
    y_left, y_right, x, chi, e = g.icr[-1].data
    assert g.icr[-1].layout.dim[0].label == 'y_left,y_right,x,chi,e'
    np.testing.assert_allclose([y_left, y_right, x], [2.23, -2.23, 0.5], atol=0.15)
    assert chi == pytest.approx(scenarios.PAPER_TRACK_WIDTH / (y_left - y_right))
    assert e == pytest.approx(-(y_left + y_right) / (y_left - y_right))
    assert g.node.counts['updated'] > 50
    path = g.paths[-1]
    assert path.header.frame_id == 'map'
    assert len(path.poses) == 41  # 2 s in steps of 0.05 s, plus the start
    # The path starts at the latest pose and follows the true arc for 2 s.
    start = np.array([path.poses[0].pose.position.x, path.poses[0].pose.position.y])
    end = np.array([path.poses[-1].pose.position.x, path.poses[-1].pose.position.y])
    t_end = scenario.pose_t[-1]
    assert np.linalg.norm(start - scenario.truth_at(t_end)[:2]) < 0.1
    travelled = 2.0 * 1.5  # mean track speed 1.5 m/s
    assert 0.8 * travelled < np.linalg.norm(end - start) < travelled
    stamps = [p.header.stamp.sec + 1e-9 * p.header.stamp.nanosec for p in path.poses]
    np.testing.assert_allclose(np.diff(stamps), 0.05, atol=1e-6)


def test_bad_pose_messages_are_refused_with_a_warning(graph, scenario):
    g = graph()
    g.feed(scenario, until=4.0)
    g.wait_outputs()
    p, P = g.node.estimator.p.copy(), g.node.estimator.P.copy()
    t = 100.0 + scenario.pose_t[scenario.pose_t <= 4.0][-1]
    assert g.poses.send(odometry_pose(t + 0.05, math.nan, 0.0, 0.0), 'pose')
    assert g.poses.send(odometry_pose(t - 0.5, 0.0, 0.0, 0.0), 'pose')
    assert g.poses.send(odometry_pose(0.0, 0.0, 0.0, 0.0), 'pose')
    np.testing.assert_array_equal(g.node.estimator.p, p)
    np.testing.assert_array_equal(g.node.estimator.P, P)
    assert g.node.counts['non_finite'] == 1
    assert g.node.counts['stale'] == 1
    assert g.node.counts['zero_stamp'] == 1
    assert g.stderr.warnings('icr_estimator', 'refused (non_finite)')
    assert g.stderr.warnings('icr_estimator', 'zero stamp')
    g.wait_outputs()
    assert all(map(math.isfinite, g.icr[-1].data))


def test_heading_only_from_an_imu(ros_context, executor, capfd, scenario):
    g = Graph(ros_context, executor, capfd, {'pose_type': 'imu', 'model': 'adaptive_icr'})
    g.feed(scenario, heading_only=True)
    assert g.node.counts['updated'] > 30
    g.wait_outputs(path=False)
    # Heading-only: the turn rate is learnt; no path without a position.
    assert not g.paths
    y_left, y_right = g.icr[-1].data[:2]
    model_w = (1.0 - 2.0) / (y_left - y_right)
    true_w = (1.0 - 2.0) / (2.23 + 2.23)
    assert model_w == pytest.approx(true_w, rel=0.1)


def test_pushes_the_estimate_into_a_running_odometry_node(ros_context, executor, capfd,
                                                          scenario):
    odometry = OdometryNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in BASE.items() if k != 'publish_rate'])
    executor.add_node(odometry)
    g = Graph(ros_context, executor, capfd, {'push_to': ['odometry_node'],
                                             'push_period': 0.2})
    g.feed(scenario)

    def pushed():
        return [odometry.get_parameter(n).value for n in ('icr.y_left', 'icr.y_right', 'icr.x')]

    # Pushes happen while the data stream in; wait for the one of the final estimate.
    assert spin_until(executor, lambda: np.allclose(pushed(), g.node.estimator.icr(),
                                                    atol=0.011), 5.0)
    assert g.node.counts['pushed'] >= 1
    pushed = pushed()
    np.testing.assert_allclose(pushed, [2.23, -2.23, 0.5], atol=0.2)
    assert odometry.odometry.icr.y_left == pytest.approx(pushed[0])


def test_prediction_from_cmd_vel_through_the_drivetrain(ros_context, executor, capfd,
                                                        scenario):
    from geometry_msgs.msg import Twist
    g = Graph(ros_context, executor, capfd, {'prediction.source': 'cmd_vel',
                                             'drivetrain.delay': 0.2, 'drivetrain.loop': 'ideal'})
    g.feed(scenario, until=3.0)
    command = Twist()
    command.linear.x = 0.0   # stop: the path ends after the delay and the stop
    assert spin_until(executor, lambda: g.node.count_subscribers('cmd_vel') >= 0)
    pub = g.encoders.node.create_publisher(Twist, 'cmd_vel', 10)
    assert spin_until(executor, lambda: pub.get_subscription_count() > 0)
    pub.publish(command)
    assert spin_until(executor, lambda: g.node._command is not None)
    # Paths the node computed before the command may still be on their way (under load,
    # several): the first path from after it is the first stamped at a later encoder step.
    # One more step of the scenario, sent now, moves the node's "now" there.
    last_pose = scenario.pose_t[scenario.pose_t <= 3.0][-1]   # where feed() stopped
    k = int(np.searchsorted(scenario.enc_t, last_pose + 1e-9, side='right'))
    t_next = scenario.enc_t[k] + 100.0
    angles = [np.sum(scenario.enc_left[:k + 1]) / RADIUS,
              np.sum(scenario.enc_right[:k + 1]) / RADIUS]
    assert g.encoders.send(joint_state(t_next, angles, names=('left', 'right')))

    def after_the_command():
        return [p for p in g.paths
                if p.header.stamp.sec + 1e-9 * p.header.stamp.nanosec >= t_next - 1e-6]
    assert spin_until(executor, after_the_command)
    xy = np.array([[p.pose.position.x, p.pose.position.y]
                   for p in after_the_command()[0].poses])
    steps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert np.all(steps[:3] > 0.05)          # still moving during the 0.2 s delay
    assert np.all(steps[5:] < 1e-9)          # stopped after it (no lag, no ramp)


def test_bad_parameters_refuse_to_start(ros_context):
    for overrides, text in (({'window': 10.0}, 'window'), ({'pose_type': 'gps'}, 'pose_type'),
                            ({'icr.y_left': -2.0}, 'icr.y_left')):
        with pytest.raises(ParameterError, match=text):
            IcrEstimatorNode(context=ros_context, parameter_overrides=[
                Parameter(k, value=v) for k, v in {**BASE, **overrides}.items()])


# Issue 23: every EstimatorConfig field is a node parameter; a value at start and a changed
# value at runtime both reach the filter, and a value outside its range is refused.
AT_START = {'min_coverage': 0.5, 'adaptive_noise': False, 'noise_memory': 50, 'prior_std': 0.2,
            'prior_time': 12.0, 'fallback': False, 'fallback_span': 5.0,
            'fallback_margin': 0.3}
AT_RUNTIME = {'min_coverage': 0.95, 'adaptive_noise': True, 'noise_memory': 400,
              'prior_std': math.inf, 'prior_time': 2.0, 'fallback': True, 'fallback_span': 60.0,
              'fallback_margin': 0.0}
REFUSED = {'min_coverage': 0.0, 'noise_memory': 19, 'prior_std': 0.0, 'prior_time': 0.0,
           'fallback_span': 0.0, 'fallback_margin': 1.0}


def test_every_estimator_setting_is_a_parameter():
    from dataclasses import fields
    from tracked_kinematics.core.estimate.config import EstimatorConfig
    from tracked_kinematics.params.node_tables import ESTIMATOR_PARAMS
    declared = {spec.name: spec for spec in ESTIMATOR_PARAMS}
    # The noise model's settings are the terrain file's covariance.* (identify_icr's names).
    named = {'track_noise': 'covariance.k_left', 'turn_noise': 'covariance.turn',
             'slip_noise': 'covariance.slip'}
    for field in fields(EstimatorConfig):
        name = named.get(field.name, field.name)
        assert name in declared, field.name
        spec = declared[name]
        assert spec.description and spec.default == field.default
        assert isinstance(spec.default, bool) or spec.has_range, field.name
    assert set(AT_START) | set(AT_RUNTIME) | {'pose_delay'} <= declared.keys()


def test_estimator_settings_reach_the_filter_at_start_and_at_runtime(ros_context):
    node = IcrEstimatorNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {**BASE, **AT_START}.items()])
    try:
        config = node.estimator.config
        assert {name: getattr(config, name) for name in AT_START} == AT_START
        results = node.set_parameters([Parameter(k, value=v) for k, v in AT_RUNTIME.items()])
        assert all(r.successful for r in results), [r.reason for r in results]
        config = node.estimator.config
        assert {name: getattr(config, name) for name in AT_RUNTIME} == AT_RUNTIME
        for name, value in REFUSED.items():
            result = node.set_parameters([Parameter(name, value=value)])[0]
            assert not result.successful, name
            assert getattr(node.estimator.config, name) == AT_RUNTIME[name]
    finally:
        node.destroy_node()


@pytest.mark.parametrize('name', sorted(REFUSED))
def test_an_estimator_setting_out_of_range_refuses_to_start(ros_context, name):
    with pytest.raises(ParameterError, match=name):
        IcrEstimatorNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**BASE, name: REFUSED[name]}.items()])


@pytest.mark.parametrize('name, value, message', [
    ('pose_std_xy', 0.0, 'pose_std_xy must be > 0'),
    ('process_std', -1.0, 'process_std must be >= 0'),
    ('gate_probability', 1.0, 'gate_probability must be < 1'),
    ('max_outliers', 0, 'max_outliers must be > 0'),
    ('pose_delay', math.nan, 'pose_delay must be finite'),
    ('noise_memory', 5, 'noise_memory must be in [20, 100000]'),
    ('prior_std', 0.0, 'prior_std must be > 0'),
    ('fallback_span', 0.0, 'fallback_span must be > 0'),
    ('fallback_margin', 1.0, 'fallback_margin must be < 1'),
])
def test_estimator_settings_are_checked_where_they_enter(name, value, message):
    # EstimatorConfig trusts its fields: the node's parameter table checks each, once.
    from tracked_kinematics.params.spec import check_values
    from tracked_kinematics.params.node_tables import ESTIMATOR_PARAMS
    assert check_values(ESTIMATOR_PARAMS, {name: value}) == [f'{message}, got {value!r}']


@pytest.mark.parametrize('name, value', [('adaptive_noise', 1), ('fallback', 'yes')])
def test_an_estimator_switch_that_is_not_a_bool_refuses_to_start(ros_context, name, value):
    with pytest.raises(ParameterError, match=name):
        IcrEstimatorNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**BASE, name: value}.items()])


def test_pose_delay_reaches_the_filter(ros_context):
    # Issue 16: the ground-truth delay identify_icr finds applies to the node's pose stream.
    node = IcrEstimatorNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {**BASE, 'pose_delay': 0.25}.items()])
    assert node.estimator.config.pose_delay == 0.25
    assert node.set_parameters([Parameter('pose_delay', value=0.1)])[0].successful
    assert node.estimator.config.pose_delay == 0.1
    assert not node.set_parameters([Parameter('pose_delay', value=5.0)])[0].successful
    assert node.estimator.config.pose_delay == 0.1
    node.destroy_node()


def test_console_script_starts_and_exits_cleanly(tmp_path):
    with ConsoleScript('icr_estimator', '--ros-args', '-p', 'track_width:=0.5', '-p',
                       'sprocket_radius:=0.1', '-p', 'icr.y_left:=0.3', '-p',
                       'icr.y_right:=-0.3', tmp_path=tmp_path) as proc:
        assert _wait_for(lambda: 'estimating icr' in proc.output)
        assert proc.stop() == 0
    for args, text in ((['-p', 'process_std:=-1.0'], 'process_std must be >= 0'),
                       (['-p', 'publish_rate:=1e-11'], 'publish_rate must be in [0.01, 1000]'),
                       (['-p', 'push_to:=[1odometry_node]'], 'push_to [0] must be a valid'),
                       ([], 'track_width and sprocket_radius have no default')):
        bad = ConsoleScript('icr_estimator', '--ros-args', '-p', 'track_width:=0.5', '-p',
                            'sprocket_radius:=0.1', *args, tmp_path=tmp_path) if args else \
            ConsoleScript('icr_estimator', tmp_path=tmp_path)
        assert bad.wait() == 2, bad.output
        fatal = [line for line in bad.output.splitlines() if 'FATAL' in line]
        assert len(fatal) == 1 and text in fatal[0], bad.output


def _wait_for(condition, timeout=20.0):
    import time
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.1)
    return condition()


def test_pose_stamped_type_is_accepted(ros_context, executor, capfd, scenario):
    g = Graph(ros_context, executor, capfd, {'pose_type': 'pose_stamped'})
    k = 0
    angle_left = np.cumsum(scenario.enc_left) / RADIUS
    angle_right = np.cumsum(scenario.enc_right) / RADIUS
    for t, pose in list(zip(scenario.pose_t, scenario.poses))[:25]:
        while scenario.enc_t[k] <= t + 1e-9:
            assert g.encoders.send(joint_state(scenario.enc_t[k] + 100.0,
                                               [angle_left[k], angle_right[k]],
                                               names=('left', 'right')))
            k += 1
        msg = PoseStamped()
        msg.header.stamp = stamp(t + 100.0)
        msg.header.frame_id = 'odom_gps'
        msg.pose.position.x, msg.pose.position.y = float(pose[0]), float(pose[1])
        _quaternion(msg.pose.orientation, pose[2])
        assert g.poses.send(msg, 'pose')
    assert g.node.counts['updated'] > 10
    g.wait_outputs()
    assert g.paths[-1].header.frame_id == 'odom_gps'


def test_runtime_parameters_and_reset(ros_context, executor, capfd, scenario):
    from rclpy.parameter import Parameter as P
    from std_srvs.srv import Trigger
    g = Graph(ros_context, executor, capfd)
    g.feed(scenario, until=4.0)
    assert g.node.estimator.updates > 10
    before = g.node.estimator.p.copy()
    result = g.node.set_parameters_atomically([P('icr.y_left', value=1.5),
                                               P('icr.y_right', value=-1.5),
                                               P('publish_rate', value=5.0)])
    assert result.successful
    np.testing.assert_array_equal(g.node.estimator.p, before)  # the estimate is kept
    assert g.node._timer.timer_period_ns == 200_000_000
    assert not g.node.set_parameters([P('window', value=100.0)])[0].successful
    client = g.encoders.node.create_client(Trigger, '/icr_estimator/reset')
    assert client.wait_for_service(timeout_sec=5.0)
    future = client.call_async(Trigger.Request())
    assert spin_until(executor, future.done)
    assert future.result().success
    np.testing.assert_allclose(g.node.estimator.p, [1.5, -1.5, 0.0])
    assert g.node.set_parameters([P('track_width', value=2.0)])[0].successful
    assert g.node.estimator.model.track_width == 2.0


def test_absurd_encoder_positions_do_not_kill_it(graph, scenario):
    # Issue 14 item 5: JointState positions of +-1e308 killed the node (core ValueError).
    g = graph()
    g.feed(scenario, until=2.0)
    t = 100.0 + scenario.enc_t[scenario.enc_t <= 2.0][-1]
    for i, position in enumerate(([1e308, -1e308], [-1e308, 1e308], [1e308, 1e308])):
        assert g.encoders.send(joint_state(t + 0.01 * (i + 1), position,
                                           names=('left', 'right')))
    assert g.stderr.warnings('icr_estimator', 'implausible encoder input skipped')
    g.wait_outputs()
    assert all(map(math.isfinite, g.icr[-1].data))
    assert np.all(np.isfinite(g.node.estimator.p))


@pytest.mark.parametrize('push_to', [['bad name'], ['1odometry_node'], ['ok', ''],
                                     ['odometry_node/'], ['~/private']])
def test_invalid_push_targets_are_refused(ros_context, push_to):
    # Issue 14 item 5: ['bad name'] was accepted and killed the node seconds later.
    with pytest.raises(ParameterError, match='push_to'):
        IcrEstimatorNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**BASE, 'push_to': push_to}.items()])
    node = IcrEstimatorNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in BASE.items()])
    result = node.set_parameters([Parameter('push_to', value=push_to)])[0]
    assert not result.successful and 'push_to' in result.reason
    assert node.set_parameters([Parameter('push_to', value=['/robot/odometry_node',
                                                            'cmd_vel_translator'])])[0].successful
    node.destroy_node()


@pytest.mark.parametrize('name, value', [
    ('publish_rate', 1e-11), ('publish_rate', 1e9), ('prediction.dt', 1e-9),
    ('prediction.horizon', 1e6), ('window', 1e300), ('pose_std_xy', 5e-324),
    ('max_outliers', 10**12), ('track_width', 5e-324), ('max_plausible_speed', -1.0)])
def test_absurd_values_are_refused(ros_context, name, value):
    node = IcrEstimatorNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in BASE.items()])
    result = node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful and name in result.reason
    node.destroy_node()


def test_publish_rate_change_takes_effect_at_once(graph):
    g = graph({'publish_rate': 0.01})
    assert g.node.set_parameters([Parameter('publish_rate', value=50.0)])[0].successful
    assert g.node._timer.timer_period_ns == 20_000_000
    # Outputs (the timer also runs without an estimate) come at once, not after 100 s.
    ticks = []
    original = g.node._timer.callback
    g.node._timer.callback = lambda: (ticks.append(1), original())
    assert spin_until(g.executor, lambda: len(ticks) >= 5, 5.0)


def test_wrong_pose_type_is_named(ros_context, executor, capfd):
    import rclpy
    from rclpy.node import Node
    other = rclpy.Context()
    rclpy.init(context=other)
    try:
        node = IcrEstimatorNode(context=ros_context, namespace='typed', parameter_overrides=[
            Parameter(k, value=v) for k, v in BASE.items()])
        executor.add_node(node)
        stranger = Node('stranger', namespace='typed', context=other)
        stranger.create_publisher(PoseStamped, 'pose', 10)
        stderr = Stderr(capfd)
        assert spin_until(executor, lambda: stderr.warnings('typed.icr_estimator',
                                                            'another message type'), 5.0)
        (line,) = stderr.warnings('typed.icr_estimator', 'another message type')
        assert 'geometry_msgs/msg/PoseStamped' in line and 'nav_msgs/msg/Odometry' in line
        stranger.destroy_node()
        executor.remove_node(node)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=other)
