"""odometry_node with an IMU (imu_topic): gyro-aided heading, fallback, covariance, push_to."""

import math

from helpers.encoder_stream import Driver, joint_state, stamp, Stderr
from helpers.gyro_drive import gyro_drive, true_heading
from helpers.ros_helpers import spin_until
from nav_msgs.msg import Odometry as OdometryMsg
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray
from tracked_kinematics.core.covariance import message_twist_covariance, TrackNoise
from tracked_kinematics.core.gyro import replay
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.params import (gyro_config_from_values, gyro_noise_model_from_values,
                                       icr_from_values, noise_model_from_values,
                                       read_params_file)
from tracked_kinematics.ros.odometry_node import OdometryNode
from tracked_kinematics.ros.parameters import ParameterError
from tracked_kinematics.share import config_file

pytestmark = pytest.mark.ros

TERRAIN = config_file('auriga_alpha_hard_floor.yaml')
VALUES = {k: v for k, v in read_params_file(TERRAIN).items() if k not in ('terrain', 'source')}
AURIGA = icr_from_values(VALUES)
RADIUS = VALUES['sprocket_radius']
# The simulated gyro: bias 0.02 rad/s (learnt at standstill), scale 1.02, stamped 0.05 s late.
WITH_GYRO = {'imu_topic': 'imu', 'imu_delay': 0.05, 'gyro_scale': 1.02}
TRACKS_ONLY = {'covariance.turn': 0.0, 'covariance.slip': 0.0, 'covariance.timing': 0.0}


def imu_msg(t, wz):
    msg = Imu()
    msg.header.stamp = stamp(t)
    msg.angular_velocity.z = float(wz)
    return msg


def yaws(msgs):
    return np.unwrap([2.0 * math.atan2(m.pose.pose.orientation.z, m.pose.pose.orientation.w)
                      for m in msgs])


def planar(covariance):
    c = np.asarray(covariance).reshape(6, 6)
    return c[np.ix_([0, 1, 5], [0, 1, 5])]


class Graph:
    """An in-process odometry_node fed encoders and an IMU in stamp order; records odom."""

    def __init__(self, ros_context, executor, capfd, overrides=None):
        values = {**VALUES, **WITH_GYRO, **(overrides or {})}
        self.node = OdometryNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
        executor.add_node(self.node)
        self.executor = executor
        self.stderr = Stderr(capfd)
        self.encoders = Driver(ros_context, executor, lambda: self.node.encoder.received)
        self.imu = None if self.node.imu is None else Driver(
            ros_context, executor, lambda: self.node.imu.count.count, node=self.encoders.node)
        self.odom, self.icr = [], []
        self.encoders.node.create_subscription(
            OdometryMsg, 'odom', self.odom.append,
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        self.encoders.node.create_subscription(Float64MultiArray, 'odometry_node/icr',
                                               self.icr.append, 10)
        assert spin_until(executor, lambda: self.node.count_subscribers('odom') >= 1)

    def feed(self, t, left, right, tg=(), wg=(), after=None):
        """
        Send encoder and gyro samples in stamp order (gyro first); return the new odom.

        ``wg`` holds z rates (rad/s) or whole Imu messages (stamped ``tg``).
        """
        events = sorted([(s, 0, k) for k, s in enumerate(tg)]
                        + [(s, 1, k) for k, s in enumerate(t)])
        start = len(self.odom)
        for s, kind, k in events:
            if kind == 0:
                sample = wg[k]
                assert self.imu.send(sample if isinstance(sample, Imu) else imu_msg(s, sample),
                                     'imu')
            else:
                assert self.encoders.send(joint_state(s, [left[k] / RADIUS, right[k] / RADIUS]))
                if after is not None:
                    after(s)
        assert spin_until(self.executor, lambda: len(self.odom) >= start + len(t) - 1)
        return self.odom[start:]

    def report(self):
        return {v.key: v.value for v in self.node.health.report().values}

    def fallbacks(self):
        return self.stderr.warnings('odometry_node', 'heading from the encoders until')


@pytest.fixture
def graph(ros_context, executor, capfd):
    def make(overrides=None):
        return Graph(ros_context, executor, capfd, overrides)
    return make


T0 = 10.0  # s, the drives' start (a zero stamp is refused)


def drive(**kwargs):
    t, left, right, tg, wg = gyro_drive(
        AURIGA, **{'seconds': 8.0, 'still': 3.5, 'gyro_rate': 100.0, **kwargs})
    return T0 + t, left, right, T0 + tg, wg


def test_gyro_heading_matches_replay_and_the_truth(graph):
    g = graph()
    t, left, right, tg, wg = drive()
    msgs = g.feed(t, left, right, tg, wg)
    assert g.node.odometry.source == 'gyro'
    # The node is replay() of the same streams with gyro_config_from_values of its
    # parameters: evaluate_model --fuse-imu's path.
    # The stamps as the node reads them: integer nanoseconds, in seconds.
    ns = (lambda times: np.round(np.asarray(times) * 1e9) * 1e-9)
    values = g.node.params.values
    poses, sources, end = replay(ns(t), left, right, ns(tg), wg, AURIGA,
                                 gyro_config_from_values(values),
                                 terms=noise_model_from_values(values).without_tracks(),
                                 gyro_terms=gyro_noise_model_from_values(values).without_tracks())
    got = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in msgs])
    np.testing.assert_allclose(got, poses[1:, :2], atol=1e-6)
    np.testing.assert_allclose(yaws(msgs), poses[1:, 2], atol=1e-6)
    # Gyro-aided: the true heading within 0.03 rad where the encoders are off by 20 %.
    truth = true_heading(AURIGA, t, left, right)
    model = truth / 0.8
    assert abs(truth[-1]) > 0.5
    assert abs(yaws(msgs)[-1] - truth[-1]) < 0.03 < abs(model[-1] - truth[-1])
    # twist.angular.z is the gyro's (de-biased, scaled): the true rate.
    true_rate = (truth[-1] - truth[-2]) * 50.0
    assert msgs[-1].twist.twist.angular.z == pytest.approx(true_rate, abs=0.02)
    # The slip adapted: the ICR spread widened (the ground turns the robot less), on ~/icr.
    # ~/icr is published on the node's check timer: the last one after the last step.
    final = (end.icr.y_left, end.icr.y_right)
    assert spin_until(g.executor, lambda: g.icr and abs(g.icr[-1].data[0] - final[0]) < 1e-6,
                      3.0)
    y_left, y_right = g.icr[-1].data[:2]
    assert y_left - y_right > 1.03 * (AURIGA.y_left - AURIGA.y_right)
    assert (y_left, y_right) == pytest.approx((end.icr.y_left, end.icr.y_right), abs=1e-6)
    report = g.report()
    assert report['heading source'] == 'gyro'
    assert float(report['gyro bias (rad/s)']) == pytest.approx(0.02, abs=0.002)
    assert '/imu rate (Hz)' in report and not g.fallbacks()
    # The covariance: finite, PSD, grown in the turns; the twist's too.
    for m in msgs:
        for c in (planar(m.pose.covariance), planar(m.twist.covariance)):
            assert np.all(np.isfinite(c)) and np.linalg.eigvalsh(c).min() > -1e-12
    moving = int(3.5 * 50)
    assert np.trace(planar(msgs[-1].pose.covariance)[:2, :2]) > 10 * np.trace(
        planar(msgs[moving].pose.covariance)[:2, :2])


@pytest.mark.parametrize('fault', ['nan', 'saturated', 'jump', 'stale'])
def test_a_faulty_gyro_falls_back_without_a_jump_and_recovers(graph, fault):
    g = graph({'imu_saturation': 3.0, 'imu_max_jump': 1.0})
    t, left, right, tg, wg = drive(seconds=7.0)
    at = np.searchsorted(tg, T0 + 5.0)
    wg = wg.copy()
    if fault == 'nan':
        wg[at] = math.nan
    elif fault == 'saturated':
        wg[at:at + 3] = 5.0
    elif fault == 'jump':
        wg[at] += 2.0
    else:
        keep = (tg < T0 + 5.0) | (tg > T0 + 6.0)   # one second without a sample (timeout 0.5 s)
        tg, wg = tg[keep], wg[keep]
    seen = []

    def after(s):
        seen.append((s, g.node.odometry.source))
        if g.node.odometry.source == 'encoders' and s > T0 + 5.0 and 'during' not in g.__dict__:
            g.during = g.report()

    msgs = g.feed(t, left, right, tg, wg, after)
    sources = dict(seen)
    assert sources[T0 + 4.9] == 'gyro'
    assert 'encoders' in [src for s, src in seen if T0 + 5.0 < s < T0 + 6.6]
    assert g.during['heading source'] == 'encoders'
    assert g.during['heading source reason'] in {
        'nan': 'the gyro reads a non-finite value', 'saturated': 'the gyro is saturated',
        'jump': 'the gyro jumps', 'stale': 'the gyro is stale'}[fault]
    assert len(g.fallbacks()) == 1
    assert g.node.odometry.source == 'gyro'   # back once healthy
    # No jump: each published step is one encoder step of a slow drive.
    xy = np.array([[m.pose.pose.position.x, m.pose.pose.position.y] for m in msgs])
    assert np.abs(np.diff(xy, axis=0)).max() < 0.012
    assert np.abs(np.diff(yaws(msgs))).max() < 0.03
    assert all(np.all(np.isfinite(planar(m.pose.covariance))) for m in msgs)


def test_an_imu_that_appears_late(graph):
    g = graph()
    t, left, right, tg, wg = drive(seconds=9.0, still=5.0)
    late = tg >= T0 + 1.0
    seen = []
    g.feed(t, left, right, tg[late], wg[late],
           lambda s: seen.append((s, g.node.odometry.source, g.node.odometry.reason)))
    first = {s: (src, why) for s, src, why in seen}
    assert first[T0 + 0.5] == ('encoders', 'no gyro sample yet')
    assert g.node.odometry.source == 'gyro' and not g.fallbacks()


def test_without_imu_topic_the_output_is_today_s(graph):
    """imu_topic '' (the default): today's Odometry, bit for bit, with its covariance."""
    for overrides in (TRACKS_ONLY, {}):
        g = graph({'imu_topic': '', **overrides})
        assert g.node.imu is None and isinstance(g.node.odometry, Odometry)
        steps = []
        update = g.node.odometry.update

        def recording(*args, update=update):
            steps.append(args)
            return update(*args)

        g.node.odometry.update = recording
        t, left, right, _, _ = drive(seconds=5.0, still=1.0)
        msgs = g.feed(t, left, right)
        today = Odometry(AURIGA, TrackNoise())
        for m, step in zip(msgs, steps):
            assert today.update(*step)
            twist, covariance = today.take_twist()
            x, y, theta = today.pose
            assert (m.pose.pose.position.x, m.pose.pose.position.y) == (x, y)
            assert (m.twist.twist.linear.x, m.twist.twist.linear.y,
                    m.twist.twist.angular.z) == twist
            if overrides:
                # Per message: the 1-s mean's covariance over the step's interval (dt).
                assert tuple(planar(m.twist.covariance)[np.triu_indices(3)]) == \
                    message_twist_covariance(covariance, step[-1])
                assert tuple(planar(m.pose.covariance)[np.triu_indices(3)]) == \
                    today.covariance_upper
        g.node.destroy_node()


def test_reset_zeroes_the_pose_and_its_covariance(graph):
    from std_srvs.srv import Trigger
    g = graph()
    t, left, right, tg, wg = drive(seconds=6.0)
    g.feed(t, left, right, tg, wg)
    assert np.trace(planar(g.odom[-1].pose.covariance)) > 1e-3
    client = g.encoders.node.create_client(Trigger, 'odometry_node/reset')
    assert client.wait_for_service(timeout_sec=2.0)
    future = client.call_async(Trigger.Request())
    assert spin_until(g.executor, future.done) and future.result().success
    # Standing still afterwards: the pose zero.
    ts = t[-1] + 0.02 * np.arange(1, 4)
    tgs = tg[-1] + 0.01 * np.arange(1, 7)
    msgs = g.feed(ts, np.full(3, left[-1]), np.full(3, right[-1]), tgs, np.full(6, 0.02))
    m = msgs[-1]
    assert (m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.orientation.z) == (
        0.0, 0.0, 0.0)
    # Reset while it moved: the time error of that start stays published (timing u u^T at
    # the rates of the reset, as evaluate_model's windows count both ends) ...
    assert 0.0 < np.abs(planar(m.pose.covariance)).max() < 1e-2
    # ... and reset again while standing still: pose and covariance zero (no rate, no timing).
    future = client.call_async(Trigger.Request())
    assert spin_until(g.executor, future.done) and future.result().success
    msgs = g.feed(ts + 0.06, np.full(3, left[-1]), np.full(3, right[-1]), tgs + 0.06,
                  np.full(6, 0.02))
    m = msgs[-1]
    assert (m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.orientation.z) == (
        0.0, 0.0, 0.0)
    assert np.abs(planar(m.pose.covariance)).max() < 1e-8


def test_push_to_reaches_a_cmd_vel_translator(ros_context, executor, capfd):
    from tracked_kinematics.ros.cmd_vel_translator import CmdVelTranslator
    translator = CmdVelTranslator(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in VALUES.items()])
    executor.add_node(translator)
    g = Graph(ros_context, executor, capfd, {'push_to': ['cmd_vel_translator'],
                                             'push_period': 0.1, 'push_min_change': 0.002})
    t, left, right, tg, wg = drive()
    g.feed(t, left, right, tg, wg)
    adapted = g.node.odometry.icr

    def pushed():
        return [translator.get_parameter(n).value for n in ('icr.y_left', 'icr.y_right')]

    assert spin_until(executor, lambda: np.allclose(pushed(), [adapted.y_left,
                                                               adapted.y_right], atol=0.003),
                      5.0)
    assert pushed()[0] - pushed()[1] > 1.03 * (AURIGA.y_left - AURIGA.y_right)
    assert translator.get_parameter('icr.x').value == pytest.approx(AURIGA.x)
    assert translator.get_parameter('scale.left').value == pytest.approx(AURIGA.scale_left)
    translator.destroy_node()


@pytest.mark.parametrize('name, value, message', [
    ('imu_timeout', -1.0, 'imu_timeout must be > 0'),
    ('imu_timeout', math.nan, 'imu_timeout must be finite'),
    ('imu_delay', math.inf, 'imu_delay must be finite'),
    ('gyro_scale', 0.0, 'gyro_scale must be > 0'),
    ('imu_saturation', -1.0, 'imu_saturation must be >= 0'),
    ('imu_max_jump', math.nan, 'imu_max_jump must be finite'),
    ('covariance.turn', -1e-3, 'covariance.turn must be >= 0'),
    ('covariance.timing', math.inf, 'covariance.timing must be finite'),
    ('covariance.gyro_noise', -0.1, 'covariance.gyro_noise must be >= 0'),
    ('imu_topic', 'bad topic', 'imu_topic must be a valid ROS name'),
    ('push_to', ['1bad'], 'push_to'),
])
def test_hostile_parameters_are_refused(ros_context, name, value, message):
    with pytest.raises(ParameterError, match=message):
        OdometryNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**VALUES, **WITH_GYRO, name: value}.items()])


def test_hostile_runtime_changes_are_refused(graph):
    g = graph()
    for name, value in (('imu_timeout', -1.0), ('imu_timeout', math.nan),
                        ('imu_topic', 'other'), ('gyro_scale', -1.0)):
        assert not g.node.set_parameters([Parameter(name, value=value)])[0].successful
    assert g.node.set_parameters([Parameter('imu_timeout', value=0.2)])[0].successful
    assert g.node.odometry.config.timeout == 0.2


@pytest.mark.parametrize('frame', ['', 'a', 'imu_link', 'x' * 13])
def test_imu_reader_reads_what_rclpy_reads(frame):
    from rclpy.serialization import serialize_message
    from tracked_kinematics.ros.imu_reader import ImuReader, raw_stamp_key
    reader = ImuReader()
    for z in (0.3, -1.5, math.inf, math.nan):
        msg = imu_msg(12.000000007, z)
        msg.header.frame_id = frame
        msg.angular_velocity.x = 9.0
        msg.orientation_covariance[8] = 4.0
        data = serialize_message(msg)
        for _ in range(2):   # the first by rclpy, the second in place
            stamp_s, rate = reader.read(data)
            # From the origin, the first message's whole seconds.
            assert reader.origin == 12
            assert stamp_s == 7 * 1e-9 and (rate == z or (math.isnan(z) and math.isnan(rate)))
        assert raw_stamp_key(data) == 12_000_000_007
    assert reader.read(b'\x00\x01\x00\x00garbage') is None
    # An epoch stamp keeps its nanoseconds (as a float of the epoch it would not).
    reader = ImuReader()
    reader.origin = 1_700_000_000
    msg = imu_msg(0.0, 0.1)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 1_700_000_012, 250_000_001
    stamp_s, _ = reader.read(serialize_message(msg))
    assert stamp_s == pytest.approx(12.250000001, abs=1e-12)
