"""
Property-based fuzzing of odometry_node and icr_estimator, in-process with real rclpy.

Random JointState messages (huge finite values, NaN, inf, int64-range values, time going
back, zero stamps, wrong or missing names) and random parameter sets set at runtime (accepted
ones drawn from the specs' ranges, and absurd ones); after every example the node is alive,
everything it published is finite and within limits, and a clean manoeuvre afterwards is
integrated correctly (issue 14, "Tests"). Seeded and bounded (about 10-20 s each).
"""

import math

from helpers.encoder_stream import Driver, joint_state, LEFT, RIGHT
from helpers.ros_helpers import spin_until
from hypothesis import given, strategies as st
from hypothesis import HealthCheck, seed, settings
from nav_msgs.msg import Odometry as OdometryMsg, Path
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from tracked_kinematics.core.covariance import MAX_VARIANCE, UNOBSERVED_VARIANCE
from tracked_kinematics.ros.icr_estimator import IcrEstimatorNode, PARAMS as ESTIMATOR_PARAMS
from tracked_kinematics.ros.odometry_node import OdometryNode, PARAMS as ODOMETRY_PARAMS

pytestmark = pytest.mark.ros

RADIUS = 0.1
VEHICLE = {'track_width': 0.42, 'sprocket_radius': RADIUS, 'icr.y_left': 0.21,
           'icr.y_right': -0.21, 'icr.x': 0.0, 'scale.left': 1.0, 'scale.right': 1.0}
FUZZ = settings(max_examples=20, deadline=None, derandomize=False, database=None,
                suppress_health_check=list(HealthCheck))

# Readings a careless driver or an attacker sends.
reading = st.one_of(
    st.floats(-10.0, 10.0),
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.sampled_from([1e308, -1e308, 1e100, 3e99, 9.223372036854776e18, -2.0**63, 0.0,
                     math.pi, -math.pi, 5e-324]),
)
stamp_s = st.one_of(st.floats(1.0, 2000.0), st.just(0.0), st.sampled_from([2**31 - 1.0, 1e-9]))
names = st.sampled_from([(LEFT, RIGHT), (RIGHT, LEFT), (LEFT,), ('wheel_a', 'wheel_b'),
                         (LEFT, RIGHT, 'caster'), (LEFT, LEFT, RIGHT), ()])


@st.composite
def joint_states(draw):
    joints = draw(names)
    msg = joint_state(draw(stamp_s), names=joints)
    n = len(joints)
    if draw(st.booleans()):
        msg.position = [draw(reading) for _ in range(draw(st.sampled_from([n, n, n, 1])))]
    if draw(st.booleans()):
        msg.velocity = [draw(reading) for _ in range(draw(st.sampled_from([n, n, 0])))]
    return msg


def value_in_range(spec):
    """Return a strategy of values of ``spec``: mostly within its range, sometimes absurd."""
    if isinstance(spec.default, bool):
        return st.booleans()
    if isinstance(spec.default, int):
        low = -2**63 if spec.low is None else int(spec.low)
        high = 2**63 - 1 if spec.high is None else int(spec.high)
        return st.one_of(st.integers(low, high), st.integers(-2**63, 2**63 - 1))
    if isinstance(spec.default, float):
        low = -1e6 if spec.low is None else spec.low
        high = 1e6 if spec.high is None else spec.high
        return st.one_of(st.floats(low, high), st.sampled_from([5e-324, -1.0, 1e300, 0.0]),
                         st.floats(allow_nan=True, allow_infinity=True))
    return None


def parameter_sets(specs, skip=()):
    """Return a strategy of a few (name, value) pairs of settable numeric/bool parameters."""
    settable = [spec for spec in specs if not spec.read_only and spec.name not in skip
                and value_in_range(spec) is not None]
    pairs = st.sampled_from(settable).flatmap(
        lambda spec: st.tuples(st.just(spec.name), value_in_range(spec)))
    return st.lists(pairs, max_size=4)


def finite(values):
    return all(map(math.isfinite, values))


def check_odometry_message(msg):
    pose, twist = msg.pose.pose, msg.twist.twist
    values = [pose.position.x, pose.position.y, pose.position.z, pose.orientation.x,
              pose.orientation.y, pose.orientation.z, pose.orientation.w, twist.linear.x,
              twist.linear.y, twist.linear.z, twist.angular.x, twist.angular.y, twist.angular.z,
              *msg.pose.covariance, *msg.twist.covariance]
    assert finite(values), msg
    q = pose.orientation
    assert math.isclose(q.z * q.z + q.w * q.w, 1.0, rel_tol=1e-9)
    for flat in (msg.pose.covariance, msg.twist.covariance):
        cov = np.asarray(flat).reshape(6, 6)
        np.testing.assert_array_equal(cov, cov.T)
        assert np.all(np.diag(cov) >= 0.0)
        assert np.all(np.diag(cov)[[0, 1, 5]] <= MAX_VARIANCE)
        assert np.all(np.diag(cov)[[2, 3, 4]] == UNOBSERVED_VARIANCE)


def call_reset(executor, client):
    assert client.wait_for_service(timeout_sec=5.0)
    future = client.call_async(Trigger.Request())
    assert spin_until(executor, future.done)
    assert future.result().success


class Fuzzer:
    """A node under test with a driver that sends it messages and records its outputs."""

    def __init__(self, ros_context, executor, node, taken):
        self.executor = executor
        self.node = node
        executor.add_node(node)
        self.driver = Driver(ros_context, executor, taken)
        self.pub = self.driver.node.create_publisher(JointState, 'joint_states', QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE))
        self.taken = taken
        assert spin_until(executor, lambda: self.pub.get_subscription_count() > 0)

    def send_all(self, msgs):
        """Publish ``msgs`` and spin until the node took them all (or 2 s passed)."""
        before = self.taken()
        for msg in msgs:
            self.pub.publish(msg)
        spin_until(self.executor, lambda: self.taken() >= before + len(msgs), 2.0)

    def set_random(self, pairs):
        for name, value in pairs:
            self.node.set_parameters([Parameter(name, value=value)])  # refused or not

    def restore(self, values):
        result = self.node.set_parameters_atomically(
            [Parameter(name, value=value) for name, value in values.items()])
        assert result.successful, result.reason


def test_odometry_node_fuzz(ros_context, executor):
    node = OdometryNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {**VEHICLE, 'publish_tf': False}.items()])
    fuzzer = Fuzzer(ros_context, executor, node, lambda: node.encoder.received)
    odom = []
    fuzzer.driver.node.create_subscription(OdometryMsg, 'odom', odom.append, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    reset = fuzzer.driver.node.create_client(Trigger, 'odometry_node/reset')
    base = {name: node.params[name] for name in (
        *VEHICLE, 'max_plausible_speed', 'max_dt', 'publish_rate', 'covariance.k_left',
        'covariance.k_right', 'covariance.floor', 'left_joints', 'right_joints')}
    clean_start = [10_000.0]

    @seed(14)
    @FUZZ
    @given(st.lists(st.one_of(joint_states(), parameter_sets(ODOMETRY_PARAMS)), max_size=12))
    def example(events):
        del odom[:]
        for event in events:
            if isinstance(event, list):
                fuzzer.set_random(event)
            else:
                fuzzer.send_all([event])
        spin_until(executor, lambda: False, 0.01)
        for msg in odom:
            check_odometry_message(msg)
        # Afterwards: back to the vehicle, then a clean straight 1 m at 0.5 m/s.
        fuzzer.restore(base)
        t0 = clean_start[0]
        clean_start[0] += 100.0
        t = t0 + np.arange(101) * 0.02
        angle = 0.5 * (t - t0) / RADIUS + 7.0
        fuzzer.send_all([joint_state(t[0], [angle[0], angle[0]])])
        call_reset(executor, reset)
        del odom[:]
        fuzzer.send_all([joint_state(ti, [ai, ai]) for ti, ai in zip(t[1:], angle[1:])])
        end = joint_state(t[-1]).header.stamp
        assert spin_until(executor, lambda: odom and odom[-1].header.stamp == end, 5.0)
        last = odom[-1]
        assert last.pose.pose.position.x == pytest.approx(1.0, abs=1e-6)
        assert last.pose.pose.position.y == pytest.approx(0.0, abs=1e-6)
        assert last.pose.pose.orientation.z == pytest.approx(0.0, abs=1e-6)
        assert last.twist.twist.linear.x == pytest.approx(0.5, abs=1e-6)
        for msg in odom:
            check_odometry_message(msg)

    example()
    executor.remove_node(node)
    node.destroy_node()


def test_icr_estimator_fuzz(ros_context, executor):
    node = IcrEstimatorNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in {**VEHICLE, 'publish_rate': 50.0}.items()])
    fuzzer = Fuzzer(ros_context, executor, node, lambda: node.encoder.received)
    icr, paths = [], []
    fuzzer.driver.node.create_subscription(Float64MultiArray, 'icr_estimate', icr.append, 100)
    fuzzer.driver.node.create_subscription(Path, 'predicted_path', paths.append, 100)
    poses = fuzzer.driver.node.create_publisher(OdometryMsg, 'pose', QoSProfile(
        depth=100, reliability=ReliabilityPolicy.RELIABLE))
    reset = fuzzer.driver.node.create_client(Trigger, 'icr_estimator/reset')
    assert spin_until(executor, lambda: poses.get_subscription_count() > 0)
    base = {name: node.params[name] for name in (
        *VEHICLE, 'max_plausible_speed', 'max_dt', 'publish_rate', 'window', 'min_window',
        'max_window', 'pose_std_xy', 'pose_std_yaw', 'travel_std', 'process_std',
        'initial_std', 'gate_probability', 'max_outliers', 'prediction.horizon',
        'prediction.dt', 'heading_only', 'pose_delay', 'min_coverage', 'adaptive_noise',
        'noise_memory', 'prior_std', 'prior_time', 'fallback', 'fallback_span',
        'fallback_margin')}
    clean_start = [10_000.0]

    def pose(t, x, y, yaw):
        msg = OdometryMsg()
        msg.header.stamp = joint_state(t).header.stamp
        msg.header.frame_id = 'map'
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        msg.pose.pose.orientation.z = math.sin(0.5 * yaw) if math.isfinite(yaw) else yaw
        msg.pose.pose.orientation.w = math.cos(0.5 * yaw) if math.isfinite(yaw) else 1.0
        return msg

    pose_messages = st.builds(pose, stamp_s, reading, reading, reading)

    def check_outputs():
        for msg in icr:
            assert finite(msg.data) and len(msg.data) == 5
        for path in paths:
            for p in path.poses:
                assert finite([p.pose.position.x, p.pose.position.y, p.pose.orientation.z,
                               p.pose.orientation.w])

    @seed(15)
    @FUZZ
    @given(st.lists(st.one_of(joint_states(), pose_messages,
                              parameter_sets(ESTIMATOR_PARAMS, skip=('push_period',))),
                    max_size=12))
    def example(events):
        del icr[:], paths[:]
        for event in events:
            if isinstance(event, list):
                fuzzer.set_random(event)
            elif isinstance(event, JointState):
                fuzzer.send_all([event])
            else:
                poses.publish(event)
                spin_until(executor, lambda: False, 0.002)
        spin_until(executor, lambda: False, 0.05)
        check_outputs()
        # Afterwards: the vehicle again, reset, then a clean straight 1 m with exact poses.
        fuzzer.restore(base)
        call_reset(executor, reset)
        t0 = clean_start[0]
        clean_start[0] += 100.0
        t = t0 + np.arange(101) * 0.02
        angle = 0.5 * (t - t0) / RADIUS
        for k, (ti, ai) in enumerate(zip(t, angle)):
            fuzzer.send_all([joint_state(ti, [ai, ai])])
            if k % 5 == 0:
                poses.publish(pose(ti, 0.5 * (ti - t0), 0.0, 0.0))
                spin_until(executor, lambda: False, 0.002)
        del icr[:], paths[:]

        def at_the_end():
            return (icr and paths and node.encoder.stamp == joint_state(t[-1]).header.stamp
                    and abs(paths[-1].poses[0].pose.position.x - 1.0) < 1e-6)
        assert spin_until(executor, at_the_end, 5.0), paths[-1:] and paths[-1].poses[0]
        check_outputs()
        now = node.estimator.pose_now()
        assert now is not None and now[1] == pytest.approx(1.0, abs=1e-6)
        assert now[2] == pytest.approx(0.0, abs=1e-6)
        y_left, y_right = icr[-1].data[:2]
        assert y_left > y_right

    example()
    executor.remove_node(node)
    node.destroy_node()
