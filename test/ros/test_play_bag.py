"""
play_bag (issue 37 item 6): a bag's topics onto live topics, as the console script runs.

A bag written here (encoders, a gyro with a standstill, and one topic of each message type the
package uses) is played into odometry_node and into the test's own subscriptions; a real run
of ../shared/realdata too, where it is. Errors and stops at any instant as a user meets them.
"""

import math
import random
import signal
import subprocess
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Twist
from helpers import realdata
from helpers.fake_robot import AURIGA, RADIUS
from helpers.gyro_drive import gyro_drive
from helpers.ros_helpers import BIN, ConsoleScript, spin_until
from helpers.stops import catches_sigterm
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, NavSatFix
from std_msgs.msg import Float64

pytestmark = pytest.mark.ros

T0_NS = 1_700_000_000_000_000_000
JOINTS = ('left_sprocket_joint', 'right_sprocket_joint')
TERRAIN = ('/**:\n  ros__parameters:\n    track_width: 0.42\n    sprocket_radius: 0.1\n'
           '    imu_topic: /imu/data\n')
#: One message of each of these per second beside the encoders and the gyro: (topic, type).
OTHERS = {'/left_track/setpoint': Float64, '/cmd_vel': Twist, '/gps/fix': NavSatFix,
          '/ground_truth/odom': Odometry, '/icp/pose': PoseStamped}
SECONDS = 8.0


@pytest.fixture(scope='module')
def small_bag(tmp_path_factory):
    """Write an 8-s bag: 3.5 s still, then arcs; encoders 50 Hz, gyro 100 Hz, others 1 Hz."""
    from tracked_kinematics.offline.bags.writer import BagWriter
    path = tmp_path_factory.mktemp('bags') / 'small'
    t, left, right, tg, wg = gyro_drive(AURIGA, seconds=SECONDS, still=3.5, gyro_rate=100.0)
    events = [(T0_NS + round(s * 1e9), 0, k) for k, s in enumerate(t)]
    events += [(T0_NS + round(s * 1e9), 1, k) for k, s in enumerate(tg)]
    events += [(T0_NS + round(s * 1e9) + 1000, 2, k) for k, s in enumerate(range(int(SECONDS)))]
    with BagWriter(path) as bag:
        for stamp, kind, k in sorted(events):
            if kind == 0:
                bag.write('/joint_states', stamp, bag.joint_state(
                    stamp, JOINTS, [left[k] / RADIUS, right[k] / RADIUS]))
            elif kind == 1:
                bag.write('/imu/data', stamp, bag.imu(stamp, wg[k]))
            else:
                bag.write('/left_track/setpoint', stamp, bag.float64(0.25 * k))
                bag.write('/cmd_vel', stamp, bag.twist(0.1 * k, -0.2))
                bag.write('/gps/fix', stamp, bag.nav_sat_fix(stamp, 46.8 + k, -71.2, 10.0))
                bag.write('/ground_truth/odom', stamp, bag.odometry(stamp, float(k), 0.0, 0.0))
                bag.write('/icp/pose', stamp, bag.pose_stamped(stamp, float(k), 1.0, 0.0))
    return path


class Listener:
    """The test's node: odometry on /odom, the node's status on /diagnostics, any topics."""

    def __init__(self, ros_context, executor, topics=()):
        self.node = Node('play_bag_listener', context=ros_context)
        executor.add_node(self.node)
        self.executor = executor
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.odom, self.heading, self.got, self.sent = [], [], {}, {}
        self.node.create_subscription(Odometry, '/odom', self.odom.append, reliable)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_status, 10)
        for topic, kind in topics:
            self.got[topic], self.sent[topic] = [], []
            self.node.create_subscription(kind, topic, self._keeper(topic), reliable)

    def _keeper(self, topic):
        def keep(msg, info):
            self.got[topic].append(msg)
            # When the player published it (the DDS source stamp, ns): its pace, not that of
            # this process's executor, which a loaded machine holds up and then serves in a
            # burst (1.2 s of arrivals for 1.5 s of publishing was seen).
            self.sent[topic].append(info['source_timestamp'] * 1e-9)
        return keep

    def _on_status(self, msg):
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if 'heading source' in values:
                self.heading.append(values['heading source'])

    def wait(self, condition, seconds, process):
        """Spin until ``condition()``; False when ``seconds`` pass or ``process`` died."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            if condition():
                return True
            if process is not None and process.process.poll() is not None:
                return bool(condition())
            self.executor.spin_once(timeout_sec=0.02)
        return bool(condition())


def test_plays_into_odometry_node_with_the_gyro_on_sim_time(ros_context, executor, tmp_path,
                                                            small_bag):
    terrain = tmp_path / 'terrain.yaml'
    terrain.write_text(TERRAIN)
    listener = Listener(ros_context, executor)
    with ConsoleScript('odometry_node', '--ros-args', '--params-file', terrain,
                       '-p', 'use_sim_time:=true', tmp_path=tmp_path) as node:
        assert listener.wait(lambda: listener.node.count_publishers('/odom') >= 1, 60.0, node), \
            node.output
        with ConsoleScript('play_bag', small_bag, '--clock', '--wait-for', '/joint_states',
                           '/imu/data', tmp_path=tmp_path) as player:
            # The standstill measures the bias (3.5 s), then the gyro is the heading source.
            assert listener.wait(lambda: 'gyro' in listener.heading and listener.odom, 90.0,
                                 player), (listener.heading[-3:], player.output, node.output)
            assert player.wait(60.0) == 0, player.output
        out = player.output
    assert 'played' in out and '/imu/data' in out, out
    # On the bag's time: the odometry's stamps are the recorded ones, in the bag's window.
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in listener.odom]
    assert all(T0_NS * 1e-9 <= s <= T0_NS * 1e-9 + SECONDS + 0.1 for s in stamps), stamps[:3]
    assert all(math.isfinite(m.pose.pose.position.x) for m in listener.odom)


def test_every_message_type_arrives_intact_and_paced(ros_context, executor, tmp_path,
                                                     small_bag):
    topics = [('/joint_states', JointState), ('/imu/data', Imu), ('/clock', Clock),
              *OTHERS.items()]
    listener = Listener(ros_context, executor, topics)
    with ConsoleScript('play_bag', small_bag, '--rate', '4', '--clock', '--start', '2',
                       '--delay', '0', '--wait-for',
                       *(topic for topic, _ in topics if topic != '/clock'),
                       tmp_path=tmp_path) as player:
        # All of the window arrives: the encoders and gyro after 2 s, the others' last ones.
        assert listener.wait(lambda: player.process.poll() is not None, 120.0, None)
        assert player.wait() == 0, player.output
        spin_until(executor, lambda: len(listener.got['/joint_states']) >= 301, 5.0)
    got = listener.got
    assert len(got['/joint_states']) == 301     # 2..8 s at 50 Hz
    assert len(got['/imu/data']) > 550          # 2..8 s at 100 Hz (the gyro's late stamps)
    assert [m.data for m in got['/left_track/setpoint']] == [0.25 * k for k in range(2, 8)]
    assert [m.linear.x for m in got['/cmd_vel']] == pytest.approx([0.1 * k for k in range(2, 8)])
    assert [m.latitude for m in got['/gps/fix']] == [46.8 + k for k in range(2, 8)]
    assert [m.pose.pose.position.x for m in got['/ground_truth/odom']] == list(range(2, 8))
    assert [m.pose.position.y for m in got['/icp/pose']] == [1.0] * 6
    # /clock carries the bag's time, never beyond the messages, and goes forward.
    clock = [c.clock.sec + c.clock.nanosec * 1e-9 for c in got['/clock']]
    assert clock == sorted(clock) and clock[0] >= T0_NS * 1e-9 + 2.0 - 1e-6
    assert clock[-1] <= T0_NS * 1e-9 + SECONDS + 0.1
    first = got['/joint_states'][0].header.stamp
    assert first.sec + first.nanosec * 1e-9 == pytest.approx(T0_NS * 1e-9 + 2.0, abs=0.021)
    # Paced at 4 x: the 6 s of encoders are not published faster than 1.5 s.
    sent = listener.sent['/joint_states']
    assert sent[-1] - sent[0] > 0.9 * 6.0 / 4


@pytest.mark.parametrize('args, text', [
    (['missing_bag'], 'bag not found'),
    (['{corrupt}'], 'cannot read bag'),
    (['{bag}', '--topics', '/no_such_topic'], 'no topic /no_such_topic'),
    (['{bag}', '--start', '100'], 'beyond the bag'),
    (['{bag}', '--rate', '0'], 'must be in [0.01, 100]'),
    (['{bag}', '--topics', '/imu/data', '--wait-for', '/joint_states'], 'not a played topic'),
])
def test_bad_input_is_one_line_and_status_2(tmp_path, small_bag, args, text):
    corrupt = tmp_path / 'corrupt'
    corrupt.mkdir()
    (corrupt / 'metadata.yaml').write_text('rosbag2_bagfile_information: [not, a, bag\n')
    argv = [a.format(bag=small_bag, corrupt=corrupt) for a in args]
    result = subprocess.run([str(BIN / 'play_bag'), *argv], capture_output=True, text=True,
                            cwd=tmp_path, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('play_bag: error: ') and text in lines[0], \
        result.stderr
    assert 'Traceback' not in result.stderr


@pytest.mark.parametrize('signum, when', [(signal.SIGINT, 'starting'),
                                          (signal.SIGTERM, 'playing')])
def test_a_signal_at_any_instant_ends_it_cleanly(tmp_path, small_bag, signum, when):
    process = subprocess.Popen([str(BIN / 'play_bag'), str(small_bag), '--loop', '--clock'],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               cwd=tmp_path)
    deadline = time.monotonic() + 120.0
    while not catches_sigterm(process.pid) and time.monotonic() < deadline:
        assert process.poll() is None     # the package's first line has not run yet
    if when == 'playing':
        # The topic table is printed just before the first message is published.
        line = process.stdout.readline()
        assert line.startswith(str(small_bag)), line
    else:
        # Importing, reading the bag, or starting ROS: an instant of its own in every run.
        time.sleep(random.uniform(0.0, 1.0))
    assert process.poll() is None
    process.send_signal(signum)
    out, err = process.communicate(timeout=max(1.0, deadline - time.monotonic()))
    assert process.returncode == 0, err
    assert 'Traceback' not in err and err == '', err
    if when == 'playing':
        assert out.strip().endswith('(stopped)'), out


def test_plays_a_real_run_into_odometry_node_with_the_gyro(ros_context, executor, tmp_path):
    # The acceptance of issue 37: a real Warthog run, its gyro on /imu/data, the node on the
    # wall clock (no --clock), /diagnostics says the gyro is the heading source.
    bag = realdata.bag('warthog_grass_2024-07-29_14h04')
    listener = Listener(ros_context, executor)
    with ConsoleScript('odometry_node', '--ros-args', '-p', 'track_width:=1.08',
                       '-p', 'sprocket_radius:=0.3', '-p', 'imu_topic:=/imu/data',
                       tmp_path=tmp_path) as node:
        assert listener.wait(lambda: listener.node.count_publishers('/odom') >= 1, 60.0, node), \
            node.output
        with ConsoleScript('play_bag', bag, '--duration', '15', '--topics', '/joint_states',
                           '/imu/data', '--wait-for', '/joint_states', '/imu/data',
                           tmp_path=tmp_path) as player:
            assert listener.wait(lambda: 'gyro' in listener.heading and listener.odom, 90.0,
                                 player), (listener.heading[-3:], player.output, node.output)
