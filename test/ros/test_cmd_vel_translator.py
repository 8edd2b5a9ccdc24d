"""cmd_vel_translator on a real rclpy graph (issues 5, 14 and 15), but the launch file."""

import math
import threading
import time

from geometry_msgs.msg import Twist, TwistStamped
from helpers.ros_helpers import ConsoleScript, spin_until
import numpy as np
import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64, Float64MultiArray, String
from tracked_kinematics.core.command import (CommandLimiter, setpoint_twist, track_setpoints,
                                             TRACK_SPEED_ENVELOPE)
from tracked_kinematics.core.kinematics import forward, true_speeds
from tracked_kinematics.params import icr_from_values, limits_from_values, read_params_file
from tracked_kinematics.ros.cmd_vel_translator import CmdVelTranslator
from tracked_kinematics.ros.parameters import ParameterError
from tracked_kinematics.share import config_file

pytestmark = pytest.mark.ros

AURIGA_FILE = config_file('auriga_alpha_hard_floor.yaml')
AURIGA_VALUES = read_params_file(AURIGA_FILE)
AURIGA = icr_from_values(AURIGA_VALUES)
TIMEOUT = 5.0  # s, deadline of every wait on the graph
# The vehicle every node must be given (issue 15: no default vehicle); ICRs ideal.
VEHICLE = {'track_width': 0.42, 'sprocket_radius': 0.1}
VEHICLE_PARAMS = [Parameter(name, value=value) for name, value in VEHICLE.items()]
IDEAL = icr_from_values(VEHICLE)
# The same vehicle on a console script's command line (later -p of a name override these).
VEHICLE_ARGS = [a for name, value in VEHICLE.items() for a in ('-p', f'{name}:={value}')]
JOINTS = 'probe_joint_commands'
DEPTH = 1000  # the probe never drops a message, however late it spins
BIG = 1.7976931348623157e308


class Probe:
    """
    The rest of the graph: a cmd_vel publisher and recorders of what the node publishes.

    Setpoint *pairs* come from the joint command message, which carries both sides: the
    two Float64 topics are matched by discovery at different moments, so pairing their
    messages by index can pair the left of one publish with the right of another (that
    was the flake of the ramp test). ``left`` and ``right`` record the Float64 topics.
    """

    def __init__(self, context, stamped=False, radius=0.1, cmd_context=None):
        self.node = Node('translator_probe', context=context)
        self.cmd_node = (self.node if cmd_context is None
                         else Node('translator_cmd_probe', context=cmd_context))
        self.stamped = stamped
        self.radius = radius
        self.pub = self.cmd_node.create_publisher(TwistStamped if stamped else Twist,
                                                  'cmd_vel', 10)
        self.left, self.right, self.joints, self.out = [], [], [], []
        self.node.create_subscription(Float64, 'left_track/setpoint',
                                      lambda m: self.left.append(m.data), DEPTH)
        self.node.create_subscription(Float64, 'right_track/setpoint',
                                      lambda m: self.right.append(m.data), DEPTH)
        self.node.create_subscription(Float64MultiArray, JOINTS,
                                      lambda m: self.joints.append(tuple(m.data)), DEPTH)
        self.node.create_subscription(TwistStamped, 'cmd_vel_translator/cmd_vel_out',
                                      self.out.append, DEPTH)

    def send(self, v_x, w, v_y=0.0, stamp_ns=0):
        twist = Twist()
        twist.linear.x, twist.linear.y, twist.angular.z = float(v_x), float(v_y), float(w)
        if self.stamped:
            msg = TwistStamped(twist=twist)
            msg.header.frame_id = 'base_link'
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
            self.pub.publish(msg)
        else:
            self.pub.publish(twist)

    def setpoints(self):
        """Return the (left, right) setpoint pairs received so far, one row per publish."""
        return np.array(self.joints, dtype=float).reshape(-1, 2) * self.radius

    def latest(self):
        """Return the last (left, right) pair, or None."""
        return tuple(self.setpoints()[-1]) if self.joints else None

    def clear(self):
        del self.left[:], self.right[:], self.joints[:], self.out[:]

    def destroy(self):
        if self.cmd_node is not self.node:
            self.cmd_node.destroy_node()
        self.node.destroy_node()


@pytest.fixture
def graph(ros_context, executor):
    """Build a translator with parameter overrides and a probe, both on the executor."""
    made = []

    def make(probe_context=None, wait=True, **params):
        params.setdefault('joint_velocity_topic', JOINTS)
        overrides = [Parameter(name, value=value)
                     for name, value in {**VEHICLE, **params}.items()]
        node = CmdVelTranslator(context=ros_context, parameter_overrides=overrides)
        probe = Probe(ros_context, stamped=params.get('use_stamped', False),
                      radius=params.get('sprocket_radius', 0.1), cmd_context=probe_context)
        made.extend([node, probe])
        executor.add_node(node)
        executor.add_node(probe.node)
        if wait:
            assert spin_until(executor, lambda: probe.pub.get_subscription_count() > 0
                              and probe.latest() is not None, TIMEOUT)
        return node, probe

    yield make
    for thing in made:
        if isinstance(thing, Probe):
            executor.remove_node(thing.node)
            thing.destroy()
        else:
            executor.remove_node(thing)
            thing.destroy_node()


@pytest.fixture
def other_context():
    """Give a second context: another DDS participant, free to use other types on cmd_vel."""
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


def drive(executor, probe, v_x, w, until, v_y=0.0, **send):
    """Send a command every spin until ``until(probe)`` holds; return whether it did."""
    def condition():
        probe.send(v_x, w, v_y, **send)
        return until(probe)
    return spin_until(executor, condition, TIMEOUT)


def reaches(target, rel=1e-9):
    """Return a condition: the last setpoints are ``target``."""
    def condition(probe):
        last = probe.latest()
        return last is not None and last == pytest.approx(tuple(target), rel=rel, abs=1e-12)
    return condition


def new_messages(probe, n):
    """Return a condition: ``n`` more setpoint pairs than now."""
    count = len(probe.joints)
    return lambda: len(probe.joints) >= count + n


def twist_of(pairs, icr):
    """Return (v_x, w) arrays that nominal setpoint pairs give through the odometry model."""
    v_x, _, w = forward(*true_speeds(pairs[:, 0], pairs[:, 1], icr), icr)
    return v_x, w


def assert_sane(pairs, max_speed=TRACK_SPEED_ENVELOPE):
    assert np.all(np.isfinite(pairs)), pairs
    assert np.all(np.abs(pairs) <= max_speed * (1 + 1e-9)), np.max(np.abs(pairs))


# Issue 5: the command path ----------------------------------------------------------------


def test_round_trip_at_rest_then_commanded(graph, executor):
    node, probe = graph(**AURIGA_VALUES, rate=100.0)
    assert probe.latest() == (0.0, 0.0)  # before any command: stopped
    # Nav2-like command: 0.5 m/s on an arc of 0.3 rad/s.
    target = track_setpoints(0.5, 0.3, AURIGA)
    assert drive(executor, probe, 0.5, 0.3, reaches(target))
    # Fed through the odometry model (same terrain, scales applied to the nominal
    # setpoints) the setpoints reproduce the commanded v_x and w.
    v_x, w = twist_of(probe.setpoints()[-1:], AURIGA)
    assert v_x[0] == pytest.approx(0.5) and w[0] == pytest.approx(0.3)
    # The Float64 topics carry the same numbers.
    assert spin_until(executor, lambda: probe.left and probe.right
                      and (probe.left[-1], probe.right[-1]) == pytest.approx(target), TIMEOUT)
    # A fixed rate, whether commands come or not.
    probe.clear()
    start = node.get_clock().now().nanoseconds
    assert spin_until(executor, lambda: len(probe.setpoints()) >= 20, TIMEOUT)
    elapsed = (node.get_clock().now().nanoseconds - start) * 1e-9
    assert 19 / 100.0 * 0.7 < elapsed < 21 / 100.0 * 3.0  # not faster; slower only if starved


def test_timeout_ramps_to_zero(graph, executor):
    accel, rate = 2.0, 100.0
    # A timeout longer than a spin of a loaded machine, so the ramp up is never cut.
    _, probe = graph(cmd_timeout=0.5, max_track_accel=accel, rate=rate)
    assert drive(executor, probe, 0.4, 0.0, reaches((0.4, 0.4)))
    probe.clear()
    # No more commands: after cmd_timeout the setpoints fall at max_track_accel to zero.
    assert spin_until(executor, lambda: probe.latest() == (0.0, 0.0), TIMEOUT)
    left = probe.setpoints()[:, 0]
    assert left[0] == pytest.approx(0.4)
    steps = np.diff(left)
    assert np.all(steps <= 0.0)
    assert np.all(-steps <= accel * 2.0 / rate + 1e-9)  # at most two periods' worth
    assert np.count_nonzero(steps) >= 0.4 / (accel * 2.0 / rate)  # a ramp, not a step


def test_saturation_keeps_curvature(graph, executor):
    _, probe = graph(**AURIGA_VALUES, max_track_speed=0.5)
    # 1 m/s with 1 rad/s would need 1.43 m/s on the right track.
    target = np.array(track_setpoints(1.0, 1.0, AURIGA))
    expected = target * 0.5 / np.max(np.abs(target))
    assert drive(executor, probe, 1.0, 1.0, reaches(expected))
    pair = probe.setpoints()[-1:]
    assert np.max(np.abs(pair)) == pytest.approx(0.5)
    v_x, w = twist_of(pair, AURIGA)
    assert w[0] / v_x[0] == pytest.approx(1.0)  # same curvature as commanded, slower


# Known flake under a full-suite load: the twist case misses its exact target about once in
# a few full runs, never alone (cause not found yet). Rerun from scratch, fixtures included;
# every assertion holds on the run that passes.
@pytest.mark.parametrize('params', [
    {'max_track_accel': 1.0},
    {'linear.x.max_acceleration': 0.5, 'angular.z.max_acceleration': 1.0},
], ids=['track', 'twist'])
def test_acceleration_ramp_keeps_curvature(graph, executor, params):
    rate = 50.0
    # cmd_timeout long: a stall of this test process under load must not make the command
    # stale mid-ramp (the ramp would turn back down and look non-monotone).
    _, probe = graph(**AURIGA_VALUES, rate=rate, cmd_timeout=10.0, **params)
    probe.clear()
    target = track_setpoints(0.3, 0.4, AURIGA)
    assert drive(executor, probe, 0.3, 0.4, reaches(target))
    pairs = probe.setpoints()
    pairs = pairs[np.any(pairs != 0.0, axis=1)]
    assert len(pairs) >= 5  # ramped over several periods
    assert np.all(np.diff(pairs, axis=0) * np.sign(target) >= -1e-12)  # monotone
    v_x, w = twist_of(pairs, AURIGA)
    np.testing.assert_allclose(w / v_x, 0.4 / 0.3, rtol=1e-9)  # on the commanded arc
    period_max = 2.0 / rate  # the node ramps over at most two periods per publish
    if 'max_track_accel' in params:
        assert np.max(np.abs(np.diff(pairs, axis=0))) <= 1.0 * period_max + 1e-9
    else:
        assert np.max(np.abs(np.diff(v_x))) <= 0.5 * period_max + 1e-9
        assert np.max(np.abs(np.diff(w))) <= 1.0 * period_max + 1e-9


def test_twist_velocity_limits_keep_curvature(graph, executor):
    _, probe = graph(**{'linear.x.max_velocity': 0.2, 'angular.z.max_velocity': 0.5})
    # (1.0, 0.5) scaled by 0.2 to meet the linear limit: (0.2, 0.1).
    assert drive(executor, probe, 1.0, 0.5, reaches((0.2 - 0.21 * 0.1, 0.2 + 0.21 * 0.1)))
    # (0.1, 2.0) scaled by 0.25 to meet the angular limit: (0.025, 0.5).
    assert drive(executor, probe, 0.1, 2.0, reaches((0.025 - 0.21 * 0.5, 0.025 + 0.21 * 0.5)))


def test_non_finite_commands_dropped_with_throttled_warning(graph, executor, capfd):
    _, probe = graph(cmd_timeout=1.0)
    target = track_setpoints(0.3, 0.1, IDEAL)
    assert drive(executor, probe, 0.3, 0.1, reaches(target))
    probe.clear()
    bad = [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, -math.inf)] * 10
    for v_x, w, v_y in bad:
        probe.send(v_x, w, v_y)
        executor.spin_once(timeout_sec=0.01)
    # The last good command holds (until the timeout) and nothing non-finite goes out.
    assert spin_until(executor, lambda: len(probe.setpoints()) >= 10, TIMEOUT)
    pairs = probe.setpoints()
    assert np.all(np.isfinite(pairs))
    np.testing.assert_allclose(pairs[:5], [target] * 5)
    warnings = capfd.readouterr().err.count('dropped a non-finite cmd_vel')
    assert 1 <= warnings <= 2  # 30 bad messages in well under 2 s, throttled to 1 per s


def test_lateral_velocity_ignored_with_one_note(graph, executor, capfd):
    _, probe = graph()
    target = track_setpoints(0.2, 0.0, IDEAL)
    assert drive(executor, probe, 0.2, 0.0, reaches(target), v_y=0.3)
    for _ in range(5):
        probe.send(0.2, 0.0, 0.3)
        executor.spin_once(timeout_sec=0.01)
    assert probe.latest() == pytest.approx(target)
    assert capfd.readouterr().err.count('linear.y is ignored') == 1


def test_joint_velocities_in_rad_per_s(graph, executor):
    _, probe = graph(**{**AURIGA_VALUES, 'sprocket_radius': 0.05})
    target = track_setpoints(0.5, 0.3, AURIGA)
    assert drive(executor, probe, 0.5, 0.3, lambda p: p.joints and p.joints[-1]
                 == pytest.approx((target[0] / 0.05, target[1] / 0.05)))


def test_invalid_parameters_refused_at_start(ros_context):
    for name, value, match in [('max_track_speed', -1.0, 'max_track_speed must be >= 0'),
                               ('icr.y_left', 0.1, 'chi'),
                               ('joint_velocity_topic', 'bad topic', 'valid ROS name')]:
        with pytest.raises(ParameterError, match=match):
            CmdVelTranslator(context=ros_context,
                             parameter_overrides=VEHICLE_PARAMS + [
                                 Parameter(name, value=value)])


def test_runtime_parameters_validated_and_applied(graph, executor):
    node, probe = graph(**AURIGA_VALUES)
    for name, value, reason in [
            ('max_track_speed', -0.5, 'max_track_speed must be >= 0'),
            ('max_track_speed', 31.0, 'max_track_speed must be in [0, 30] m/s'),
            ('angular.z.max_acceleration', -math.inf, 'must be >= 0'),
            ('cmd_timeout', -0.1, 'cmd_timeout'),
            ('icr.y_left', -0.01, 'chi'),
            ('icr.y_left', -0.5, 'icr.y_left'),
            ('scale.right', 0.0, 'scale.right')]:
        result = node.set_parameters([Parameter(name, value=value)])[0]
        assert not result.successful and reason in result.reason, (name, result.reason)
    assert node.get_parameter('max_track_speed').value == 0.0
    target = track_setpoints(1.0, 0.0, AURIGA)
    assert drive(executor, probe, 1.0, 0.0, reaches(target))
    # A valid change applies to the next setpoints; 0, .inf and .NAN all mean no limit.
    assert node.set_parameters([Parameter('max_track_speed', value=0.5)])[0].successful
    assert drive(executor, probe, 1.0, 0.0, reaches(np.array(target) * 0.5 / max(target)))
    for none in (math.inf, math.nan, 0.0):
        assert node.set_parameters([Parameter('max_track_speed', value=none)])[0].successful
        assert drive(executor, probe, 1.0, 0.0, reaches(target))
    # A new rate takes effect.
    assert node.set_parameters([Parameter('rate', value=200.0)])[0].successful
    probe.clear()
    start = node.get_clock().now().nanoseconds
    assert spin_until(executor, lambda: len(probe.setpoints()) >= 40, TIMEOUT)
    # 0.2 s at 200 Hz; 0.8 s at the old 50 Hz.
    assert (node.get_clock().now().nanoseconds - start) * 1e-9 < 40 / 200.0 * 3.0


def drive_console_script(ros_context, executor, tmp_path, node_params, v_x, w):
    """
    Run the console script on the Auriga terrain file and a second params file.

    Drive it until its setpoints are those of the command (v_x, w) through the terrain's
    model, stop it (exit status 0) and return its output.
    """
    probe = Probe(ros_context)
    executor.add_node(probe.node)
    try:
        with ConsoleScript('cmd_vel_translator', '--ros-args', '--params-file', AURIGA_FILE,
                           '--params-file', node_params, tmp_path=tmp_path) as script:
            assert spin_until(executor, lambda: probe.pub.get_subscription_count() > 0
                              and probe.latest() is not None, 15.0), script.output
            target = track_setpoints(v_x, w, AURIGA)
            assert drive(executor, probe, v_x, w, reaches(target)), script.output
            assert script.stop() == 0
    finally:
        probe.destroy()
    return script.output


def test_console_script_with_terrain_params_file(ros_context, executor, tmp_path):
    # One terrain file configures both nodes; node parameters come in a second file.
    extra = tmp_path / 'translator.yaml'
    extra.write_text('cmd_vel_translator:\n  ros__parameters:\n    rate: 100.0\n'
                     f'    max_track_speed: 2.0\n    joint_velocity_topic: {JOINTS}\n')
    output = drive_console_script(ros_context, executor, tmp_path, extra, 0.4, -0.5)
    assert 'chi = 0.540' in output and 'max_track_speed 2' in output
    assert 'Traceback' not in output


@pytest.mark.parametrize('args, reason', [
    (['-p', 'max_track_accel:=-2.0'], 'max_track_accel must be >= 0'),
    (['-p', 'icr.y_right:=0.5'], 'icr.y_left'),
    (['-p', 'rate:=0.0'], 'rate'),
    (['-p', 'rate:=0.001'], 'rate'),
    (['-p', 'scale.left:=1.0e-300'], 'scale.left'),
    (['-p', 'sprocket_radius:=1.0e-300'], 'sprocket_radius'),
    (['-p', 'use_stamped:=true', '-p', 'cmd_vel_type:=twist'], 'contradicts'),
])
def test_console_script_exits_2_on_invalid_parameters(tmp_path, args, reason):
    with ConsoleScript('cmd_vel_translator', '--ros-args', *VEHICLE_ARGS, *args,
                       tmp_path=tmp_path) as script:
        assert script.wait(30.0) == 2
    fatal = [line for line in script.output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1 and reason in fatal[0], script.output


def test_simulated_time_paused_holds_setpoints(graph, executor):
    from rosgraph_msgs.msg import Clock
    # (Within clock_stall_timeout of steady time: longer, a clock that stands still is a
    # fault, test_frozen_clock_is_a_fault_ramped_on_steady_time.)
    _, probe = graph(use_sim_time=True, cmd_timeout=0.1, clock_stall_timeout=30.0)
    clock = probe.node.create_publisher(Clock, '/clock', 10)

    def tick(seconds):
        msg = Clock()
        msg.clock.sec = seconds
        clock.publish(msg)

    tick(100)
    target = track_setpoints(0.3, 0.0, IDEAL)
    assert drive(executor, probe, 0.3, 0.0, reaches(target))
    # The simulation is paused: however long it stays so in wall time, the command is not
    # stale (15 publishes = 0.3 s of wall time = 3 timeouts).
    probe.clear()
    assert spin_until(executor, lambda: len(probe.setpoints()) >= 15, TIMEOUT)
    assert probe.latest() == pytest.approx(target)
    # Simulated time moves on by more than cmd_timeout: stop.
    assert spin_until(executor, lambda: tick(101) or probe.latest() == (0.0, 0.0), TIMEOUT)


def test_publisher_thread_ends_with_node_and_context(ros_context, executor):
    def publisher_threads():
        return [t for t in threading.enumerate() if t.name == 'setpoint_publisher']

    node = CmdVelTranslator(context=ros_context, parameter_overrides=VEHICLE_PARAMS)
    assert len(publisher_threads()) == 1
    node.destroy_node()
    assert publisher_threads() == []
    CmdVelTranslator(context=ros_context, parameter_overrides=VEHICLE_PARAMS)
    ros_context.try_shutdown()  # e.g. Ctrl-C: the thread stops without destroy_node
    thread, = publisher_threads() or [None]
    if thread is not None:
        thread.join(TIMEOUT)
    assert publisher_threads() == []


# Issue 14 items 1-3: nothing non-finite or out of the envelope, no accepted value kills --


@pytest.mark.parametrize('limits', [
    {'max_track_accel': 1.0}, {'max_track_speed': 1.0}, {},
    {'linear.x.max_acceleration': 2.0, 'angular.z.max_acceleration': 4.0},
], ids=['max_track_accel', 'max_track_speed', 'none', 'twist_accel'])
def test_huge_twists_never_publish_nan(graph, executor, capfd, limits):
    # Item 1: two finite Twists of +-1.797e308 latched NaN setpoints (inf without limits).
    _, probe = graph(**AURIGA_VALUES, cmd_timeout=0.5, **limits)
    probe.clear()
    for sign in (1.0, -1.0):
        probe.send(sign * BIG, sign * BIG)
        executor.spin_once(timeout_sec=0.01)
    assert spin_until(executor, new_messages(probe, 15), TIMEOUT)
    assert_sane(probe.setpoints(), limits.get('max_track_speed', TRACK_SPEED_ENVELOPE))
    assert 'beyond the vehicle envelope' in capfd.readouterr().err
    # Stale: a stop, then a clean command gives its setpoints (no latch).
    assert spin_until(executor, lambda: probe.latest() == (0.0, 0.0), 2 * TIMEOUT)
    target = track_setpoints(0.3, 0.2, AURIGA)
    assert drive(executor, probe, 0.3, 0.2, reaches(target))
    assert_sane(probe.setpoints())
    assert all(map(math.isfinite, probe.left + probe.right))


@pytest.mark.parametrize('name, value', [
    ('scale.left', 5e-324), ('scale.left', 1e-300), ('scale.right', 1e300),
    ('sprocket_radius', 5e-324), ('sprocket_radius', 100.0),
    ('rate', 0.001), ('rate', 1e-10), ('rate', 1e6), ('cmd_timeout', 1e9),
    ('linear.x.max_velocity', 1e300), ('angular.z.max_deceleration', -1e300),
])
def test_absurd_values_refused_at_start_and_at_runtime(graph, ros_context, name, value):
    # Item 2 and 3: accepted values gave inf setpoints or killed the publisher.
    with pytest.raises(ParameterError, match=name):
        CmdVelTranslator(context=ros_context,
                         parameter_overrides=VEHICLE_PARAMS + [Parameter(name, value=value)])
    node, _ = graph()
    old = node.get_parameter(name).value
    result = node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful and name in result.reason
    assert node.get_parameter(name).value == old


def test_ranges_are_published(ros_context):
    node = CmdVelTranslator(context=ros_context, parameter_overrides=VEHICLE_PARAMS)
    rate = node.describe_parameter('rate').floating_point_range[0]
    assert (rate.from_value, rate.to_value) == (1.0, 1000.0)
    timeout = node.describe_parameter('cmd_timeout').floating_point_range[0]
    assert (timeout.from_value, timeout.to_value) == (0.0, 60.0)
    scale = node.describe_parameter('scale.left').floating_point_range[0]
    assert (scale.from_value, scale.to_value) == (0.1, 10.0)
    # Limits: their "no limit" values NaN and inf lie outside any range, so the range is
    # stated as an additional constraint (and checked by the node).
    speed = node.describe_parameter('max_track_speed')
    assert not speed.floating_point_range
    assert speed.additional_constraints.startswith('[0, 30] m/s')
    decel = node.describe_parameter('linear.x.max_deceleration')
    assert decel.additional_constraints.startswith('[-100, 100] m/s^2')
    node.destroy_node()


def test_rate_change_takes_effect_at_once(graph, executor):
    # Item 3: setting 50 Hz after 1 Hz slept out the old 1 s period first.
    node, probe = graph(rate=1.0)
    assert spin_until(executor, new_messages(probe, 1), TIMEOUT)  # just published: 1 s to go
    changed = time.monotonic()
    assert node.set_parameters([Parameter('rate', value=50.0)])[0].successful
    assert spin_until(executor, new_messages(probe, 5), TIMEOUT)
    assert time.monotonic() - changed < 0.8  # five at 50 Hz: 0.1 s; after the old 1 s: > 1 s


def test_rate_from_params_file_at_start(tmp_path, ros_context, executor):
    params = tmp_path / 'rate.yaml'
    params.write_text('/**:\n  ros__parameters:\n    rate: 1.0e-10\n')
    with ConsoleScript('cmd_vel_translator', '--ros-args', *VEHICLE_ARGS, '--params-file',
                       params, tmp_path=tmp_path) as script:
        assert script.wait(30.0) == 2
    assert 'rate' in next(line for line in script.output.splitlines() if 'FATAL' in line)
    params.write_text(f'/**:\n  ros__parameters:\n    rate: 200.0\n'
                      f'    joint_velocity_topic: {JOINTS}\n')
    probe = Probe(ros_context)
    executor.add_node(probe.node)
    with ConsoleScript('cmd_vel_translator', '--ros-args', *VEHICLE_ARGS, '--params-file',
                       params, tmp_path=tmp_path) as script:
        assert spin_until(executor, lambda: len(probe.joints) >= 2, 15.0), script.output
        count, start = len(probe.joints), time.monotonic()
        assert spin_until(executor, lambda: len(probe.joints) >= count + 40, TIMEOUT)
        assert time.monotonic() - start < 40 / 200.0 * 3.0
    probe.destroy()


def zeros_from_now_on(executor, probe):
    """Wait for the first zero pair and three more; return the pairs from that one on."""
    def first_zero():
        return next((k for k, pair in enumerate(probe.joints) if pair == (0.0, 0.0)), None)
    assert spin_until(executor, lambda: first_zero() is not None, TIMEOUT)
    start = first_zero()  # in order: everything from here was published after the fault
    assert spin_until(executor, lambda: len(probe.joints) >= start + 4, TIMEOUT)
    return probe.setpoints()[start:]


def test_output_guard_publishes_zero_and_says_why(graph, executor, capfd):
    node, probe = graph(**AURIGA_VALUES, **{'max_track_speed': 1.0})
    real_update = node._limiter.update
    target = track_setpoints(0.3, 0.0, AURIGA)
    for bad in [(math.nan, 0.1), (0.2, math.inf), (1.5, 0.0), (31.0, 31.0)]:
        node._limiter.update = real_update
        assert drive(executor, probe, 0.3, 0.0, reaches(target))
        probe.clear()
        node._limiter.update = lambda t, max_dt=math.inf, steady=None, bad=bad: bad
        assert np.all(zeros_from_now_on(executor, probe) == 0.0), bad
    node._limiter.update = real_update
    assert drive(executor, probe, 0.3, 0.0, reaches(target))
    err = capfd.readouterr().err
    assert 'output guard: setpoints nan, 0.1 not published (non-finite setpoints' in err
    assert 1 <= err.count('output guard') <= 4  # throttled to one a second


def test_an_error_in_the_publisher_is_logged_and_it_keeps_publishing(graph, executor, capfd):
    node, probe = graph()
    real_update = node._limiter.update

    def broken(t, max_dt=math.inf, steady=None):
        raise RuntimeError('injected fault')

    assert drive(executor, probe, 0.3, 0.0, reaches(track_setpoints(0.3, 0.0, IDEAL)))
    probe.clear()
    node._limiter.update = broken
    assert np.all(zeros_from_now_on(executor, probe) == 0.0)  # still publishing: zero
    assert 'injected fault' in capfd.readouterr().err
    node._limiter.update = real_update
    assert drive(executor, probe, 0.3, 0.0, reaches(track_setpoints(0.3, 0.0, IDEAL)))


def test_publishing_that_keeps_failing_stops_the_node(other_context, capfd):
    node = CmdVelTranslator(context=other_context, parameter_overrides=VEHICLE_PARAMS)

    def broken(msg):
        raise RuntimeError('injected publish fault')

    node._left_pub.publish = broken
    deadline = time.monotonic() + TIMEOUT
    while other_context.ok() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not other_context.ok() and isinstance(node.failure, RuntimeError)
    assert 'stopping the node' in capfd.readouterr().err
    node.destroy_node()


# Issue 14 items 7 and 13: clean signals, a wrong type on cmd_vel --------------------------


def stderr_until(executor, capfd, text):
    """Spin until ``text`` is on stderr or TIMEOUT passes; return the stderr read meanwhile."""
    err = ''
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline and text not in err:
        executor.spin_once(timeout_sec=0.05)
        err += capfd.readouterr().err
    return err


def test_wrong_message_type_on_cmd_vel_is_named(graph, executor, other_context, capfd):
    _, probe = graph()
    stranger = Node('string_talker', context=other_context)
    stranger.create_publisher(String, 'cmd_vel', 10)
    # The graph is looked at twice a second; the warning names topic, type and publisher.
    err = stderr_until(executor, capfd, 'std_msgs/msg/String')
    line = next(line for line in err.splitlines() if 'std_msgs/msg/String' in line)
    assert '/cmd_vel' in line and '/string_talker' in line and 'TwistStamped' in line
    stranger.destroy_node()


# Issue 15 items 4 and 5: Twist and TwistStamped, stamps, timeout 0, decelerations --------


def test_follows_the_type_of_the_publishers(executor, other_context, capfd):
    # A translator that has seen no publisher subscribes Twist; a TwistStamped publisher
    # (Jazzy's DDC type) appears in another process: the node switches, says so, drives.
    node = CmdVelTranslator(context=executor.context, parameter_overrides=VEHICLE_PARAMS + [
        Parameter('joint_velocity_topic', value=JOINTS)])
    executor.add_node(node)
    recorder = Probe(executor.context, cmd_context=other_context, stamped=True)
    executor.add_node(recorder.node)
    try:
        target = track_setpoints(0.25, -0.2, IDEAL)
        assert drive(executor, recorder, 0.25, -0.2, reaches(target))
        assert 'subscribed as such (was geometry_msgs/msg/Twist)' in capfd.readouterr().err
        # Back to Twist when only Twist publishers remain.
        recorder.cmd_node.destroy_publisher(recorder.pub)
        recorder.pub = recorder.cmd_node.create_publisher(Twist, 'cmd_vel', 10)
        recorder.stamped = False
        target = track_setpoints(0.1, 0.3, IDEAL)
        assert drive(executor, recorder, 0.1, 0.3, reaches(target))
        assert 'geometry_msgs/msg/Twist: subscribed as such' in capfd.readouterr().err
    finally:
        executor.remove_node(recorder.node)
        recorder.destroy()
        executor.remove_node(node)
        node.destroy_node()


def test_forced_type_warns_about_the_other(graph, executor, other_context, capfd):
    _, probe = graph(probe_context=other_context, use_stamped=True)
    third = rclpy.Context()  # a third participant: other_context has a TwistStamped writer
    rclpy.init(context=third)
    talker = Node('twist_talker', context=third)
    talker.create_publisher(Twist, 'cmd_vel', 10)
    err = stderr_until(executor, capfd, 'twist_talker')
    assert 'is geometry_msgs/msg/TwistStamped (cmd_vel_type / use_stamped)' in err
    assert 'their commands are not received' in err
    talker.destroy_node()
    rclpy.try_shutdown(context=third)


def test_stamped_commands_stale_by_their_stamp(graph, executor, capfd):
    node, probe = graph(use_stamped=True, cmd_timeout=0.5)
    target = track_setpoints(0.25, -0.2, IDEAL)
    # A zero stamp counts as "now" (as in DDC): the vehicle moves.
    assert drive(executor, probe, 0.25, -0.2, reaches(target))
    assert 'zero stamp' in capfd.readouterr().err
    # Stamped 1 s ago with cmd_timeout 0.5 s: stale on arrival, the vehicle stops, and a
    # warning says why.

    def old():
        return node.get_clock().now().nanoseconds - 1_000_000_000
    assert spin_until(executor, lambda: probe.send(0.25, -0.2, stamp_ns=old())
                      or probe.latest() == (0.0, 0.0), TIMEOUT)
    assert 'old by its header stamp' in capfd.readouterr().err
    # Fresh stamps move it; stamps far ahead count as their arrival, with a warning.
    assert drive(executor, probe, 0.25, -0.2, reaches(target),
                 stamp_ns=node.get_clock().now().nanoseconds)
    assert drive(executor, probe, 0.1, 0.0, reaches(track_setpoints(0.1, 0.0, IDEAL)),
                 stamp_ns=node.get_clock().now().nanoseconds + 10_000_000_000)
    assert 'ahead of this node' in capfd.readouterr().err
    # ... and do not keep the command alive: it goes stale 0.5 s after its arrival.
    assert spin_until(executor, lambda: probe.latest() == (0.0, 0.0), TIMEOUT)


def test_cmd_timeout_zero_disables_the_timeout(graph, executor, capfd):
    node, probe = graph(cmd_timeout=0.0)
    assert 'no timeout' in capfd.readouterr().err
    target = track_setpoints(0.2, 0.1, IDEAL)
    assert drive(executor, probe, 0.2, 0.1, reaches(target))
    probe.clear()
    # No command for 1 s (two default timeouts): the command holds.
    start = time.monotonic()
    spin_until(executor, lambda: time.monotonic() - start > 1.0, 2 * TIMEOUT)
    assert len(probe.setpoints()) >= 10 and np.all(probe.setpoints() == target)
    # Setting a timeout again stops the vehicle.
    assert node.set_parameters([Parameter('cmd_timeout', value=0.3)])[0].successful
    assert spin_until(executor, lambda: probe.latest() == (0.0, 0.0), TIMEOUT)


def test_separate_deceleration_limit_ddc_sign(graph, executor):
    # DDC writes max_deceleration negative; up at 0.5 m/s^2, down at 4 m/s^2.
    rate = 100.0
    # The timeout outlasts a loaded machine's slowest spin, so the 0.4 s ramp is never cut.
    _, probe = graph(rate=rate, cmd_timeout=1.0, **{'linear.x.max_acceleration': 0.5,
                                                    'linear.x.max_deceleration': -4.0})
    assert drive(executor, probe, 0.2, 0.0, reaches((0.2, 0.2)))
    up = probe.setpoints()[:, 0]
    up = up[(up > 0.0) & (up < 0.2)]
    assert len(up) >= 0.2 / (0.5 * 2 / rate) - 1  # at most 0.01 m/s per publish
    probe.clear()
    assert spin_until(executor, lambda: probe.latest() == (0.0, 0.0), TIMEOUT)
    down = -np.diff(probe.setpoints()[:, 0])
    assert np.max(down) <= 4.0 * 2 / rate + 1e-9
    assert np.max(down) > 0.5 * 2 / rate  # faster than the acceleration limit allows
    assert np.count_nonzero(down) <= 0.2 / (4.0 / rate) + 2


def test_limited_command_on_cmd_vel_out(graph, executor):
    _, probe = graph(**AURIGA_VALUES, max_track_speed=0.5)
    target = np.array(track_setpoints(1.0, 1.0, AURIGA))
    expected = target * 0.5 / np.max(np.abs(target))
    assert drive(executor, probe, 1.0, 1.0, reaches(expected))
    # The twist of the limited setpoints: on the commanded arc, slower.
    v_x, w = setpoint_twist(*expected, AURIGA)
    assert spin_until(executor, lambda: probe.out and (probe.out[-1].twist.linear.x,
                      probe.out[-1].twist.angular.z) == pytest.approx((v_x, w)), TIMEOUT)
    msg = probe.out[-1]
    assert msg.header.stamp.sec > 0 and v_x < 1.0 and w / v_x == pytest.approx(1.0)


def test_cmd_vel_out_can_be_turned_off(graph, executor):
    node, probe = graph(publish_limited_velocity=False)
    assert node.count_publishers('cmd_vel_translator/cmd_vel_out') == 0
    assert spin_until(executor, new_messages(probe, 5), TIMEOUT) and not probe.out


def test_ddc_nan_limits_are_no_limits(tmp_path, ros_context, executor):
    # A DDC YAML's .NAN ("no limit", its default) is accepted and means exactly no limit.
    params = tmp_path / 'ddc.yaml'
    params.write_text('/**:\n  ros__parameters:\n    cmd_timeout: 0.5\n'
                      '    linear.x.max_velocity: .NAN\n    linear.x.max_acceleration: .NAN\n'
                      '    linear.x.max_deceleration: .NAN\n    angular.z.max_velocity: .NAN\n'
                      '    angular.z.max_acceleration: .NAN\n'
                      f'    joint_velocity_topic: {JOINTS}\n')
    assert 'limits: none' in drive_console_script(ros_context, executor, tmp_path, params,
                                                  2.0, 1.5)


def test_nan_limits_in_process_match_the_core(graph, executor):
    values = {**AURIGA_VALUES, 'linear.x.max_velocity': math.nan,
              'angular.z.max_velocity': 0.5, 'max_track_decel': math.nan}
    node, probe = graph(**values)
    limiter = CommandLimiter(AURIGA, limits_from_values(values))
    assert drive(executor, probe, 1.0, 1.0, reaches(limiter.target(1.0, 1.0)))


def test_docs_page_lists_every_parameter():
    from helpers.setup_info import ROOT
    from tracked_kinematics.params import TERRAIN_PARAMS
    from tracked_kinematics.params.node_tables import TRANSLATOR_PARAMS
    page = (ROOT / 'docs' / 'nodes' / 'cmd_vel_translator.md').read_text()
    for spec in TRANSLATOR_PARAMS:
        assert spec in TERRAIN_PARAMS or f'`{spec.name}`' in page, spec.name


# Issue 27 item 4: a /clock that stalls, goes back or is invalid ----------------------------


class SimClock:
    """
    A simulation's /clock, ``rate`` x real time, published every 5 ms from a thread.

    ``commands(send, every, wall)`` calls ``send()`` every ``every`` s of simulated time
    (of wall time with ``wall``), from the same thread, as a drive on the simulation would.
    ``change(sim=..., rate=..., invalid=...)`` jumps, freezes (rate 0) or sends ``sec = -1``.
    """

    def __init__(self, node, start=100.0, rate=1.0):
        from rosgraph_msgs.msg import Clock
        self._msg = Clock()
        self._pub = node.create_publisher(Clock, '/clock', 10)
        self.sim, self.rate, self.invalid = start, rate, False
        self._command = None
        self._lock = threading.RLock()  # send() may read now()
        self._halt = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def now(self):
        with self._lock:
            return self.sim

    def change(self, **attrs):
        with self._lock:
            for name, value in attrs.items():
                setattr(self, name, value)

    def commands(self, send, every, wall=False):
        with self._lock:
            self._command, self._next = (send, every, wall), None

    def _run(self):
        last = time.monotonic()
        while not self._halt.wait(0.005):
            now = time.monotonic()
            with self._lock:
                self.sim += self.rate * (now - last)
                last = now
                stamp = self._msg.clock
                if self.invalid:
                    stamp.sec, stamp.nanosec = -1, 0
                else:
                    stamp.sec, stamp.nanosec = divmod(round(self.sim * 1e9), 1_000_000_000)
                self._pub.publish(self._msg)
                if self._command is not None:
                    send, every, wall = self._command
                    at = now if wall else self.sim
                    if self._next is None or at >= self._next:
                        send()
                        self._next = at + every

    def stop(self):
        self._halt.set()
        self._thread.join(TIMEOUT)


@pytest.fixture
def sim_clock(graph):
    """Give SimClocks on a probe's node, stopped before the graph is destroyed."""
    clocks = []

    def make(probe, **kwargs):
        clocks.append(SimClock(probe.node, **kwargs))
        return clocks[-1]

    yield make
    for clock in clocks:
        clock.stop()


def spin_to(executor, probe, target, timeout=TIMEOUT):
    """Spin until the last setpoints are ``target``; return the steady time it took."""
    start = time.monotonic()
    assert spin_until(executor, lambda: reaches(target)(probe), timeout), probe.latest()
    return time.monotonic() - start


def assert_ramp_down(probe, max_step=math.inf):
    """Assert the left setpoints fell to zero in steps, none larger than ``max_step``."""
    steps = np.diff(probe.setpoints()[:, 0])
    assert np.all(steps <= 0.0) and np.all(-steps <= max_step + 1e-9), steps
    assert np.count_nonzero(steps) >= 3  # a ramp, not a step


def test_frozen_clock_is_a_fault_ramped_on_steady_time(graph, sim_clock, executor, capfd):
    # The clock stops while commands keep coming (issue 27: the drive went on 3.3 m): after
    # clock_stall_timeout (= cmd_timeout) of steady time the setpoints ramp to zero at the
    # deceleration limit, on the steady clock since the node's own clock stands still.
    timeout, decel, rate = 0.3, 2.0, 50.0
    _, probe = graph(use_sim_time=True, cmd_timeout=timeout, max_track_accel=decel, rate=rate)
    clock = sim_clock(probe)
    clock.commands(lambda: probe.send(0.4, 0.0), every=0.05, wall=True)
    spin_to(executor, probe, (0.4, 0.4))
    capfd.readouterr()
    probe.clear()
    clock.change(rate=0.0)
    elapsed = spin_to(executor, probe, (0.0, 0.0))
    assert elapsed < timeout + 0.4 / decel + 1.0  # 1 s for a loaded machine
    assert_ramp_down(probe, decel * 2.0 / rate)  # steady time: two periods at most
    assert 'the ROS clock has not advanced for' in capfd.readouterr().err
    # The clock runs again: the next command is followed.
    clock.change(rate=1.0)
    spin_to(executor, probe, (0.4, 0.4))
    assert 'the ROS clock is healthy again' in capfd.readouterr().err


def test_rewound_clock_never_revives_a_stale_command(graph, sim_clock, executor, capfd):
    _, probe = graph(use_sim_time=True, cmd_timeout=0.5)
    clock = sim_clock(probe)
    sent = []

    def send():
        probe.send(0.3, 0.0)
        sent.append(clock.now())

    assert drive(executor, probe, 0.3, 0.0, lambda p: sent.append(clock.now())
                 or reaches((0.3, 0.3))(p))
    spin_to(executor, probe, (0.0, 0.0))  # stale by the simulated clock
    # Back into the command's life (as the deadman was revived in issue 27): still stale.
    # (Before its last send: the node's clock may lag the one sent, it sees no future.)
    clock.change(sim=sent[-1] - 0.2)
    probe.clear()
    assert spin_until(executor, lambda: len(probe.joints) >= 25, TIMEOUT)
    assert np.all(probe.setpoints() == 0.0), probe.setpoints()
    assert 'the ROS clock went back' in capfd.readouterr().err
    # A jump back while a command is in force drops it too; a new one is followed.
    clock.commands(send, every=0.05)
    spin_to(executor, probe, (0.3, 0.3))
    clock.commands(lambda: None, every=1.0)
    clock.change(sim=clock.now() - 5.0)
    spin_to(executor, probe, (0.0, 0.0), timeout=3.0)  # cmd_timeout would take 5.5 s


def test_invalid_clock_stops_and_recovers(graph, sim_clock, executor, capfd):
    node, probe = graph(use_sim_time=True, cmd_timeout=0.5, max_track_accel=4.0)
    clock = sim_clock(probe)
    clock.commands(lambda: probe.send(0.4, 0.0), every=0.05, wall=True)
    spin_to(executor, probe, (0.4, 0.4))
    clock.change(invalid=True)  # sec = -1, while the commands keep coming
    elapsed = spin_to(executor, probe, (0.0, 0.0))
    assert elapsed < 0.4 / 4.0 + 1.0
    count = len(probe.joints)
    assert spin_until(executor, lambda: len(probe.joints) > count + 10, TIMEOUT)  # alive
    assert node.failure is None and np.all(probe.setpoints()[count:] == 0.0)
    assert 'negative time -1 s' in capfd.readouterr().err
    clock.change(invalid=False)
    spin_to(executor, probe, (0.4, 0.4))


@pytest.mark.parametrize('rate, timeout, every', [(0.05, 0.25, 0.05), (20.0, 5.0, 0.05)],
                         ids=['slow_0.05x', 'fast_20x'])
def test_slow_and_fast_simulations_are_followed(graph, sim_clock, executor, rate, timeout,
                                                every):
    # Commands at 20 Hz of simulated time: at 0.05x one a second of wall time (4 x the
    # steady clock's cmd_timeout), at 20x one every 2.5 ms. Neither times out.
    _, probe = graph(use_sim_time=True, cmd_timeout=timeout)
    clock = sim_clock(probe, rate=rate)
    clock.commands(lambda: probe.send(0.3, 0.1), every=every)
    target = track_setpoints(0.3, 0.1, IDEAL)
    spin_to(executor, probe, target)
    probe.clear()
    end = time.monotonic() + 3.0  # a window of wall time, not a wait for a condition
    assert spin_until(executor, lambda: time.monotonic() > end, 4.0)
    assert len(probe.joints) > 50
    assert probe.setpoints() == pytest.approx(np.tile(target, (len(probe.joints), 1)))


DRIVE_SCRIPT = """
import rclpy
from geometry_msgs.msg import Twist
rclpy.init()
node = rclpy.create_node('drive_to_kill')
pub = node.create_publisher(Twist, 'cmd_vel', 10)
msg = Twist()
msg.linear.x = 0.4
node.create_timer(0.05, lambda: pub.publish(msg))
rclpy.spin(node)
"""


@pytest.mark.parametrize('sim', [False, True], ids=['real_time', 'sim_time'])
def test_killed_drive_stops_the_tracks(graph, sim_clock, executor, tmp_path, sim):
    # The drive is SIGKILLed: its commands simply stop, nothing says goodbye.
    import signal
    import subprocess
    import sys
    timeout, decel = 0.3, 2.0
    _, probe = graph(use_sim_time=sim, cmd_timeout=timeout, max_track_accel=decel)
    if sim:
        sim_clock(probe)
    log = open(tmp_path / 'drive.log', 'w')
    drive_process = subprocess.Popen([sys.executable, '-c', DRIVE_SCRIPT], stdout=log,
                                     stderr=log)
    try:
        spin_to(executor, probe, (0.4, 0.4), timeout=30.0)  # the import takes seconds
        probe.clear()
        drive_process.send_signal(signal.SIGKILL)
        elapsed = spin_to(executor, probe, (0.0, 0.0))
    finally:
        drive_process.kill()
        drive_process.wait(TIMEOUT)
        log.close()
    assert elapsed < timeout + 0.4 / decel + 0.5
    # (On simulated time a publish ramps over the simulated time since the last one.)
    assert_ramp_down(probe, math.inf if sim else decel * 2.0 / 50.0)
