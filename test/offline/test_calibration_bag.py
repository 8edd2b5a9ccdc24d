"""The calibration drive's bag: the rows it recorded come back exactly, stamps to the ns."""

from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.recording import from_stamped_rows
from tracked_kinematics.offline.calibration_files import write_bag

T0 = 1_733_200_000_123_456_789   # an epoch stamp: int64 ns beyond a double's integers
RADIUS = 0.3


def rows(kind, seed=7):
    rng = np.random.default_rng(seed)
    enc_t = T0 + np.cumsum(rng.integers(9_000_000, 11_000_000, 2000))
    travel = np.cumsum(rng.normal(0.01, 0.003, (2000, 2)), axis=0)
    out = {'encoder': [(int(t), *map(float, v)) for t, v in zip(enc_t, travel)],
           'pose': [], 'imu': [],
           'cmd': [(int(t), *map(float, rng.normal(size=2)))
                   for t in T0 + 777 + np.cumsum(rng.integers(40_000_000, 60_000_000, 400))]}
    if kind == 'pose':   # starts before the encoders: time 0 is the earliest stamp
        out['pose'] = [(int(t), *map(float, rng.normal(size=3)))
                       for t in T0 - 5_000_001 + np.cumsum(rng.integers(9e7, 11e7, 200))]
    else:
        q = rng.normal(size=(3000, 4))
        q /= np.linalg.norm(q, axis=1)[:, None]
        out['imu'] = [(int(t), float(r), *map(float, qq), float(c)) for t, r, qq, c in zip(
            T0 + 1234 + np.cumsum(rng.integers(4_000_000, 6_000_000, 3000)),
            rng.normal(size=3000), q, rng.choice([-1.0, 0.01], 3000))]
    return out


def decoded(path):
    """Rows ``(stamp, values...)`` per topic, as the bag holds them."""
    out = {}
    with AnyReader([Path(path)]) as reader:
        for conn, stamp, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.msgtype == 'sensor_msgs/msg/JointState':
                values = tuple(float(p) for p in msg.position)
            elif conn.msgtype == 'nav_msgs/msg/Odometry':
                p, q = msg.pose.pose.position, msg.pose.pose.orientation
                values = (p.x, p.y, q.z, q.w)
            elif conn.msgtype == 'sensor_msgs/msg/Imu':
                q = msg.orientation
                values = (msg.angular_velocity.z, q.x, q.y, q.z, q.w,
                          float(msg.orientation_covariance[0]))
            else:
                values = (msg.linear.x, msg.angular.z)
            header = getattr(msg, 'header', None)
            if header is not None:
                assert header.stamp.sec * 10**9 + header.stamp.nanosec == stamp
            out.setdefault(conn.topic, []).append((stamp, *values))
    return out


@pytest.mark.parametrize('kind', ['pose', 'imu'])
def test_the_bag_holds_the_recorded_rows(tmp_path, kind):
    recorded = rows(kind)
    recording = from_stamped_rows(**recorded)
    topics = {'joint_states': '/r/joint_states', 'joint_names': ['l', 'r'], 'reference': '/ref',
              'reference_kind': kind, 'cmd_vel': '/cmd_vel'}
    write_bag(tmp_path / 'bag', recording, topics, RADIUS)
    bag = decoded(tmp_path / 'bag')
    assert bag['/r/joint_states'] == [(t, left / RADIUS, right / RADIUS)
                                      for t, left, right in recorded['encoder']]
    assert bag['/cmd_vel'] == recorded['cmd']
    if kind == 'imu':
        assert bag['/ref'] == recorded['imu']
    else:
        assert [row[0] for row in bag['/ref']] == [row[0] for row in recorded['pose']]
        assert [row[1:3] for row in bag['/ref']] == [row[1:3] for row in recorded['pose']]
        yaw = [np.arctan2(2 * w * z, 1 - 2 * z * z) for *_, z, w in bag['/ref']]
        np.testing.assert_allclose(yaw, [row[3] for row in recorded['pose']], atol=1e-12)


def test_rows_out_of_order_are_sorted_and_the_first_of_a_stamp_kept():
    recording = from_stamped_rows(encoder=[(T0, 0.0, 0.0), (T0 + 10, 0.1, 0.1)],
                                  imu=[(T0 + 5, 0.2, 0, 0, 0, 1, -1.0),
                                       (T0 + 1, 0.1, 0, 0, 0, 1, -1.0),
                                       (T0 + 5, 0.3, 0, 0, 0, 1, -1.0)])
    assert recording.stamps_ns(recording.gyro_t).tolist() == [T0 + 1, T0 + 5]
    assert recording.gyro_rate.tolist() == [0.1, 0.2]
    assert recording.t0_ns == T0 and recording.gt_t is None and recording.cmd_vel_t is None
