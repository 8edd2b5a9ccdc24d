"""
Node health on /diagnostics and the warnings that name a missing input (issue 31, item 3).

Through the nodes, on real topics: a status per node on /diagnostics as diagnostic_updater
publishes it; odometry_node with no joint_states publisher (ERROR and a warning naming the
topic) and with one at 50 Hz (OK, its rate); calibration_drive with a pose_topic nobody
publishes. And the rules of :class:`Health` on a plain node.
"""

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers.encoder_stream import joint_state, Stderr
from helpers.ros_helpers import ConsoleScript, spin_until
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from std_msgs.msg import Float64
from tracked_kinematics.ros.calibration_drive_node import CalibrationDriveNode
from tracked_kinematics.ros.cmd_vel_translator import CmdVelTranslator
from tracked_kinematics.ros.health import ERROR, Health, OK
from tracked_kinematics.ros.icr_estimator import IcrEstimatorNode
from tracked_kinematics.ros.odometry_node import OdometryNode
from tracked_kinematics.ros.tracked_simulator import TrackedSimulator
from tracked_kinematics.share import config_file

pytestmark = pytest.mark.ros

VEHICLE = {'track_width': 0.42, 'sprocket_radius': 0.1}
NS = '/health_test'

NODES = {
    'odometry_node': (OdometryNode, {}),
    'icr_estimator': (IcrEstimatorNode, {}),
    'cmd_vel_translator': (CmdVelTranslator, {}),
    'tracked_simulator': (TrackedSimulator, None),  # its own vehicle file
    'calibration_drive': (CalibrationDriveNode, {'output': 'unused.yaml'}),
}


class Monitor:
    """A node of the test that keeps the latest status of each name on /diagnostics."""

    def __init__(self, ros_context, executor):
        self.node = Node('health_monitor', context=ros_context)
        self.latest = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on, 10)
        executor.add_node(self.node)

    def _on(self, msg):
        for status in msg.status:
            self.latest[status.name] = status

    def values(self, name):
        status = self.latest.get(name)
        return {} if status is None else {kv.key: kv.value for kv in status.values}


@pytest.fixture
def made(ros_context, executor):
    nodes = []
    yield nodes
    for node in reversed(nodes):
        executor.remove_node(node)
        node.destroy_node()


def start(cls, overrides, ros_context, executor, made, namespace=NS):
    params = None if overrides is None else [
        Parameter(k, value=v) for k, v in {**VEHICLE, **overrides}.items()]
    node = cls(context=ros_context, namespace=namespace, parameter_overrides=params or [])
    executor.add_node(node)
    made.append(node)
    return node


@pytest.mark.parametrize('name', NODES)
def test_every_node_publishes_its_status_on_diagnostics(name, ros_context, executor, made):
    monitor = Monitor(ros_context, executor)
    made.append(monitor.node)
    cls, overrides = NODES[name]
    start(cls, overrides, ros_context, executor, made)
    status_name = f'{name}: health'
    assert spin_until(executor, lambda: status_name in monitor.latest, 10.0), monitor.latest
    status = monitor.latest[status_name]
    assert status.level in (OK, DiagnosticStatus.WARN, ERROR)
    assert status.message
    # Every input the node subscribes to has its publishers, rate and age.
    keys = monitor.values(status_name)
    inputs = [key[:-len(' publishers')] for key in keys if key.endswith(' publishers')]
    assert inputs, keys
    for topic in inputs:
        assert topic.startswith('/')
        assert {f'{topic} rate (Hz)', f'{topic} age (s)', f'{topic} messages'} <= set(keys)


def test_odometry_node_without_joint_states_names_the_topic(ros_context, executor, made,
                                                            capfd):
    stderr = Stderr(capfd)
    monitor = Monitor(ros_context, executor)
    made.append(monitor.node)
    start(OdometryNode, {}, ros_context, executor, made)
    topic = f'{NS}/joint_states'

    def error():
        status = monitor.latest.get('odometry_node: health')
        return status is not None and status.level == ERROR
    assert spin_until(executor, error, 10.0), monitor.latest
    status = monitor.latest['odometry_node: health']
    assert status.message == f'{topic}: no publisher'
    assert monitor.values(status.name)[f'{topic} publishers'] == '0'
    assert monitor.values(status.name)[f'{topic} age (s)'] == 'never'
    assert stderr.warnings('health_test.odometry_node', f'{topic}: no publisher')


def test_odometry_node_with_joint_states_at_50_hz_is_ok(ros_context, executor, made):
    monitor = Monitor(ros_context, executor)
    made.append(monitor.node)
    start(OdometryNode, {}, ros_context, executor, made)
    topic = f'{NS}/joint_states'
    driver = Node('driver', context=ros_context)
    made.append(driver)
    executor.add_node(driver)
    publisher = driver.create_publisher(type(joint_state(0.0)), topic, QoSProfile(depth=100))
    sent = []

    def tick():
        sent.append(time.monotonic())
        publisher.publish(joint_state(len(sent) * 0.02, position=[0.0, 0.0]))
    driver.create_timer(0.02, tick)

    def rate():
        values = monitor.values('odometry_node: health')
        return float(values.get(f'{topic} rate (Hz)', 'nan'))

    def steady():
        status = monitor.latest.get('odometry_node: health')
        return status is not None and status.level == OK and 40.0 <= rate() <= 60.0
    assert spin_until(executor, steady, 15.0), (monitor.latest, rate())
    status = monitor.latest['odometry_node: health']
    assert status.message == 'OK'
    assert monitor.values(status.name)[f'{topic} publishers'] == '1'
    assert float(monitor.values(status.name)[f'{topic} age (s)']) < 1.0


def test_calibration_drive_names_a_pose_topic_nobody_publishes(ros_context, executor, made,
                                                               capfd):
    stderr = Stderr(capfd)
    monitor = Monitor(ros_context, executor)
    made.append(monitor.node)
    start(CalibrationDriveNode, {'output': 'unused.yaml', 'pose_topic': 'nobody/pose'},
          ros_context, executor, made)
    topic = f'{NS}/nobody/pose'

    def named():
        status = monitor.latest.get('calibration_drive: health')
        return status is not None and status.level == ERROR and topic in status.message
    assert spin_until(executor, named, 10.0), monitor.latest
    status = monitor.latest['calibration_drive: health']
    assert f'{topic}: no publisher' in status.message
    assert monitor.values(status.name)['state'] == 'idle'
    # The deadman is needed only while driving: idle, its silence is no error.
    assert f'{NS}/deadman' not in status.message
    assert stderr.warnings('health_test.calibration_drive', f'{topic}: no publisher')


def test_with_auto_start_a_silent_deadman_is_named_before_the_start(
        ros_context, executor, made):
    # auto_start waits for the deadman: idle, its silence is why nothing happens.
    monitor = Monitor(ros_context, executor)
    made.append(monitor.node)
    start(CalibrationDriveNode, {'output': 'unused.yaml', 'auto_start': True}, ros_context,
          executor, made)

    def named():
        status = monitor.latest.get('calibration_drive: health')
        return status is not None and f'{NS}/deadman: no publisher' in status.message
    assert spin_until(executor, named, 10.0), monitor.latest


def test_health_rules_on_a_plain_node(ros_context, executor, made, capfd):
    stderr = Stderr(capfd)
    node = Node('plain', namespace=NS, context=ros_context)
    made.append(node)
    executor.add_node(node)
    health = Health(node, hardware_id='robot-7', timer=False)
    needed = [False]
    count = health.watch_topic('speed', ['std_msgs/msg/Float64'], needed=lambda: needed[0],
                               silence=0.2)
    node.create_subscription(Float64, 'speed', count.counted(lambda msg: None), 10)
    health.add(lambda report: report.add('source', 'encoders'))
    assert health.name == 'plain: health'

    # Not needed: OK however long it is quiet.
    report = health.report()
    assert report.level == OK and report.message == 'OK'
    assert {kv.key: kv.value for kv in report.values}['source'] == 'encoders'
    status = health.status(report)
    assert status.hardware_id == 'robot-7' and status.name == 'plain: health'

    # Needed: silence counts from then on; after it, an ERROR and one throttled warning.
    needed[0] = True
    assert health.report().level == OK
    assert spin_until(executor, lambda: health.report().level == ERROR, 5.0)
    assert health.report().message == f'{NS}/speed: no publisher'
    assert len(stderr.warnings('health_test.plain', f'{NS}/speed: no publisher')) == 1

    # A publisher that sends nothing: the message says so and counts it.
    talker = Node('talker', namespace=NS, context=ros_context)
    made.append(talker)
    publisher = talker.create_publisher(Float64, 'speed', 10)
    assert spin_until(executor, lambda: 'no message' in health.report().message, 5.0)
    assert f'{NS}/speed: no message for' in health.report().message
    assert health.report().message.endswith('(1 publisher)')

    # Messages again: OK, and a line saying so.
    assert spin_until(executor, lambda: publisher.publish(Float64()) or count.count > 0, 5.0)
    assert health.report().level == OK
    assert stderr.lines('INFO', 'health_test.plain', f'{NS}/speed: receiving again')


def test_odometry_node_remapped_to_a_silent_topic_says_so(tmp_path):
    # The case: the console script, remapped to a topic nobody publishes, printed
    # nothing after its start-up line.
    script = ConsoleScript('odometry_node', '--ros-args', '--params-file',
                           config_file('auriga_alpha_hard_floor.yaml'), '-p',
                           'publish_tf:=false', '-r', 'joint_states:=/nobody/joint_states',
                           tmp_path=tmp_path)
    with script:
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and script.process.poll() is None:
            if '/nobody/joint_states: no publisher' in script.output:
                break
            time.sleep(0.1)
        output = script.output
    warned = [line for line in output.splitlines()
              if line.startswith('[WARN]') and '/nobody/joint_states: no publisher' in line]
    assert warned, output
