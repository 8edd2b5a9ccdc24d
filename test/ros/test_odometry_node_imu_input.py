"""
odometry_node's IMU intake on real topics (issue 35 items 3 and 5).

Mountings (z down, NED, x up) right with ``imu_mount.*``; the heading's rate from the
orientation on a slope; a typo'd, mistyped or wrong-clock ``imu_topic`` a WARN with its reason
within seconds; memory flat with silent encoders; a 2038 stamp that does not shut the gyro out.
"""

import math
import time
import tracemalloc

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from helpers.encoder_stream import joint_state, stamp
from helpers.gyro_drive import gyro_drive, true_heading
from helpers.ros_helpers import spin_until
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64
from test_odometry_node_imu import AURIGA, Graph as OdometryGraph, VALUES, WITH_GYRO, yaws
from tracked_kinematics.core.gyro import replay
from tracked_kinematics.params import gyro_config_from_values
from tracked_kinematics.ros.imu_input import CLOCK_WINDOW, HELD
from tracked_kinematics.ros.odometry_node import OdometryNode

pytestmark = pytest.mark.ros

T0 = 10.0
SLIP = 0.8    # gyro_drive's: the ground turns the robot 0.8 times what the model says


def imu(t, omega=(0.0, 0.0, 0.0), quaternion=None, frame=''):
    """Return an Imu at ``t``: rates in its frame, an orientation (x, y, z, w) or none (-1)."""
    msg = Imu()
    msg.header.stamp = stamp(t)
    msg.header.frame_id = frame
    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = map(float, omega)
    if quaternion is None:
        msg.orientation_covariance[0] = -1.0
        msg.orientation.w = 0.0
    else:
        (msg.orientation.x, msg.orientation.y, msg.orientation.z,
         msg.orientation.w) = map(float, quaternion)
    return msg


class Graph(OdometryGraph):
    """test_odometry_node_imu's graph, also recording the node's /diagnostics status."""

    def __init__(self, ros_context, executor, capfd, overrides=None):
        super().__init__(ros_context, executor, capfd, overrides)
        self.statuses = []
        self.encoders.node.create_subscription(
            DiagnosticArray, '/diagnostics',
            lambda msg: self.statuses.extend(s for s in msg.status
                                             if s.name == 'odometry_node: health'), 10)

    def warned(self, text):
        """Return whether /diagnostics said WARN (or worse) with ``text``."""
        return any(s.level >= DiagnosticStatus.WARN and text in s.message
                   for s in self.statuses)


@pytest.fixture
def graph(ros_context, executor, capfd):
    made = []

    def make(overrides=None):
        made.append(Graph(ros_context, executor, capfd, overrides))
        return made[-1]
    yield make
    for g in made:
        g.node.destroy_node()


def drive(**kwargs):
    """Return a gyro_drive: encoder streams, the gyro's times and the true body rate there."""
    t, left, right, tg, reading = gyro_drive(
        AURIGA, **{'seconds': 8.0, 'still': 3.5, 'gyro_rate': 100.0, **kwargs})
    _, _, _, _, rate = gyro_drive(AURIGA, **{'seconds': 8.0, 'still': 3.5, 'gyro_rate': 100.0,
                                             'bias': 0.0, 'scale': 1.0, 'noise': 0.0,
                                             **kwargs})
    return T0 + t, left, right, T0 + tg, reading, rate


def yaw_quaternion(angle):
    return (0.0, 0.0, math.sin(0.5 * angle), math.cos(0.5 * angle))


# Mountings: (imu_mount roll, pitch, yaw), the Imu of a reading r (rad/s about base z) and of
# the true heading psi (ENU).
MOUNTINGS = {
    # Upside down, no orientation: z down reads -r.
    'z_down': ((math.pi, 0.0, 0.0), lambda r, psi: ((0.0, 0.0, -r), None)),
    # NED: x forward, y right, z down, its orientation in NED (heading pi/2 - psi).
    'ned': ((math.pi, 0.0, 0.0),
            lambda r, psi: ((0.0, 0.0, -r), yaw_quaternion(0.5 * math.pi - psi))),
    # Upside down with its orientation in ENU (REP-145): Rz(psi) Rx(pi).
    'z_down_enu': ((math.pi, 0.0, 0.0),
                   lambda r, psi: ((0.0, 0.0, -r), tuple(
                       (Rotation.from_euler('z', psi) * Rotation.from_euler('x', math.pi))
                       .as_quat()))),
    # On its side: its x axis up (pitch -pi/2), no orientation.
    'x_up': ((0.0, -0.5 * math.pi, 0.0), lambda r, psi: ((r, 0.0, 0.0), None)),
    # NED, a one-axis gyro: NaN on x and y (before: 0 * NaN, every sample refused).
    'ned_z_only': ((math.pi, 0.0, 0.0),
                   lambda r, psi: ((math.nan, math.nan, -r), yaw_quaternion(0.5 * math.pi - psi))),
}


@pytest.mark.parametrize('mounting', sorted(MOUNTINGS))
def test_a_mounted_imu_is_right_with_imu_mount(graph, mounting):
    rpy, make = MOUNTINGS[mounting]
    g = graph(dict(zip(('imu_mount.roll', 'imu_mount.pitch', 'imu_mount.yaw'), rpy)))
    t, left, right, tg, reading, _ = drive()
    truth = true_heading(AURIGA, t, left, right)
    psi = np.interp(tg - 0.05, t, truth)
    msgs = g.feed(t, left, right, tg, [imu(s, *make(r, p)) for s, r, p in zip(tg, reading, psi)])
    assert g.node.odometry.source == 'gyro'
    # The truth within 0.03 rad (as an upright IMU: test_odometry_node_imu), where a mirrored
    # heading would be 2 |truth| off.
    assert abs(truth[-1]) > 0.5
    assert abs(yaws(msgs)[-1] - truth[-1]) < 0.03
    assert not g.stderr.warnings('odometry_node', 'heading from the encoders until')


def test_the_heading_rate_on_a_slope_comes_from_the_orientation(graph):
    """On a 20-deg slope the heading turns cos(20 deg) as fast as the body along the contour."""
    g = graph()
    t, left, right, tg, reading, rate = drive()
    slope, alpha0 = math.radians(20.0), 0.43   # it turns by -0.85 rad: across the contour
    # The body turns about the slope's normal: alpha about its z axis, from alpha0.
    alpha = alpha0 + np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1])
                                                      * np.diff(tg))])
    tilt = Rotation.from_euler('x', slope)
    quats = (tilt * Rotation.from_euler('z', alpha[:, None])).as_quat()
    # The heading: the direction of base x projected on the horizontal plane.
    psi = np.unwrap(np.arctan2(np.sin(alpha) * math.cos(slope), np.cos(alpha)))
    msgs = g.feed(t, left, right, tg, [imu(s, (0.0, 0.0, r), q)
                                       for s, r, q in zip(tg, reading, quats)])
    assert g.node.odometry.source == 'gyro'
    got = yaws(msgs)
    at = tg - 0.05   # the gyro's true times (it is stamped 0.05 s late)
    truth = np.interp(t[1:], at, psi - psi[0])
    body = np.interp(t[1:], at, alpha - alpha0)
    # The body z rate integrated is off by 2.6 deg at the end. The node fuses the gyro with
    # the tracks (which turn with the body: on a slope they agree with the body rate), so its
    # heading is not the gyro's alone: compare it with the same node fed the body rate only.
    err = np.abs(got - truth)
    assert abs(body[-1] - truth[-1]) > math.radians(2.5)
    report = {v.key: v.value for v in g.node.health.report().values}
    assert report['imu heading rate'] == 'from the orientation (tilt corrected)'
    # The node fed the body rate is core.gyro.replay() of it (test_odometry_node_imu).
    ns = (lambda times: np.round(np.asarray(times) * 1e9) * 1e-9)
    poses, _, _ = replay(ns(t), left, right, ns(tg), reading, AURIGA,
                         gyro_config_from_values(g.node.params.values))
    err_plain = np.abs(poses[1:, 2] - truth)
    # Measured: 0.57 deg with the orientation, 2.0 deg with the body rate.
    assert err[-1] < math.radians(0.8) and err[-1] < 0.4 * err_plain[-1], (
        math.degrees(err[-1]), math.degrees(err_plain[-1]))


def test_the_frame_id_through_tf_when_there_is_a_transform(graph):
    """A stand-in for tf2_ros (not on PyPI): the mount of frame_id is TF's; none yet: wait."""
    from geometry_msgs.msg import TransformStamped
    g = graph()
    transform = TransformStamped()
    q = Rotation.from_euler('x', math.pi).as_quat()
    (transform.transform.rotation.x, transform.transform.rotation.y,
     transform.transform.rotation.z, transform.transform.rotation.w) = q
    lookups = []

    class Buffer:
        def lookup_transform(self, target, source, when):
            lookups.append((target, source))
            if source != 'imu_link':
                raise LookupError(f'no frame {source}')
            return transform

    g.node._imu_input._tf_buffer = Buffer
    t, left, right, tg, reading, _ = drive()
    truth = true_heading(AURIGA, t, left, right)
    # Half of them ROS 1 style, '/imu_link' (tf2 refuses a leading slash): the same frame.
    msgs = g.feed(t, left, right, tg, [imu(s, (0.0, 0.0, -r), frame='/imu_link'[k % 2:])
                                       for k, (s, r) in enumerate(zip(tg, reading))])
    assert lookups[0] == ('base_link', 'imu_link') and len(lookups) == 1   # cached
    assert abs(yaws(msgs)[-1] - truth[-1]) < 0.03
    report = {v.key: v.value for v in g.node.health.report().values}
    assert report['imu frame'] == 'TF (imu_link)'
    # Another frame without a transform: its samples wait, and say why.
    g.feed(t[-1] + 0.02 * np.arange(1, 4), np.full(3, left[-1]), np.full(3, right[-1]),
           tg[-1] + 0.01 * np.arange(1, 4), [imu(tg[-1] + 0.01 * k, frame='other')
                                             for k in range(1, 4)])
    assert g.stderr.warnings('odometry_node', "no transform from 'other' to 'base_link'")


def pump(g, until, timeout=10.0, imu_stamp=lambda s: s, imu_topic='imu', imu_msg=None):
    """
    Drive on, standing still, until ``until()`` or ``timeout`` s; return ``until()``.

    The encoders at 50 Hz and the IMU at 100 Hz of the steady clock (as real drivers publish),
    stamped from T0; ``imu_stamp`` maps the encoders' time to the IMU's.
    """
    start = time.monotonic()
    deadline = start + timeout
    k = 0
    while time.monotonic() < deadline:
        if until():
            return True
        tick = start + 0.02 * k
        spin_until(g.executor, lambda: time.monotonic() >= tick, 1.0)
        s = T0 + 0.02 * k
        k += 1
        g.encoders.send(joint_state(s, [0.0, 0.0]))
        if imu_topic is not None:
            for ds in (0.0, 0.01):
                msg = imu(imu_stamp(s + ds), (0.0, 0.0, 0.01)) if imu_msg is None \
                    else imu_msg(imu_stamp(s + ds))
                g.imu.publisher(type(msg), imu_topic).publish(msg)
    return bool(until())


@pytest.fixture
def foreign_publisher(ros_domain):
    """Publish a std_msgs/Float64 on /imu from a participant of its own (types differ)."""
    import rclpy
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=ros_domain)
    node = rclpy.create_node('float_publisher', context=context)
    node.create_publisher(Float64, 'imu', 10)
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def no_rate(t):
    """Return an Imu at ``t`` that says it has no angular velocity (an orientation only)."""
    msg = imu(t, quaternion=(0.0, 0.0, 0.0, 1.0))
    msg.angular_velocity_covariance[0] = -1.0
    return msg


@pytest.mark.parametrize('case, reason', [
    ('typo', 'no publisher'),
    ('wrong_type', 'its publishers are of another type (std_msgs/msg/Float64)'),
    ('other_clock', "s from the encoders' time"),
    ('garbage', 'every sample refused by the odometry (the gyro reads a non-finite value)'),
    # Before: fused at standstill, then refused as 'the yaw rate on another axis'.
    ('no_rate', 'samples without an angular velocity (their angular_velocity_covariance[0] '
     'is -1'),
    # Before: '... refused by the odometry (the gyro restarts (a gap, or time went back))'.
    ('frozen', 'every sample refused by the odometry (a gyro stamp not after the last one'),
])
def test_an_imu_topic_without_a_usable_sample_warns_with_the_reason(
        graph, case, reason, request):
    if case == 'wrong_type':
        request.getfixturevalue('foreign_publisher')
    g = graph({'imu_topic': 'imu_typo' if case == 'typo' else 'imu'})
    kwargs = {
        'typo': {'imu_topic': None},       # subscribed on /imu_typo, which nobody publishes
        'wrong_type': {'imu_topic': None},
        'other_clock': {'imu_stamp': lambda s: s + 1.7e9},
        'garbage': {'imu_msg': lambda s: imu(s, (0.0, 0.0, math.nan))},
        'no_rate': {'imu_msg': no_rate},
        'frozen': {'imu_stamp': lambda s: T0 + 0.5},   # a driver that never advances it
    }[case]
    started = time.monotonic()
    assert pump(g, lambda: g.warned(reason), **kwargs), [s.message for s in g.statuses[-3:]]
    # Within seconds: the grace (3 s) and one update.
    assert time.monotonic() - started < 8.0
    assert g.stderr.warnings('odometry_node', 'no usable gyro sample')
    assert g.node.odometry.source == 'encoders'


def test_a_healthy_imu_raises_no_warn(graph):
    g = graph()
    assert not pump(g, lambda: g.warned('no usable gyro sample'), timeout=5.0)
    assert g.statuses and g.statuses[-1].level == DiagnosticStatus.OK
    assert g.node._imu_input.counts['used'] > 100


def test_without_imu_topic_the_status_is_ok(graph):
    """docs/diagnostics.md once said WARN: the heading is the encoders', which is no fault."""
    g = graph({'imu_topic': ''})
    assert pump(g, lambda: g.statuses, imu_topic=None)
    assert g.statuses[-1].level == DiagnosticStatus.OK
    values = {v.key: v.value for v in g.statuses[-1].values}
    assert values['heading source reason'] == 'imu_topic is empty'


def test_another_clock_is_not_buffered(graph):
    g = graph()
    assert pump(g, lambda: g.node._imu_input.counts['clock'] > 200,
                imu_stamp=lambda s: s + 1.7e9)
    assert g.node._imu_input.counts['used'] == 0
    assert g.stderr.warnings('odometry_node', "from the encoders' time (beyond 10 s after "
                             'imu_delay): another clock')


def flood(g, stamps, rate_z=0.01, chunk=200):
    """Publish Imu samples at ``stamps`` as fast as the node takes them; return how many did."""
    if 'flood' not in g.imu.publishers:
        pub = g.imu.node.create_publisher(Imu, 'imu', QoSProfile(
            depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        assert spin_until(g.executor, lambda: pub.get_subscription_count() > 0)
        g.imu.publishers['flood'] = pub
    pub = g.imu.publishers['flood']
    for i in range(0, len(stamps), chunk):
        before = g.node.imu.count.count
        part = stamps[i:i + chunk]
        for s in part:
            pub.publish(imu(s, (0.0, 0.0, rate_z)))

        def drained(target=before + len(part)):
            # What the node does at an encoder step (drain the IMU's queue), without the
            # executor's turn per message: a minute at 400 Hz in seconds.
            g.node._take_imu()
            return g.node.imu.count.count >= target
        # Each chunk taken before the next, however loaded the machine (on the condition).
        spin_until(g.executor, drained, 60.0)
    return g.node.imu.count.count


def test_memory_is_flat_at_400_hz_with_silent_encoders(graph):
    """A simulated minute of a 400-Hz IMU after the encoders stopped: nothing piles up."""
    g = graph()
    t = T0 + 0.02 * np.arange(50)
    g.feed(t, np.zeros(50), np.zeros(50), t[::2] + 0.005,
           [imu(s + 0.005, (0.0, 0.0, 0.01)) for s in t[::2]])
    stamps = t[-1] + np.arange(1, 60 * 400 + 1) / 400.0
    third = len(stamps) // 3
    received = flood(g, stamps[:third])
    tracemalloc.start()
    try:
        received = flood(g, stamps[third:2 * third])
        first = tracemalloc.take_snapshot()
        received = flood(g, stamps[2 * third:])
        second = tracemalloc.take_snapshot()
    finally:
        tracemalloc.stop()
    assert received >= 0.95 * len(stamps)
    # Where IMU samples are kept (the whole package counted what other threads of this
    # process allocate too: 55 kB once in a loaded suite, none alone).
    ours = [tracemalloc.Filter(True, f'*tracked_kinematics/{name}')
            for name in ('ros/imu_*.py', 'core/gyro/*.py', 'ros/odometry_node.py')]
    grown = sum(stat.size_diff for stat in second.filter_traces(ours).compare_to(
        first.filter_traces(ours), 'filename'))
    # 8000 samples buffered would be over 0.3 MB at 36 B each (a float); the intake keeps at
    # most CLOCK_WINDOW s.
    assert grown < 100_000, grown
    counts = g.node._imu_input.counts
    assert counts['used'] <= (CLOCK_WINDOW + 0.2) * 400 + 25
    # The rest dropped, but for the last HELD samples, held for an encoder step.
    assert counts['waiting'] + counts['clock'] >= len(stamps) - counts['used'] - HELD


def test_a_sample_stamped_in_2038_does_not_shut_the_gyro_out(graph):
    g = graph()
    t, left, right, tg, reading, _ = drive()
    msgs = [imu(s, (0.0, 0.0, r)) for s, r in zip(tg, reading)]
    at = int(np.searchsorted(tg, T0 + 5.0))
    wild = imu(0.0, (0.0, 0.0, reading[at]))
    wild.header.stamp.sec, wild.header.stamp.nanosec = 2**31 - 1, 0   # 2038-01-19
    seen = []
    odom = g.feed(t, left, right, np.insert(tg, at, tg[at] - 1e-4), msgs[:at] + [wild]
                  + msgs[at:], lambda s: seen.append((s, g.node.odometry.source)))
    assert dict(seen)[T0 + 4.9] == 'gyro'
    # The gyro is used again (it never stopped): no sample after the wild one was refused.
    assert all(source == 'gyro' for s, source in seen if s > T0 + 5.0)
    truth = true_heading(AURIGA, t, left, right)
    assert abs(yaws(odom)[-1] - truth[-1]) < 0.03
    assert g.stderr.warnings('odometry_node', "s from the encoders' time")
    assert g.node._imu_input.counts['clock'] == 1


@pytest.mark.parametrize('frame', ['', 'a', 'imu_link', 'x' * 13])
def test_read_sample_reads_what_rclpy_reads(frame):
    from rclpy.serialization import serialize_message
    from tracked_kinematics.ros.imu_reader import ImuReader
    reader = ImuReader()
    for omega, quaternion in (((0.1, -0.2, 0.3), (0.1, 0.2, 0.3, 0.9)),
                              ((math.nan, 1e300, -0.0), None), ((4.0, 5.0, 6.0), (0, 0, 0, 0))):
        msg = imu(12.000000007, omega, quaternion, frame)
        data = serialize_message(msg)
        for _ in range(2):   # the first by rclpy, the second in place
            sample = reader.read_sample(data)
            assert sample.stamp_ns == 12_000_000_007 and sample.frame_id == frame
            np.testing.assert_array_equal(sample.omega, omega)
            assert sample.has_orientation == (quaternion is not None)
            if quaternion is not None:
                np.testing.assert_array_equal(sample.quaternion, quaternion)
        assert len(reader._starts) == 1
        assert sample.has_rate
    for _ in range(2):
        assert not reader.read_sample(serialize_message(no_rate(12.0))).has_rate
    assert reader.read_sample(b'\x00\x01\x00\x00garbage') is None


@pytest.mark.parametrize('name, value, message', [
    ('imu_mount.roll', math.nan, 'imu_mount.roll must be finite'),
    ('imu_mount.pitch', 7.0, r'imu_mount.pitch .*\[-6.28'),
    ('imu_mount.yaw', 'pi', 'imu_mount.yaw'),
])
def test_hostile_mounts_are_refused(ros_context, name, value, message):
    from tracked_kinematics.ros.parameters import ParameterError
    with pytest.raises(ParameterError, match=message):
        OdometryNode(context=ros_context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {**VALUES, **WITH_GYRO, name: value}.items()])


def test_a_mount_changed_at_runtime_is_used(graph):
    g = graph()
    assert g.node.set_parameters([Parameter('imu_mount.roll', value=math.pi)])[0].successful
    assert not g.node.set_parameters([Parameter('imu_mount.yaw', value=math.inf)])[0].successful
    t, left, right, tg, reading, _ = drive()
    truth = true_heading(AURIGA, t, left, right)
    msgs = g.feed(t, left, right, tg, [imu(s, (0.0, 0.0, -r)) for s, r in zip(tg, reading)])
    assert abs(yaws(msgs)[-1] - truth[-1]) < 0.03
