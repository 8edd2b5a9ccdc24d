"""
cmd_vel_translator fuzzed on a real rclpy graph (issue 14): random Twists, random parameters.

One in-process translator receives, example after example, random parameter sets at runtime
(valid, absurd, NaN) and random Twists (huge finite, NaN, inf, subnormal, mixed). Whatever
it accepted, everything it publishes must be finite and within the limits in force and the
vehicle envelope, it must keep publishing, and a clean command afterwards must give the
setpoints of the inverse kinematics of its current parameters.
"""

import math

from geometry_msgs.msg import Twist, TwistStamped
from helpers.ros_helpers import spin_until
from hypothesis import example, given, HealthCheck, seed, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from tracked_kinematics.core.command import (CommandLimiter, setpoint_twist,
                                             TRACK_SPEED_ENVELOPE)
from tracked_kinematics.params import icr_from_values, limits_from_values
from tracked_kinematics.params.node_tables import TRANSLATOR_PARAMS
from tracked_kinematics.ros.cmd_vel_translator import CmdVelTranslator

pytestmark = pytest.mark.ros

TIMEOUT = 5.0
JOINTS = 'fuzz_joint_commands'
BIG = 1.7976931348623157e308
NAMES = [spec.name for spec in TRANSLATOR_PARAMS if not spec.read_only]
REL = 1e-6

absurd = st.sampled_from([BIG, -BIG, 1e300, -1e300, 5e-324, -5e-324, 1e-300, math.nan,
                          math.inf, -math.inf, -1.0, 0.0])
component = st.one_of(st.floats(-3.0, 3.0), absurd,
                      st.floats(allow_nan=True, allow_infinity=True))
planar = st.builds(lambda v_x, w: (v_x, 0.0, 0.0, 0.0, 0.0, w), absurd, absurd)
twists = st.lists(st.one_of(st.tuples(*[component] * 6), planar), min_size=1, max_size=8)
# Issue 14 item 1, verbatim: +-1.797e308 in linear.x and angular.z, two Twists.
ISSUE_TWISTS = [(BIG, 0, 0, 0, 0, BIG), (-BIG, 0, 0, 0, 0, -BIG)]


def limit(low, high):
    """Draw a limit value: none (0, NaN, inf), a sane one, or anything (often refused)."""
    return st.one_of(st.sampled_from([0.0, math.nan, math.inf]), st.floats(low, high), absurd)


def rate_limit(low, high):
    """Draw a rate limit under which the clean manoeuvre ends in a second or two."""
    return st.one_of(st.sampled_from([0.0, math.nan, math.inf]), st.floats(low, high),
                     st.sampled_from([1e300, -1.0, -math.inf]))


def deceleration(low, high):
    """Draw a deceleration limit: a rate limit, or one in DDC's negative convention."""
    return st.one_of(rate_limit(low, high), st.floats(-high, -low))


candidates = {
    'max_track_speed': limit(0.05, 30.0),
    'max_track_accel': rate_limit(20.0, 100.0),
    'max_track_decel': deceleration(20.0, 100.0),
    'linear.x.max_velocity': limit(0.05, 30.0),
    'linear.x.max_acceleration': rate_limit(20.0, 100.0),
    'linear.x.max_deceleration': deceleration(20.0, 100.0),
    'angular.z.max_velocity': limit(0.05, 50.0),
    'angular.z.max_acceleration': rate_limit(100.0, 1000.0),
    'angular.z.max_deceleration': deceleration(100.0, 1000.0),
    'rate': st.one_of(st.floats(20.0, 1000.0), st.sampled_from([0.001, 1e-10, 5e-324, 1e6])),
    'cmd_timeout': st.one_of(st.just(0.0), st.floats(0.2, 2.0), st.sampled_from([1e9, -1.0])),
    'scale.left': st.one_of(st.floats(0.5, 2.0), absurd),
    'scale.right': st.one_of(st.floats(0.5, 2.0), absurd),
    'sprocket_radius': st.one_of(st.floats(0.02, 0.5), absurd),
    'track_width': st.one_of(st.floats(0.2, 1.0), absurd),
    'icr.y_left': st.one_of(st.floats(0.1, 0.8), absurd),
    'icr.y_right': st.one_of(st.floats(-0.8, -0.1), absurd),
    'icr.x': st.one_of(st.floats(-0.2, 0.2), absurd),
}
param_sets = st.dictionaries(st.sampled_from(sorted(candidates)), st.none(), max_size=6).flatmap(
    lambda keys: st.fixed_dictionaries({key: candidates[key] for key in keys}))


class Recorder:
    """What the translator publishes: joint commands (both sides) and ~/cmd_vel_out."""

    def __init__(self, context):
        self.node = Node('fuzz_probe', context=context)
        self.pub = self.node.create_publisher(Twist, 'cmd_vel', 10)
        self.joints, self.out = [], []
        self.node.create_subscription(Float64MultiArray, JOINTS,
                                      lambda m: self.joints.append(tuple(m.data)), 1000)
        self.node.create_subscription(
            TwistStamped, 'cmd_vel_translator/cmd_vel_out',
            lambda m: self.out.append((m.twist.linear.x, m.twist.angular.z)), 1000)

    def send(self, values):
        msg = Twist()
        (msg.linear.x, msg.linear.y, msg.linear.z,
         msg.angular.x, msg.angular.y, msg.angular.z) = map(float, values)
        self.pub.publish(msg)


def current(node):
    return {name: node.get_parameter(name).value for name in NAMES}


def check_published(recorder, values):
    """Every pair received since the last clear: finite, within limits and envelope."""
    icr, limits = icr_from_values(values), limits_from_values(values)
    radius = values['sprocket_radius']
    joints = np.array(recorder.joints, dtype=float).reshape(-1, 2)
    assert np.all(np.isfinite(joints)), joints
    pairs = joints * radius
    max_speed = min(limits.max_track_speed, TRACK_SPEED_ENVELOPE)
    assert np.all(np.abs(pairs) <= max_speed * (1 + REL) + 1e-12), (pairs, limits)
    for left, right in pairs:
        v_x, w = setpoint_twist(left, right, icr)
        assert abs(v_x) <= limits.max_linear_velocity * (1 + REL) + 1e-12, (v_x, limits)
        assert abs(w) <= limits.max_angular_velocity * (1 + REL) + 1e-12, (w, limits)
    out = np.array(recorder.out, dtype=float).reshape(-1, 2)
    assert np.all(np.isfinite(out)), out


@pytest.fixture
def translator(ros_context, executor):
    node = CmdVelTranslator(context=ros_context, parameter_overrides=[
        Parameter('track_width', value=0.42), Parameter('sprocket_radius', value=0.1),
        Parameter('joint_velocity_topic', value=JOINTS)])
    recorder = Recorder(ros_context)
    executor.add_node(node)
    executor.add_node(recorder.node)
    assert spin_until(executor, lambda: recorder.pub.get_subscription_count() > 0
                      and recorder.joints and recorder.out, TIMEOUT)
    yield node, recorder
    for n in (node, recorder.node):
        executor.remove_node(n)
        n.destroy_node()


def test_fuzz_parameters_and_twists(translator, executor):
    node, recorder = translator
    defaults = [Parameter(name, value=value) for name, value in current(node).items()]

    def more(n):
        count = len(recorder.joints)
        return spin_until(executor, lambda: len(recorder.joints) >= count + n, TIMEOUT)

    @seed(20260114)
    @settings(max_examples=15, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(params=param_sets, commands=twists)
    @example(params={'max_track_accel': 1.0}, commands=ISSUE_TWISTS)
    @example(params={'max_track_speed': 1.0}, commands=ISSUE_TWISTS)
    @example(params={}, commands=ISSUE_TWISTS)
    @example(params={'scale.left': 5e-324, 'sprocket_radius': 5e-324}, commands=ISSUE_TWISTS)
    def fuzz(params, commands):
        assert node.set_parameters_atomically(defaults).successful
        for name, value in params.items():
            node.set_parameters([Parameter(name, value=value)])
        values = current(node)
        # What came before the change may still be in flight: wait for the new ones.
        assert more(5), 'the node stopped publishing after a parameter change'
        recorder.joints.clear()
        recorder.out.clear()
        for command in commands:
            recorder.send(command)
            executor.spin_once(timeout_sec=0.005)
        assert more(5), 'the node stopped publishing after the Twists'
        check_published(recorder, values)
        # A clean command gives the inverse kinematics of the current parameters.
        icr, limits = icr_from_values(values), limits_from_values(values)
        left, right = CommandLimiter(icr, limits).target(0.2, 0.1)
        radius = values['sprocket_radius']
        target = pytest.approx((left / radius, right / radius), rel=1e-9, abs=1e-12)
        assert spin_until(executor, lambda: recorder.send((0.2, 0, 0, 0, 0, 0.1))
                          or (recorder.joints and recorder.joints[-1] == target), 2 * TIMEOUT)
        check_published(recorder, values)

    fuzz()
