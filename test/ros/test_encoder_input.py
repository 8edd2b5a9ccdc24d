"""EncoderInput on real topics: the three modes and every kind of bad input."""

import math

from helpers.encoder_stream import Driver, joint_state, LEFT, RIGHT, Stderr
from helpers.ros_helpers import spin_until
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Int32, Int64
from tracked_kinematics.params import ENCODER_INPUT_DEFAULTS, TERRAIN_DEFAULTS
from tracked_kinematics.ros.encoder_input import EncoderInput

pytestmark = pytest.mark.ros

DEFAULTS = {**TERRAIN_DEFAULTS, **ENCODER_INPUT_DEFAULTS}


class Harness:
    """A bare node with an EncoderInput, recording its callbacks, and a driver."""

    def __init__(self, ros_context, executor, capfd, namespace='', **values):
        self.executor = executor
        self.stderr = Stderr(capfd)
        self.node = Node('encoder_probe', namespace=namespace, context=ros_context)
        self.steps = []
        self.input = EncoderInput(self.node, {**DEFAULTS, **values},
                                  lambda *step: self.steps.append(step))
        executor.add_node(self.node)
        self.driver = Driver(ros_context, executor, lambda: self.input.received, namespace)

    def send(self, msg, topic='joint_states'):
        assert self.driver.send(msg, topic)

    def warned(self, text):
        return self.stderr.warnings(self.node.get_logger().name, text)

    def logged(self, level, text):
        return self.stderr.lines(level, self.node.get_logger().name, text)


@pytest.fixture
def harness(ros_context, executor, capfd):
    def make(namespace='', **values):
        return Harness(ros_context, executor, capfd, namespace, **values)
    return make


def test_positions_give_exact_travel_and_stamps(harness):
    h = harness(sprocket_radius=0.1)
    h.send(joint_state(100.0, [1.0, 2.0]))
    h.send(joint_state(100.02, [1.5, 1.0]))
    assert len(h.steps) == 1
    stamp_s, d_left, d_right, dt = h.steps[0]
    assert stamp_s == pytest.approx(100.02, abs=1e-9) and dt == pytest.approx(0.02, abs=1e-12)
    assert (d_left, d_right) == pytest.approx((0.05, -0.1), abs=1e-15)
    assert (h.input.stamp.sec, h.input.stamp.nanosec) == (100, 20_000_000)


def test_several_joints_per_side_are_averaged_in_any_order(harness):
    h = harness(left_joints=['l1', 'l2'], right_joints=['r1', 'r2'], sprocket_radius=0.2)
    names = ['r2', 'l1', 'x', 'r1', 'l2']
    h.send(joint_state(1.0, [0.0, 0.0, 9.0, 0.0, 0.0], names=names))
    h.send(joint_state(1.1, [3.0, 1.0, 7.0, 1.0, 2.0], names=names))
    # left = mean(1, 2) = 1.5 rad, right = mean(1, 3) = 2 rad
    assert h.steps[0][1:3] == pytest.approx((0.3, 0.4))


def test_velocities_when_positions_are_absent_or_nan(harness):
    h = harness(sprocket_radius=0.1)
    h.send(joint_state(1.0, velocity=[1.0, 2.0]))
    h.send(joint_state(1.5, velocity=[3.0, 2.0]))
    assert h.steps[-1][1:] == pytest.approx((0.1, 0.1, 0.5))  # trapezoid: 2 rad/s x 0.5 s
    # A driver that fills positions with NaN: velocities are used instead.
    h.send(joint_state(2.0, position=[math.nan, math.nan], velocity=[3.0, 2.0]))
    assert h.steps[-1][1:] == pytest.approx((0.15, 0.1, 0.5))


def test_nan_reading_is_skipped_and_travel_across_it_kept(harness):
    h = harness(sprocket_radius=1.0)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(1.1, [math.inf, 0.2]))
    h.send(joint_state(1.2, [0.4, 0.4]))
    assert len(h.steps) == 1
    assert h.steps[0][1:] == pytest.approx((0.4, 0.4, 0.2))
    assert h.input.counts['non_finite'] == 1
    assert h.warned('non-finite encoder reading')


def test_each_kind_of_bad_input_is_logged_once_per_period(harness):
    # Throttled per kind: a second non-finite reading within WARN_PERIOD is counted, not
    # logged again; a bad input of another kind right after it still is.
    h = harness(sprocket_radius=1.0)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(1.1, [math.inf, 0.2]))
    h.send(joint_state(1.2, [0.4, math.nan]))
    h.send(joint_state(0.5, [0.5, 0.5]))   # time went back
    assert h.input.counts['non_finite'] == 2 and h.input.counts['time_back'] == 1
    assert len(h.warned('non-finite encoder reading')) == 1
    assert len(h.warned('time did not advance')) == 1


def test_missing_joints_warn_with_names(harness):
    h = harness()
    h.send(joint_state(1.0, [0.0, 0.0], names=['left_wheel', RIGHT]))
    h.send(joint_state(1.1, [0.1, 0.1], names=['left_wheel', RIGHT]))
    assert h.steps == [] and h.input.counts['missing_joints'] == 2
    (line,) = h.warned('lacks the joints')
    assert LEFT in line and 'left_wheel' in line
    # Fixing the parameter at runtime makes the next messages count.
    h.input.configure({**DEFAULTS, 'left_joints': ['left_wheel']})
    h.send(joint_state(1.2, [0.2, 0.2], names=['left_wheel', RIGHT]))
    h.send(joint_state(1.3, [0.3, 0.3], names=['left_wheel', RIGHT]))
    assert len(h.steps) == 1


def test_no_readings_and_zero_stamp_are_skipped(harness):
    h = harness()
    h.send(joint_state(1.0))
    assert h.input.counts['no_readings'] == 1 and h.warned('neither positions nor velocities')
    h.send(joint_state(0.0, [0.0, 0.0]))
    assert h.input.counts['zero_stamp'] == 1 and h.warned('no header.stamp')
    assert h.steps == []


def test_bytes_that_are_no_joint_state_are_skipped_with_a_warning(harness):
    # The input is taken as bytes (JointStateReader): a writer of garbage on the topic (no
    # ROS node does that, a bare DDS one might) costs one warning, not the node.
    h = harness(sprocket_radius=1.0)
    pub = h.driver.publisher(JointState, 'joint_states')
    for _ in range(4):
        pub.publish(b'\x00\x01\x00\x00' + b'\xff' * 40)
        if spin_until(h.executor, lambda: h.input.received > 0, 0.5):
            break
    assert h.input.counts['unreadable'] == 1 and h.warned('no serialised sensor_msgs/JointState')
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(1.1, [0.1, 0.2]))
    assert h.steps[-1][1:] == pytest.approx((0.1, 0.2, 0.1))
    assert (h.input.stamp.sec, h.input.stamp.nanosec) == (1, 100_000_000)


@pytest.mark.parametrize('t2', [0.9, 1.0])
def test_time_going_back_restarts_from_the_new_message(harness, t2):
    h = harness(sprocket_radius=1.0)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(t2, [5.0, 5.0]))  # sim time reset / bag loop / duplicate
    h.send(joint_state(t2 + 0.1, [5.1, 5.2]))
    assert len(h.steps) == 1 and h.steps[0][1:] == pytest.approx((0.1, 0.2, 0.1))
    assert h.warned('time did not advance')


def test_positions_integrate_across_any_gap_with_a_note(harness):
    # Issue 15 item 2: the travel of positions is exact, however long the gap.
    h = harness(sprocket_radius=1.0, max_dt=0.2)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(1.7, [0.7, 0.7]))
    h.send(joint_state(1.8, [0.8, 0.8]))
    assert [step[1:] for step in h.steps] == [pytest.approx((0.7, 0.7, 0.7)),
                                              pytest.approx((0.1, 0.1, 0.1))]
    assert h.input.counts['long_step'] == 1
    (line,) = h.logged('INFO', 'without encoder data')
    assert '0.7 s' in line and 'integrated' in line


def test_velocities_bridge_up_to_max_dt_and_warn_beyond(harness):
    h = harness(sprocket_radius=1.0, max_dt=0.5)
    h.send(joint_state(1.0, velocity=[1.0, 1.0]))
    h.send(joint_state(1.4, velocity=[1.0, 1.0]))   # 0.4 s: bridged
    h.send(joint_state(2.1, velocity=[1.0, 1.0]))   # 0.7 s: unknown travel, restart
    h.send(joint_state(2.2, velocity=[1.0, 1.0]))
    assert [step[1:] for step in h.steps] == [pytest.approx((0.4, 0.4, 0.4)),
                                              pytest.approx((0.1, 0.1, 0.1))]
    assert h.input.counts['gap'] == 1
    (line,) = h.warned('without encoder data')
    assert 'only velocities' in line and 'not integrated' in line


def test_implausible_steps_are_skipped_with_a_warning_naming_them(harness):
    h = harness(sprocket_radius=0.1, max_plausible_speed=5.0)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(1.01, [1e100, 0.0]))
    h.send(joint_state(1.02, [3e99, 0.0]))
    h.send(joint_state(1.03, [0.0, 0.0]))
    h.send(joint_state(1.04, [0.1, 0.1]))
    assert h.input.counts['implausible'] == 2
    assert [step[1:3] for step in h.steps] == [pytest.approx((0.0, 0.0)),
                                               pytest.approx((0.01, 0.01))]
    (line,) = h.warned('implausible encoder input skipped')
    assert '1e+99' in line and 'max_plausible_speed 5 m/s' in line


def test_duplicated_samples_are_ignored_silently(harness):
    h = harness(sprocket_radius=1.0)
    for msg in (joint_state(1.0, [0.0, 0.0]), joint_state(1.1, [0.1, 0.1]),
                joint_state(1.1, [0.1, 0.1]), joint_state(1.2, [0.2, 0.2])):
        h.send(msg)
    assert [step[1] for step in h.steps] == pytest.approx([0.1, 0.1])
    assert h.input.counts['duplicate'] == 1 and not h.warned('did not advance')


def test_wrapped_joint_positions_are_unwrapped(harness):
    # Issue 15 item 3: continuous joints reported in [-pi, pi]; 1 m at r = 0.1 m.
    h = harness(sprocket_radius=0.1)
    truth = np.linspace(0.0, 10.0, 51)
    for i, angle in enumerate(np.angle(np.exp(1j * truth))):
        h.send(joint_state(1.0 + 0.02 * i, [angle, angle]))
    travel = np.sum([step[1:3] for step in h.steps], axis=0)
    np.testing.assert_allclose(travel, [1.0, 1.0], atol=1e-12)


def test_reliable_publishers_get_a_reliable_deep_queue(harness):
    # Issue 15 item 2: no sample a reliable publisher sends is dropped. A burst of 600
    # messages published while nobody spins all arrive. A namespace of its own: publishers of
    # earlier tests that discovery still lists must not make the topic look best effort.
    h = harness(sprocket_radius=0.1, namespace='deep_queue')
    topic, = h.input.inputs
    pub = h.driver.node.create_publisher(JointState, 'joint_states', QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    assert spin_until(h.executor, lambda: topic.reliability == ReliabilityPolicy.RELIABLE
                      and not topic.switching and pub.get_subscription_count() >= 1, 5.0)
    qos = topic.subscription.qos_profile
    assert (qos.reliability, qos.depth) == (ReliabilityPolicy.RELIABLE, 1000)
    turns = []
    drained = topic.subscription.callback
    topic.subscription.callback = lambda data: (turns.append(1), drained(data))
    for i in range(600):
        pub.publish(joint_state(1.0 + 0.001 * i, [0.001 * i, 0.001 * i]))
    assert spin_until(h.executor, lambda: h.input.received >= 600, 10.0)
    assert h.input.received == 600 and len(h.steps) == 599, h.input.counts
    # The backlog is taken in batches (InputTopic's drain), each in one turn of the executor.
    assert len(turns) < 300


class FakeHandle:
    """A subscription handle whose queue holds ``queued``; raises InvalidHandle when empty."""

    def __init__(self, queued, destroyed=False):
        self.queued = list(queued)
        self.destroyed = destroyed

    def __enter__(self):
        from rclpy.exceptions import InvalidHandle
        if self.destroyed and not self.queued:
            raise InvalidHandle('destroyed')

    def __exit__(self, *exc):
        return False

    def take_message(self, msg_type, raw):
        assert raw  # as the joint_states input subscribes
        return (self.queued.pop(0), None) if self.queued else None


@pytest.mark.parametrize('queued, destroyed, passed', [
    ([], False, 1), ([b'2', b'3'], False, 3), ([b'%d' % i for i in range(2, 200)], False, 51),
    ([b'2'], True, 2)])
def test_drain_passes_on_what_waits_in_order_up_to_its_limit(harness, queued, destroyed,
                                                             passed):
    from types import SimpleNamespace
    from tracked_kinematics.ros.encoder_input import DRAIN
    h = harness()
    topic, = h.input.inputs
    seen = []
    topic._callback = seen.append
    handle = FakeHandle(queued, destroyed)
    real, topic._subscription = topic._subscription, SimpleNamespace(handle=handle)
    try:
        topic._drained(b'1')
    finally:
        topic._subscription = real
    assert DRAIN == 50 and seen == [b'%d' % i for i in range(1, passed + 1)]


def test_switching_to_reliable_mid_stream_loses_and_repeats_nothing(harness):
    # The subscription starts best effort (no publisher known yet) and switches to reliable
    # while samples stream in: the old and the new one are merged by stamp.
    import time
    h = harness(sprocket_radius=0.1, namespace='switch')
    topic, = h.input.inputs
    assert topic.reliability == ReliabilityPolicy.BEST_EFFORT
    pub = h.driver.node.create_publisher(JointState, 'joint_states', QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    sent, deadline = 0, time.monotonic() + 20.0
    while time.monotonic() < deadline and (topic.reliability != ReliabilityPolicy.RELIABLE
                                           or topic.switching or sent < 300):
        if pub.get_subscription_count():
            sent += 1
            pub.publish(joint_state(1.0 + 0.001 * sent, [0.001 * sent, 0.001 * sent]))
        h.executor.spin_once(timeout_sec=0.001)
    assert topic.reliability == ReliabilityPolicy.RELIABLE and not topic.switching
    assert spin_until(h.executor, lambda: h.input.received >= sent, 5.0)
    counts = h.input.counts
    assert h.input.received == sent and counts['step'] == sent - 1, counts
    assert counts['duplicate'] == counts['time_back'] == 0


def test_switching_away_from_a_silent_subscription(ros_context, executor, capfd):
    # The node starts reliable for a reliable publisher that then goes; a sensor-data one
    # streams instead. The old subscription never delivers again: the switch must still end.
    import time
    from rclpy.node import Node
    early = Node('early_driver', namespace='away', context=ros_context)
    reliable = early.create_publisher(JointState, 'joint_states', QoSProfile(
        depth=10, reliability=ReliabilityPolicy.RELIABLE))
    h = Harness(ros_context, executor, capfd, 'away', sprocket_radius=0.1)
    topic, = h.input.inputs
    assert spin_until(executor, lambda: topic.reliability == ReliabilityPolicy.RELIABLE
                      and not topic.switching, 5.0)
    early.destroy_publisher(reliable)
    pub = h.driver.node.create_publisher(JointState, 'joint_states', qos_profile_sensor_data)
    sent, deadline = 0, time.monotonic() + 20.0

    def send():
        nonlocal sent
        sent += 1
        pub.publish(joint_state(1.0 + 0.001 * sent, [0.001 * sent, 0.001 * sent]))
        executor.spin_once(timeout_sec=0.001)
    # A sensor-data publisher cannot reach the reliable subscription: until the switch
    # (within about a check period) its samples are lost.
    start = time.monotonic()
    while time.monotonic() < deadline and (topic.reliability != ReliabilityPolicy.BEST_EFFORT
                                           or topic.switching):
        send()
    assert topic.reliability == ReliabilityPolicy.BEST_EFFORT and not topic.switching
    switch_time, before = time.monotonic() - start, h.input.received
    for _ in range(300):
        send()
    assert spin_until(executor, lambda: h.input.received - before >= 0.95 * 300, 5.0)
    assert h.input.counts['time_back'] == 0
    assert switch_time < 3.0
    early.destroy_node()


def test_best_effort_publishers_still_match(harness):
    h = harness(sprocket_radius=0.1)
    topic, = h.input.inputs
    pub = h.driver.node.create_publisher(JointState, 'joint_states', qos_profile_sensor_data)
    assert spin_until(h.executor, lambda: pub.get_subscription_count() >= 1
                      and topic.reliability == ReliabilityPolicy.BEST_EFFORT
                      and not topic.switching, 5.0)
    for i in range(3):
        pub.publish(joint_state(1.0 + 0.01 * i, [0.0, 0.0]))
        spin_until(h.executor, lambda: h.input.received > i, 2.0)
    assert h.input.received >= 2


def test_wrong_message_type_is_named(ros_context, executor, capfd):
    # Fast DDS keeps a topic's type per participant: the wrong publisher is another context.
    import rclpy
    other = rclpy.Context()
    rclpy.init(context=other)
    try:
        h = Harness(ros_context, executor, capfd, namespace='wrong')
        stranger = Node('stranger', namespace='wrong', context=other)
        stranger.create_publisher(Float64, 'joint_states', 10)
        assert spin_until(executor, lambda: h.warned('another message type'), 5.0)
        (line,) = h.warned('another message type')
        assert '/wrong/joint_states' in line and 'std_msgs/msg/Float64' in line
        assert 'sensor_msgs/msg/JointState' in line and '/wrong/stranger' in line
        stranger.destroy_node()
    finally:
        rclpy.try_shutdown(context=other)


def test_a_silent_side_is_named(harness):
    # Issue 14 item 13: one side silent in track_speeds mode gave no odom and no word.
    h = harness(input_mode='track_speeds', namespace='silent')
    for _ in range(3):
        h.send(Float64(data=0.5), 'left_track/speed')
    assert spin_until(h.executor, lambda: h.warned('no message on'), 5.0)
    (line,) = h.warned('no message on')
    assert '/silent/right_track/speed' in line and '/silent/left_track/speed had' in line
    assert 'right encoder' in line and h.steps == []


def test_track_speeds_paired_by_arrival(harness):
    h = harness(input_mode='track_speeds')
    assert h.input.topics == ('/left_track/speed', '/right_track/speed')
    # A pair counts when both sides have arrived; the last value of a side wins.
    for left, right in [(0.5, 0.4), (0.5, 0.6)]:
        h.send(Float64(data=99.0), 'left_track/speed')
        h.send(Float64(data=left), 'left_track/speed')
        h.send(Float64(data=right), 'right_track/speed')
    (stamp_s, d_left, d_right, dt), = h.steps
    assert dt > 0.0
    assert d_left == pytest.approx(0.5 * dt) and d_right == pytest.approx(0.5 * dt)


@pytest.mark.parametrize('ticks_type, msg_type, top', [
    ('int32', Int32, 2**31 - 1), ('int64', Int64, 2**63 - 1)])
def test_tick_counters_wrap(harness, ticks_type, msg_type, top):
    # One namespace per message type: Fast DDS keeps a topic's first type for the process.
    h = harness(input_mode='encoder_ticks', ticks_type=ticks_type, ticks_per_revolution=1000.0,
                sprocket_radius=0.1, namespace=ticks_type)
    for left, right in [(top - 10, 0), (-top - 1 + 9, -20)]:  # left wraps forward by 20
        h.send(msg_type(data=left), 'left_track/ticks')
        h.send(msg_type(data=right), 'right_track/ticks')
    per_tick = 2 * math.pi * 0.1 / 1000
    assert h.steps[0][1:3] == pytest.approx((20 * per_tick, -20 * per_tick))
