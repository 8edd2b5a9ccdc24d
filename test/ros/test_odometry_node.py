"""odometry_node on real topics, in-process and as its console script."""

import math
import sys
import types

from helpers.encoder_stream import Driver, joint_state, stamp, Stderr
from helpers.manoeuvres import MANOEUVRES, track_speeds
from helpers.ros_helpers import ConsoleScript, spin_until
from nav_msgs.msg import Odometry as OdometryMsg
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64, Int32
from std_srvs.srv import Trigger
from tracked_kinematics.core.covariance import ros_covariance, TrackNoise, UNOBSERVED_VARIANCE
from tracked_kinematics.core.integration import integrate
from tracked_kinematics.core.kinematics import forward, true_speeds
from tracked_kinematics.core.noise_model import NoiseModel, PRIOR, timing_covariance
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.params import icr_from_values, read_params_file
from tracked_kinematics.params.node_tables import ODOMETRY_PARAMS
from tracked_kinematics.params.spec import check_values
from tracked_kinematics.ros import odometry_node
from tracked_kinematics.ros.odometry_node import OdometryNode
from tracked_kinematics.ros.parameters import ParameterError
from tracked_kinematics.share import config_file

pytestmark = pytest.mark.ros

TERRAIN = config_file('auriga_alpha_hard_floor.yaml')
AURIGA_VALUES = read_params_file(TERRAIN)
AURIGA = icr_from_values(AURIGA_VALUES)
RADIUS = AURIGA_VALUES['sprocket_radius']
RATE = 50.0


def manoeuvre(name, seconds=1.6):
    """Sprocket angles (rad) of a scripted manoeuvre at RATE Hz, starting at t = 10 s."""
    t = 10.0 + np.arange(int(seconds * RATE) + 1) / RATE
    # The S-curve's turn rate follows a full sine period.
    v_left, v_right = track_speeds(name, t - t[0], seconds, 0.3)
    # Track speed (m/s) -> sprocket angle: integrate the speed, divide by the radius.
    angle_left = 3.0 + np.concatenate([[0.0], np.cumsum(v_left[1:]) / RATE]) / RADIUS
    angle_right = -1.0 + np.concatenate([[0.0], np.cumsum(v_right[1:]) / RATE]) / RADIUS
    return t, angle_left, angle_right


def expected_odometry(angle_left, angle_right):
    """Poses and twists of the core's vectorised path for the same encoder angles."""
    d_left, d_right = np.diff(angle_left) * RADIUS, np.diff(angle_right) * RADIUS
    x, y, theta = integrate(*forward(*true_speeds(d_left, d_right, AURIGA), AURIGA))
    twist = np.stack(forward(*true_speeds(d_left, d_right, AURIGA), AURIGA), -1) * RATE
    return np.stack([x, y, theta], -1), twist, d_left, d_right


def yaw(msg):
    q = msg.pose.pose.orientation
    return 2.0 * math.atan2(q.z, q.w)


def unwrap_yaw(msgs):
    return np.unwrap([yaw(m) for m in msgs])


class Graph:
    """An in-process odometry_node with a driver that feeds it and records odom."""

    def __init__(self, ros_context, executor, capfd, overrides=None, namespace=''):
        overrides = {**AURIGA_VALUES, **(overrides or {})}
        overrides = {k: v for k, v in overrides.items() if k not in ('terrain', 'source')}
        self.node = OdometryNode(
            context=ros_context, namespace=namespace,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        executor.add_node(self.node)
        self.executor = executor
        self.stderr = Stderr(capfd)
        self.driver = Driver(ros_context, executor, lambda: self.node.encoder.received,
                             namespace)
        self.odom = []
        self.driver.node.create_subscription(
            OdometryMsg, 'odom', self.odom.append,
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        assert spin_until(executor, lambda: self.node.count_subscribers('odom') >= 1)

    def send(self, msg, topic='joint_states'):
        assert self.driver.send(msg, topic)

    def stream(self, t, angle_left, angle_right):
        start = len(self.odom)
        for ti, al, ar in zip(t, angle_left, angle_right):
            self.send(joint_state(ti, [al, ar]))
        spin_until(self.executor, lambda: len(self.odom) >= start + len(t) - 1, 2.0)
        return self.odom[start:]

    def warned(self, text):
        return self.stderr.warnings('odometry_node', text)


@pytest.fixture
def graph(ros_context, executor, capfd):
    def make(overrides=None, namespace=''):
        return Graph(ros_context, executor, capfd, overrides, namespace)
    return make


def assert_matches_core(msgs, t, angle_left, angle_right, tol=1e-6):
    poses, twists, d_left, d_right = expected_odometry(angle_left, angle_right)
    assert len(msgs) == len(t) - 1
    got = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in msgs])
    np.testing.assert_allclose(got, poses[:, :2], atol=tol)
    np.testing.assert_allclose(unwrap_yaw(msgs), poses[:, 2], atol=tol)
    got_twist = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y,
                           m.twist.twist.angular.z] for m in msgs])
    np.testing.assert_allclose(got_twist, twists, atol=tol)
    assert [(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9) for m in msgs] == (
        pytest.approx(list(t[1:]), abs=1e-9))
    # The covariance is the core's propagation with the default noise model (the tracks'
    # random walk, the turn and slip terms), plus the timing term at the last rates,
    # embedded in ROS's 6 x 6 layout.
    terms = NoiseModel(track=0.0, turn=PRIOR.turn, slip=PRIOR.slip, timing=PRIOR.timing,
                       floor=0.0)
    core = Odometry(AURIGA, TrackNoise(), terms)
    for dl, dr in zip(d_left, d_right):
        core.update(dl, dr, 1.0 / RATE)
    v_x, v_y, w = got_twist[-1]
    theta = core.pose[2]
    timing = timing_covariance(terms, math.cos(theta) * v_x - math.sin(theta) * v_y,
                               math.sin(theta) * v_x + math.cos(theta) * v_y, w)
    expected = [a + b for a, b in zip(core.covariance_upper, timing)]
    np.testing.assert_allclose(msgs[-1].pose.covariance, ros_covariance(expected),
                               rtol=1e-9, atol=1e-15)
    return got_twist


@pytest.mark.parametrize('name', MANOEUVRES)
def test_manoeuvre_matches_core(graph, name):
    g = graph()
    t, angle_left, angle_right = manoeuvre(name)
    msgs = g.stream(t, angle_left, angle_right)
    twist = assert_matches_core(msgs, t, angle_left, angle_right)
    for msg in msgs:
        assert msg.header.frame_id == 'odom' and msg.child_frame_id == 'base_link'
    if name != 'straight':
        # icr.x = 0.032 m: lateral slip v_y = -x w shows in the twist.
        np.testing.assert_allclose(twist[:, 1], -AURIGA.x * twist[:, 2], atol=1e-12)
        assert np.abs(twist[:, 1]).max() > 1e-3


def test_covariance_is_fusable_and_grows(graph):
    g = graph()
    msgs = g.stream(*manoeuvre('turn'))
    for msg in (msgs[0], msgs[-1]):
        for flat in (msg.pose.covariance, msg.twist.covariance):
            cov = np.asarray(flat).reshape(6, 6)
            np.testing.assert_array_equal(cov, cov.T)
            assert np.linalg.eigvalsh(cov).min() >= -1e-15
            assert cov[2, 2] == cov[3, 3] == cov[4, 4] == UNOBSERVED_VARIANCE
    first, last = (np.asarray(m.pose.covariance).reshape(6, 6) for m in (msgs[0], msgs[-1]))
    for i in (0, 1, 5):
        assert 0.0 < first[i, i] < last[i, i]
    assert np.asarray(msgs[-1].twist.covariance).reshape(6, 6)[5, 5] > 0.0


def test_publish_rate_caps_output_and_averages_the_twist(graph):
    g = graph({'publish_rate': 10.0})
    t, angle_left, angle_right = manoeuvre('s_curve')
    for ti, al, ar in zip(t, angle_left, angle_right):
        g.send(joint_state(ti, [al, ar]))
    spin_until(g.executor, lambda: len(g.odom) >= 16, 1.0)
    # 50 Hz in, at most 10 Hz out by message time: steps 1, 6, 11, ... are published.
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in g.odom]
    assert stamps == pytest.approx(list(t[1::5]), abs=1e-9)
    poses, twists, _, _ = expected_odometry(angle_left, angle_right)
    np.testing.assert_allclose([m.pose.pose.position.x for m in g.odom], poses[::5, 0],
                               atol=1e-6)
    # The twist is the mean over the steps since the previous message.
    np.testing.assert_allclose(g.odom[2].twist.twist.angular.z, twists[6:11, 2].mean(),
                               atol=1e-9)


def test_bad_input_never_publishes_non_finite_and_keeps_the_pose(graph):
    g = graph()
    t, angle_left, angle_right = manoeuvre('turn', seconds=0.4)
    g.stream(t, angle_left, angle_right)
    last = g.odom[-1]
    bad = [
        joint_state(10.42, [math.nan, 0.0]),
        joint_state(10.44, [math.nan, 0.0], velocity=[math.inf, 1.0]),
        joint_state(10.46, [1.0, 1.0], names=['wheel_a', 'wheel_b']),
        joint_state(5.0, [100.0, 100.0]),  # time jumps back: restart, pose kept
        joint_state(5.01, [1e100, 3e99]),  # implausible: skipped, pose kept
        joint_state(5.02, [-1e308, 1e308]),
        joint_state(5.03, [100.0, 100.0]),  # back to the baseline: a step of nothing
    ]
    for msg in bad:
        g.send(msg)
    assert spin_until(g.executor, lambda: len(g.odom) >= len(t))
    assert len(g.odom) == len(t)  # only the step of nothing was published
    g.send(joint_state(5.05, [100.1, 100.1]))
    assert spin_until(g.executor, lambda: len(g.odom) == len(t) + 1)
    # One step of 0.1 rad per sprocket from the pose before the bad input.
    d = np.array([0.1 * RADIUS])
    pose0 = (last.pose.pose.position.x, last.pose.pose.position.y, yaw(last))
    x, y, _ = integrate(*forward(*true_speeds(d, d, AURIGA), AURIGA), pose0=pose0)
    position = g.odom[-1].pose.pose.position
    assert (position.x, position.y) == pytest.approx((x[0], y[0]), abs=1e-9)
    for msg in g.odom:
        values = [msg.pose.pose.position.x, msg.pose.pose.position.y, yaw(msg),
                  msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z,
                  *msg.pose.covariance, *msg.twist.covariance]
        assert all(map(math.isfinite, values))
    for text in ('non-finite encoder reading', 'lacks the joints', 'time did not advance',
                 'implausible encoder input skipped'):
        assert g.warned(text), text


# The track random walk alone (the terms of the noise model that today's bounds predate off).
TRACKS_ONLY = {'covariance.turn': 0.0, 'covariance.slip': 0.0, 'covariance.timing': 0.0}


def test_reset_service_returns_pose_to_zero(graph):
    g = graph(TRACKS_ONLY)
    t, angle_left, angle_right = manoeuvre('turn', seconds=0.4)
    g.stream(t, angle_left, angle_right)
    assert g.odom[-1].pose.pose.position.x > 0.05
    client = g.driver.node.create_client(Trigger, 'odometry_node/reset')
    assert client.wait_for_service(timeout_sec=2.0)
    future = client.call_async(Trigger.Request())
    assert spin_until(g.executor, future.done)
    assert future.result().success and 'reset' in future.result().message
    # Two more steps of 0.1 rad on each sprocket: the pose starts again from zero.
    msgs = g.stream(t[-1] + np.array([0.0, 0.02, 0.04]), angle_left[-1] + [0.0, 0.1, 0.2],
                    angle_right[-1] + [0.0, 0.1, 0.2])[-2:]
    d = np.full(2, 0.1 * RADIUS)
    x, y, _ = integrate(*forward(*true_speeds(d, d, AURIGA), AURIGA))
    assert msgs[-1].pose.pose.position.x == pytest.approx(x[-1], abs=1e-9)
    assert msgs[-1].pose.pose.position.y == pytest.approx(y[-1], abs=1e-9)
    assert msgs[-1].pose.covariance[0] < 1e-4


def test_runtime_parameters(graph):
    g = graph()
    node = g.node
    # Invalid: refused with the reason, old values kept.
    result = node.set_parameters([Parameter('icr.y_left', value=-1.0)])[0]
    assert not result.successful and 'icr.y_left' in result.reason
    assert node.get_parameter('icr.y_left').value == AURIGA.y_left
    result = node.set_parameters([Parameter('covariance.k_left', value=-1.0)])[0]
    assert not result.successful and 'covariance.k_left' in result.reason
    result = node.set_parameters([Parameter('odom_frame', value='base_link')])[0]
    assert not result.successful and 'differ' in result.reason
    assert not node.set_parameters([Parameter('input_mode', value='track_speeds')])[0].successful
    # Valid: taken into use from the next message.
    assert node.set_parameters_atomically([
        Parameter('icr.x', value=-0.1), Parameter('odom_frame', value='map_odom')]).successful
    t, angle_left, angle_right = manoeuvre('turn', seconds=0.1)
    msgs = g.stream(t, angle_left, angle_right)
    twist = msgs[-1].twist.twist
    assert twist.linear.y == pytest.approx(0.1 * twist.angular.z, rel=1e-9)
    assert msgs[-1].header.frame_id == 'map_odom'


VEHICLE = [Parameter('track_width', value=0.42), Parameter('sprocket_radius', value=0.1)]


def test_invalid_parameters_at_start_raise(ros_context):
    with pytest.raises(ParameterError, match='scale.left must be > 0'):
        OdometryNode(context=ros_context,
                     parameter_overrides=VEHICLE + [Parameter('scale.left', value=0.0)])
    with pytest.raises(ParameterError, match='input_mode must be one of'):
        OdometryNode(context=ros_context,
                     parameter_overrides=VEHICLE + [Parameter('input_mode', value='wheels')])
    with pytest.raises(ParameterError, match='track_width and sprocket_radius have no default'):
        OdometryNode(context=ros_context)


def test_track_speeds_mode(graph):
    g = graph({'input_mode': 'track_speeds'}, namespace='speeds')
    for _ in range(3):
        g.send(Float64(data=0.5), 'left_track/speed')
        g.send(Float64(data=0.5), 'right_track/speed')
    assert spin_until(g.executor, lambda: len(g.odom) == 2)
    # Timed by the node's clock; straight at 0.5 m/s nominal through the scales.
    msg = g.odom[-1]
    v_x = forward(*true_speeds(0.5, 0.5, AURIGA), AURIGA)[0]
    assert msg.twist.twist.linear.x == pytest.approx(float(v_x), rel=1e-9)
    assert msg.pose.pose.position.x > 0.0


def test_track_speeds_follow_sim_time(graph):
    g = graph({'input_mode': 'track_speeds', 'use_sim_time': True}, namespace='sim')
    clock = g.driver.node.create_publisher(Clock, '/clock', 10)
    assert spin_until(g.executor, lambda: clock.get_subscription_count() > 0)
    for now in (100.0, 100.5):
        clock.publish(Clock(clock=stamp(now)))
        assert spin_until(g.executor, lambda: g.node.get_clock().now().nanoseconds
                          == int(now * 1e9))
        g.send(Float64(data=0.4), 'left_track/speed')
        g.send(Float64(data=0.4), 'right_track/speed')
    assert spin_until(g.executor, lambda: len(g.odom) == 1)
    msg = g.odom[0]
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (100, 500_000_000)
    d = np.array([0.2])  # 0.4 m/s nominal for 0.5 s of sim time
    x, y, _ = integrate(*forward(*true_speeds(d, d, AURIGA), AURIGA))
    assert msg.pose.pose.position.x == pytest.approx(x[0], rel=1e-9)


def test_encoder_ticks_mode_wraps(graph):
    g = graph({'input_mode': 'encoder_ticks', 'ticks_per_revolution': 1000.0},
              namespace='ticks')
    assert '1591.55 ticks per metre' in g.node.encoder.describe()  # 1000 / (2 pi 0.1 m)
    top = 2**31 - 1
    for left, right in [(top - 9, top - 9), (-top + 9, -top + 9)]:  # +20 ticks
        g.send(Int32(data=left), 'left_track/ticks')
        g.send(Int32(data=right), 'right_track/ticks')
    assert spin_until(g.executor, lambda: len(g.odom) == 1)
    travel = np.array([0.02 * 2 * math.pi * RADIUS])  # 2 % of a sprocket revolution
    x, y, _ = integrate(*forward(*true_speeds(travel, travel, AURIGA), AURIGA))
    position = g.odom[0].pose.pose.position
    assert (position.x, position.y) == pytest.approx((x[0], y[0]), rel=1e-9)


def test_tf_warning_once_without_tf2_ros(graph):
    if 'tf2_ros' in sys.modules:
        pytest.skip('tf2_ros is installed here')
    g = graph()
    g.stream(*manoeuvre('straight', seconds=0.1))
    (line,) = g.warned('tf2_ros cannot be imported')
    assert 'publish_tf' in line


def test_tf_broadcast_when_tf2_ros_imports(graph, monkeypatch):
    sent = []

    class TransformBroadcaster:
        def __init__(self, node):
            self.node = node

        def sendTransform(self, transform):  # noqa: N802 -- tf2_ros's name
            sent.append((transform.header.frame_id, transform.child_frame_id,
                         transform.header.stamp.nanosec, transform.transform.translation.x,
                         transform.transform.rotation.z))

    monkeypatch.setitem(sys.modules, 'tf2_ros',
                        types.SimpleNamespace(TransformBroadcaster=TransformBroadcaster))
    g = graph({'base_frame': 'chassis'})
    msgs = g.stream(*manoeuvre('turn', seconds=0.1))
    assert not g.warned('tf2_ros')
    assert sent == [('odom', 'chassis', m.header.stamp.nanosec, m.pose.pose.position.x,
                     m.pose.pose.orientation.z) for m in msgs]


def _stream_to_console_script(tmp_path, ros_context, executor, name):
    from rclpy.node import Node
    odom = []
    node = Node('odometry_probe', context=ros_context)
    executor.add_node(node)
    node.create_subscription(OdometryMsg, 'odom', odom.append,
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    with ConsoleScript('odometry_node', '--ros-args', '--params-file', TERRAIN,
                       '-p', 'publish_tf:=false', tmp_path=tmp_path) as script:
        driver = Driver(ros_context, executor, lambda: len(odom), node=node)
        t, angle_left, angle_right = manoeuvre(name)
        msgs = [joint_state(*args) for args in zip(t, zip(angle_left, angle_right))]
        pub = driver.publisher(type(msgs[0]), 'joint_states', timeout=10.0)
        # The first message is only a baseline: send it with the second until an odom
        # comes back (a duplicate of it restarts from the same sample, harmlessly).
        for _ in range(5):
            pub.publish(msgs[0])
            pub.publish(msgs[1])
            if spin_until(executor, lambda: len(odom) == 1, 1.0):
                break
        for msg in msgs[2:]:
            assert driver.send(msg), script.output
        output = script.output
    return odom, (t, angle_left, angle_right), output, script.process.returncode


def test_console_script_with_params_file(tmp_path, ros_context, executor):
    odom, (t, angle_left, angle_right), output, code = _stream_to_console_script(
        tmp_path, ros_context, executor, 's_curve')
    twist = assert_matches_core(odom, t, angle_left, angle_right)
    assert np.abs(twist[:, 1]).max() > 1e-3  # v_y of icr.x = 0.032 m
    assert 'chi 0.540' in output and 'input joint_states' in output
    assert code == 0


def test_console_script_refuses_invalid_parameters(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    track_width: 0.42\n    sprocket_radius: 0.1\n'
                   '    icr: {y_left: 0.1, y_right: -0.1}\n')
    script = ConsoleScript('odometry_node', '--ros-args', '--params-file', bad,
                           tmp_path=tmp_path)
    assert script.wait(30.0) == 2
    lines = [line for line in script.output.splitlines() if 'FATAL' in line]
    assert len(lines) == 1 and 'chi' in lines[0] and 'outside (0, 1]' in lines[0]


def _position(msg):
    return msg.pose.pose.position.x, msg.pose.pose.position.y


@pytest.mark.parametrize('frames', [('ZZZZ<<<<', 'base_ZZZZ<<<<'), ('odom', 'ZZZZ<<<<')])
def test_any_frame_ids_publish(graph, frames):
    # Issue 14 item 4: frames equal to the old serializer's sentinel killed the node.
    g = graph({'odom_frame': frames[0], 'base_frame': frames[1]})
    msgs = g.stream(*manoeuvre('turn', seconds=0.1))
    assert {(m.header.frame_id, m.child_frame_id) for m in msgs} == {frames}
    assert g.node.set_parameters_atomically([Parameter('odom_frame', value='odom_ZZZZ<<<<'),
                                             Parameter('base_frame', value='b')]).successful
    t, angle_left, angle_right = manoeuvre('turn', seconds=0.1)
    msgs = g.stream(t + 1.0, angle_left, angle_right)
    assert (msgs[-1].header.frame_id, msgs[-1].child_frame_id) == ('odom_ZZZZ<<<<', 'b')


@pytest.mark.parametrize('name, value, reason', [
    ('publish_rate', 5e-324, 'publish_rate must be 0 or >= 0.01 Hz'),
    ('publish_rate', 1e9, 'publish_rate'),
    ('odom_frame', '/odom', 'must not start with "/"'),
    ('base_frame', 'base link', 'without spaces'),
    ('base_frame', '', 'non-empty frame id'),
    ('track_width', 5e-324, 'track_width'),
    ('sprocket_radius', 1e300, 'sprocket_radius'),
    ('max_plausible_speed', 0.0, 'max_plausible_speed'),
    ('covariance.k_left', 1e300, 'covariance.k_left'),
    ('max_dt', 1e-300, 'max_dt'),
])
def test_absurd_values_are_refused_and_the_node_keeps_running(graph, name, value, reason):
    g = graph()
    result = g.node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful and reason in result.reason
    assert g.node.get_parameter(name).value == g.node.params[name]
    assert len(g.stream(*manoeuvre('straight', seconds=0.1))) == 5


def test_absurd_positions_do_not_freeze_the_heading(graph):
    # Issue 14 item 6: after left 1e100, 3e99, 0 rad, a 90 degree spin publishes 90 degrees.
    g = graph({'icr.y_left': 0.21, 'icr.y_right': -0.21, 'icr.x': 0.0, 'scale.left': 1.0,
               'scale.right': 1.0, **TRACKS_ONLY})
    for i, left in enumerate((0.0, 1e100, 3e99, 0.0)):
        g.send(joint_state(10.0 + 0.02 * i, [left, 0.0]))
    assert g.warned('implausible encoder input skipped')
    quarter = 0.5 * math.pi * 0.21 / RADIUS  # sprocket angle of a 90 degree spin
    t = 10.06 + 0.02 * np.arange(1, 26)
    k = np.arange(1, 26) / 25
    g.stream(t, -quarter * k, quarter * k)
    assert spin_until(g.executor, lambda: g.odom[-1].header.stamp == stamp(t[-1]))
    msgs = g.odom
    assert yaw(msgs[-1]) == pytest.approx(0.5 * math.pi, abs=1e-9)
    covariance = np.asarray(msgs[-1].pose.covariance).reshape(6, 6)[np.ix_([0, 1, 5], [0, 1, 5])]
    assert np.all(np.isfinite(covariance)) and np.abs(covariance).max() < 0.01


def test_a_gap_in_a_straight_drive_keeps_the_travel(graph):
    # Issue 15 item 2: a 0.7 s gap in a straight 1 m drive gave x = 0.860 m.
    g = graph({'icr.y_left': 0.21, 'icr.y_right': -0.21, 'icr.x': 0.0, 'scale.left': 1.0,
               'scale.right': 1.0})
    t = 10.0 + np.arange(101) / RATE           # 2 s at 0.5 m/s
    angle = 0.5 * (t - t[0]) / RADIUS
    keep = (t < 10.6) | (t > 11.3)             # nothing from 10.6 to 11.3 s
    msgs = g.stream(t[keep], angle[keep], angle[keep])
    assert msgs[-1].pose.pose.position.x == pytest.approx(1.0, abs=1e-9)
    (line,) = g.stderr.lines('INFO', 'odometry_node', 'without encoder data')
    assert 'integrated' in line


def test_wrapped_joints_give_the_true_travel(graph):
    # Issue 15 item 3: continuous joints reported in [-pi, pi] gave x = -0.257 m for 1 m.
    g = graph({'icr.y_left': 0.21, 'icr.y_right': -0.21, 'icr.x': 0.0, 'scale.left': 1.0,
               'scale.right': 1.0})
    t = 10.0 + np.arange(101) / RATE
    wrapped = np.angle(np.exp(1j * 0.5 * (t - t[0]) / RADIUS))
    msgs = g.stream(t, wrapped, wrapped)
    assert msgs[-1].pose.pose.position.x == pytest.approx(1.0, abs=1e-9)


def test_icrs_follow_the_track_width_until_set(ros_context, executor, capfd):
    node = OdometryNode(context=ros_context, parameter_overrides=VEHICLE)
    assert (node.odometry.icr.y_left, node.odometry.icr.y_right) == (0.21, -0.21)
    assert 'icr.y_left and icr.y_right from track_width' in capfd.readouterr().err
    assert node.set_parameters([Parameter('track_width', value=0.6)])[0].successful
    assert (node.odometry.icr.y_left, node.odometry.icr.y_right) == (0.3, -0.3)
    assert node.get_parameter('icr.y_left').value == 0.3
    assert node.set_parameters([Parameter('icr.y_left', value=0.4)])[0].successful
    assert node.set_parameters([Parameter('track_width', value=0.7)])[0].successful
    assert (node.odometry.icr.y_left, node.odometry.icr.y_right) == (0.4, -0.35)
    node.destroy_node()


def test_a_second_instance_on_the_same_topic_is_named(ros_context, executor, capfd):
    # Issue 14 item 13: two odometry_node instances doubled /odom without a word.
    first = OdometryNode(context=ros_context, namespace='dup', parameter_overrides=VEHICLE)
    second = OdometryNode(context=ros_context, namespace='robot2',
                          cli_args=['--ros-args', '-r', 'odom:=/dup/odom'],
                          parameter_overrides=VEHICLE)
    for node in (first, second):
        executor.add_node(node)
    stderr = Stderr(capfd)

    def warned(logger):
        return stderr.warnings(logger, '2 publishers on /dup/odom')
    assert spin_until(executor, lambda: warned('dup.odometry_node')
                      and warned('robot2.odometry_node'), 5.0)
    (line,) = warned('dup.odometry_node')
    assert '/dup/odometry_node' in line and '/robot2/odometry_node' in line
    for node in (first, second):
        executor.remove_node(node)
        node.destroy_node()


def test_console_script_refuses_to_start_without_a_vehicle(tmp_path):
    # Issue 15 item 1: as diff_drive_controller without wheel_separation and wheel_radius.
    script = ConsoleScript('odometry_node', '--ros-args', '-p', 'publish_tf:=false',
                           tmp_path=tmp_path)
    assert script.wait(30.0) == 2
    lines = [line for line in script.output.splitlines() if line.strip()]
    assert len(lines) == 1 and '[FATAL]' in lines[0], script.output
    assert 'track_width and sprocket_radius have no default' in lines[0]
    script = ConsoleScript('odometry_node', '--ros-args', '--params-file', TERRAIN, '-p',
                           'publish_rate:=1e-300', tmp_path=tmp_path)
    assert script.wait(30.0) == 2
    assert 'publish_rate must be 0 or >= 0.01 Hz' in script.output


@pytest.mark.parametrize('name, value, message', [
    ('covariance.k_left', -1.0, 'covariance.k_left must be >= 0'),
    ('covariance.floor', math.nan, 'covariance.floor must be finite'),
    ('covariance.k_right', 'a', 'covariance.k_right must be a number'),
])
def test_track_noise_is_checked_where_it_enters(name, value, message):
    # TrackNoise trusts its values: odometry_node's parameter table checks them, once.
    assert check_values(ODOMETRY_PARAMS, {name: value}) == [f'{message}, got {value!r}']


def test_the_model_is_built_once_at_start(ros_context, monkeypatch):
    # validate builds the kinematic model; the start takes that one into use.
    calls = []

    def counted(values):
        calls.append(values)
        return icr_from_values(values)
    monkeypatch.setattr(odometry_node, 'icr_from_values', counted)
    node = OdometryNode(context=ros_context, parameter_overrides=VEHICLE)
    try:
        assert len(calls) == 1
        assert node.odometry.icr == icr_from_values(calls[0])
        assert node.set_parameters([Parameter('icr.x', value=-0.1)])[0].successful
        assert len(calls) == 2 and node.odometry.icr.x == -0.1
    finally:
        node.destroy_node()
