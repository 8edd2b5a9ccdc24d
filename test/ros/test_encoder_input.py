"""EncoderInput on real topics: the three modes and every kind of bad input."""

import math

from helpers.encoder_stream import Driver, joint_state, LEFT, RIGHT, Stderr
import pytest
from rclpy.node import Node
from std_msgs.msg import Float64, Int32, Int64
from tracked_kinematics.params import ENCODER_INPUT_DEFAULTS, TERRAIN_DEFAULTS
from tracked_kinematics.ros.encoder_input import EncoderInput

pytestmark = pytest.mark.ros

DEFAULTS = {**TERRAIN_DEFAULTS, **ENCODER_INPUT_DEFAULTS}


class Harness:
    """A bare node with an EncoderInput, recording its callbacks, and a driver."""

    def __init__(self, ros_context, executor, capfd, namespace='', **values):
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
        return self.stderr.warnings('encoder_probe', text)


@pytest.fixture
def harness(ros_context, executor, capfd):
    def make(**values):
        return Harness(ros_context, executor, capfd, **values)
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


@pytest.mark.parametrize('t2', [0.9, 1.0])
def test_time_going_back_restarts_from_the_new_message(harness, t2):
    h = harness(sprocket_radius=1.0)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(t2, [5.0, 5.0]))  # sim time reset / bag loop / duplicate
    h.send(joint_state(t2 + 0.1, [5.1, 5.2]))
    assert len(h.steps) == 1 and h.steps[0][1:] == pytest.approx((0.1, 0.2, 0.1))
    assert h.warned('time did not advance')


def test_gap_longer_than_max_dt_is_not_integrated(harness):
    h = harness(sprocket_radius=1.0, max_dt=0.2)
    h.send(joint_state(1.0, [0.0, 0.0]))
    h.send(joint_state(1.5, [3.0, 3.0]))
    h.send(joint_state(1.6, [3.1, 3.1]))
    assert len(h.steps) == 1 and h.steps[0][1:] == pytest.approx((0.1, 0.1, 0.1))
    assert h.input.counts['gap'] == 1 and h.warned('without encoder data')


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
