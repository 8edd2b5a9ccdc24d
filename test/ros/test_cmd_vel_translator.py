"""cmd_vel_translator on a real rclpy graph: every behaviour of issue 5 but the launch file."""

import math
import threading

from geometry_msgs.msg import Twist, TwistStamped
from helpers.ros_helpers import ConsoleScript, spin_until
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64, Float64MultiArray
from tracked_kinematics.core.command import track_setpoints
from tracked_kinematics.core.kinematics import forward, true_speeds
from tracked_kinematics.params import icr_from_values, read_params_file
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


class Probe:
    """The rest of the graph: a cmd_vel publisher and recorders of the setpoints."""

    def __init__(self, context, stamped=False, joint_topic=None):
        self.node = Node('translator_probe', context=context)
        self.stamped = stamped
        self.pub = self.node.create_publisher(TwistStamped if stamped else Twist, 'cmd_vel', 10)
        self.left, self.right, self.joints = [], [], []
        self.node.create_subscription(Float64, 'left_track/setpoint',
                                      lambda m: self.left.append(m.data), 10)
        self.node.create_subscription(Float64, 'right_track/setpoint',
                                      lambda m: self.right.append(m.data), 10)
        if joint_topic:
            self.node.create_subscription(Float64MultiArray, joint_topic,
                                          lambda m: self.joints.append(list(m.data)), 10)

    def send(self, v_x, w, v_y=0.0):
        twist = Twist()
        twist.linear.x, twist.linear.y, twist.angular.z = float(v_x), float(v_y), float(w)
        if self.stamped:
            msg = TwistStamped(twist=twist)
            msg.header.frame_id = 'base_link'  # stamp left at 0: arrival time is what counts
            self.pub.publish(msg)
        else:
            self.pub.publish(twist)

    def setpoints(self):
        """Return the (left, right) pairs received so far, one row per publish."""
        n = min(len(self.left), len(self.right))
        return np.column_stack([self.left[:n], self.right[:n]])

    def latest(self):
        """Return the last (left, right) pair, or None."""
        pairs = self.setpoints()
        return tuple(pairs[-1]) if len(pairs) else None

    def clear(self):
        """Forget what was received (both sides, so that pairs stay aligned)."""
        n = min(len(self.left), len(self.right))
        del self.left[:n], self.right[:n], self.joints[:]


@pytest.fixture
def graph(ros_context, executor):
    """Build a translator with parameter overrides and a probe, both on the executor."""
    made = []

    def make(**params):
        overrides = [Parameter(name, value=value)
                     for name, value in {**VEHICLE, **params}.items()]
        node = CmdVelTranslator(context=ros_context, parameter_overrides=overrides)
        probe = Probe(ros_context, stamped=params.get('use_stamped', False),
                      joint_topic=params.get('joint_velocity_topic'))
        made.extend([node, probe.node])
        executor.add_node(node)
        executor.add_node(probe.node)
        assert spin_until(executor, lambda: probe.pub.get_subscription_count() > 0
                          and probe.latest() is not None, TIMEOUT)
        return node, probe

    yield make
    for node in made:
        executor.remove_node(node)
        node.destroy_node()


def drive(executor, probe, v_x, w, until, v_y=0.0):
    """Send a command every spin until ``until(probe)`` holds; return whether it did."""
    def condition():
        probe.send(v_x, w, v_y)
        return until(probe)
    return spin_until(executor, condition, TIMEOUT)


def reaches(target, rel=1e-9):
    """Return a condition: the last setpoints are ``target``."""
    def condition(probe):
        last = probe.latest()
        return last is not None and last == pytest.approx(tuple(target), rel=rel, abs=1e-12)
    return condition


def twist_of(pairs, icr):
    """Return (v_x, w) arrays that nominal setpoint pairs give through the odometry model."""
    v_x, _, w = forward(*true_speeds(pairs[:, 0], pairs[:, 1], icr), icr)
    return v_x, w


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
    # A fixed rate, whether commands come or not.
    probe.clear()
    start = node.get_clock().now().nanoseconds
    assert spin_until(executor, lambda: len(probe.setpoints()) >= 20, TIMEOUT)
    elapsed = (node.get_clock().now().nanoseconds - start) * 1e-9
    assert 19 / 100.0 * 0.7 < elapsed < 21 / 100.0 * 3.0  # not faster; slower only if starved


def test_timeout_ramps_to_zero(graph, executor):
    accel, rate = 2.0, 100.0
    _, probe = graph(cmd_timeout=0.15, max_track_accel=accel, rate=rate)
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


@pytest.mark.parametrize('params', [
    {'max_track_accel': 1.0},
    {'linear.x.max_acceleration': 0.5, 'angular.z.max_acceleration': 1.0},
], ids=['track', 'twist'])
def test_acceleration_ramp_keeps_curvature(graph, executor, params):
    rate = 50.0
    _, probe = graph(**AURIGA_VALUES, rate=rate, **params)
    probe.clear()
    target = track_setpoints(0.3, 0.4, AURIGA)
    assert drive(executor, probe, 0.3, 0.4, reaches(target))
    pairs = probe.setpoints()
    pairs = pairs[np.any(pairs != 0.0, axis=1)]
    assert len(pairs) >= 5  # ramped over several periods
    assert np.all(np.diff(pairs, axis=0) * np.sign(target) >= -1e-12)  # monotone
    v_x, w = twist_of(pairs, AURIGA)
    np.testing.assert_allclose(w / v_x, 0.4 / 0.3, rtol=1e-9)  # on the commanded arc
    period_max = 2.0 / rate
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
    target = track_setpoints(0.3, 0.1, icr_from_values(VEHICLE))
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
    target = track_setpoints(0.2, 0.0, icr_from_values(VEHICLE))
    assert drive(executor, probe, 0.2, 0.0, reaches(target), v_y=0.3)
    for _ in range(5):
        probe.send(0.2, 0.0, 0.3)
        executor.spin_once(timeout_sec=0.01)
    assert probe.latest() == pytest.approx(target)
    assert capfd.readouterr().err.count('linear.y is ignored') == 1


def test_stamped_mode_uses_arrival_time(graph, executor):
    # The stamps are 0 (1970): by their age every command would be stale. By arrival time
    # they are fresh, so the vehicle moves.
    _, probe = graph(use_stamped=True)
    target = track_setpoints(0.25, -0.2, icr_from_values(VEHICLE))
    assert drive(executor, probe, 0.25, -0.2, reaches(target))


def test_joint_velocities_in_rad_per_s(graph, executor):
    _, probe = graph(**{**AURIGA_VALUES, 'sprocket_radius': 0.05},
                     joint_velocity_topic='tracks_controller/commands')
    target = track_setpoints(0.5, 0.3, AURIGA)
    assert drive(executor, probe, 0.5, 0.3, lambda p: p.joints and p.joints[-1]
                 == pytest.approx([target[0] / 0.05, target[1] / 0.05]))


def test_invalid_parameters_refused_at_start(ros_context):
    with pytest.raises(ParameterError, match='max_track_speed must be >= 0'):
        CmdVelTranslator(context=ros_context,
                         parameter_overrides=VEHICLE_PARAMS + [
                             Parameter('max_track_speed', value=-1.0)])
    with pytest.raises(ParameterError, match='chi'):
        CmdVelTranslator(context=ros_context,
                         parameter_overrides=VEHICLE_PARAMS + [
                             Parameter('icr.y_left', value=0.1)])


def test_runtime_parameters_validated_and_applied(graph, executor):
    node, probe = graph(**AURIGA_VALUES)
    for name, value, reason in [
            ('max_track_speed', -0.5, 'max_track_speed must be >= 0'),
            ('angular.z.max_acceleration', math.nan, 'must be >= 0'),
            ('cmd_timeout', 0.0, 'cmd_timeout must be > 0'),
            ('icr.y_left', -0.01, 'chi'),
            ('icr.y_left', -0.5, 'icr.y_left'),
            ('scale.right', 0.0, 'scale.right out of range Min: 0.1')]:
        result = node.set_parameters([Parameter(name, value=value)])[0]
        assert not result.successful and reason in result.reason, name
    assert node.get_parameter('max_track_speed').value == 0.0
    target = track_setpoints(1.0, 0.0, AURIGA)
    assert drive(executor, probe, 1.0, 0.0, reaches(target))
    # A valid change applies to the next setpoints; .inf and 0 both mean no limit.
    assert node.set_parameters([Parameter('max_track_speed', value=0.5)])[0].successful
    assert drive(executor, probe, 1.0, 0.0, reaches(np.array(target) * 0.5 / max(target)))
    assert node.set_parameters([Parameter('max_track_speed', value=math.inf)])[0].successful
    assert drive(executor, probe, 1.0, 0.0, reaches(target))
    # A new rate takes effect.
    assert node.set_parameters([Parameter('rate', value=200.0)])[0].successful
    probe.clear()
    start = node.get_clock().now().nanoseconds
    assert spin_until(executor, lambda: len(probe.setpoints()) >= 40, TIMEOUT)
    # 0.2 s at 200 Hz; 0.8 s at the old 50 Hz.
    assert (node.get_clock().now().nanoseconds - start) * 1e-9 < 40 / 200.0 * 3.0


def test_console_script_with_terrain_params_file(ros_context, executor, tmp_path):
    # One terrain file configures both nodes; node parameters come in a second file.
    extra = tmp_path / 'translator.yaml'
    extra.write_text('cmd_vel_translator:\n  ros__parameters:\n    rate: 100.0\n'
                     '    max_track_speed: 2.0\n    joint_velocity_topic: joint_commands\n')
    probe = Probe(ros_context, joint_topic='joint_commands')
    executor.add_node(probe.node)
    with ConsoleScript('cmd_vel_translator', '--ros-args', '--params-file', AURIGA_FILE,
                       '--params-file', extra, tmp_path=tmp_path) as script:
        assert spin_until(executor, lambda: probe.pub.get_subscription_count() > 0
                          and probe.latest() is not None, 15.0), script.output
        target = track_setpoints(0.4, -0.5, AURIGA)
        assert drive(executor, probe, 0.4, -0.5, reaches(target)), script.output
        joints = pytest.approx([target[0] / 0.1, target[1] / 0.1])  # rad/s, radius 0.1 m
        assert spin_until(executor, lambda: probe.joints[-1] == joints, TIMEOUT)
        assert script.stop() == 0
    assert 'chi = 0.540' in script.output and 'max_track_speed 2' in script.output
    probe.node.destroy_node()


@pytest.mark.parametrize('args, reason', [
    (['-p', 'max_track_accel:=-2.0'], 'max_track_accel must be >= 0'),
    (['-p', 'icr.y_right:=0.5'], 'icr.y_left'),
    (['-p', 'rate:=0.0'], 'rate must be > 0'),
])
def test_console_script_exits_2_on_invalid_parameters(tmp_path, args, reason):
    script = ConsoleScript('cmd_vel_translator', '--ros-args', '--params-file', AURIGA_FILE,
                           *args, tmp_path=tmp_path)
    assert script.wait(30.0) == 2
    fatal = [line for line in script.output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1 and reason in fatal[0], script.output


def test_simulated_time_paused_holds_setpoints(graph, executor):
    from rosgraph_msgs.msg import Clock
    _, probe = graph(use_sim_time=True, cmd_timeout=0.1)
    clock = probe.node.create_publisher(Clock, '/clock', 10)

    def tick(seconds):
        msg = Clock()
        msg.clock.sec = seconds
        clock.publish(msg)

    tick(100)
    target = track_setpoints(0.3, 0.0, icr_from_values(VEHICLE))
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
