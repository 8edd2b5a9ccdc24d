"""BagWriter: what it writes, rosbags reads back, in every storage."""

import math

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.offline.bags.writer import BagWriter


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap', 'rosbag1'])
def test_round_trip(tmp_path, storage):
    path = tmp_path / ('run.bag' if storage == 'rosbag1' else 'run')
    with BagWriter(path, storage) as bag:
        for k in range(5):
            t = 1_700_000_000_000_000_000 + k * 10_000_000
            bag.write('/joint_states', t, bag.joint_state(
                t, ['left_sprocket_joint', 'right_sprocket_joint'], [0.1 * k, 0.2 * k]))
            bag.write('/mocap', t, bag.pose_stamped(t, 1.0 * k, -0.5, 0.3))
            bag.write('/odom', t, bag.odometry(t, 0.0, 0.0, -0.2, v_x=0.5, w=0.1))
            bag.write('/tf', t, bag.tf_message(t, 'map', 'base_link', 2.0, 3.0, 1.0))
            bag.write('/left', t, bag.float64(0.25))
            bag.write('/ticks', t, bag.int32(2**31 + k))
    with AnyReader([path]) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics['/joint_states'] == 'sensor_msgs/msg/JointState'
        assert topics['/tf'] == 'tf2_msgs/msg/TFMessage'
        msgs = {}
        for conn, t, raw in reader.messages():
            msgs.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    js = msgs['/joint_states'][3]
    assert list(js.name) == ['left_sprocket_joint', 'right_sprocket_joint']
    np.testing.assert_allclose(js.position, [0.3, 0.6])
    assert js.header.stamp.nanosec == 30_000_000
    pose = msgs['/mocap'][2].pose
    assert (pose.position.x, pose.position.y) == (2.0, -0.5)
    assert 2 * math.atan2(pose.orientation.z, pose.orientation.w) == pytest.approx(0.3)
    assert msgs['/odom'][0].twist.twist.linear.x == 0.5
    assert msgs['/tf'][0].transforms[0].child_frame_id == 'base_link'
    assert msgs['/left'][0].data == 0.25
    assert msgs['/ticks'][0].data == -2**31  # a 32-bit counter wraps


def test_unknown_storage(tmp_path):
    with pytest.raises(ValueError, match='storage must be one of'):
        BagWriter(tmp_path / 'x', 'parquet')


@pytest.mark.parametrize('storage', ['mcap', 'rosbag1'])
def test_the_writers_of_a_ros_version_share_its_typestore(tmp_path, storage):
    # The serialisers a typestore generates are made once per process, not once per bag.
    suffix = '.bag' if storage == 'rosbag1' else ''
    paths = [tmp_path / f'a{suffix}', tmp_path / f'b{suffix}']
    writers = [BagWriter(p, storage) for p in paths]
    assert writers[0].typestore is writers[1].typestore
    for k, (writer, path) in enumerate(zip(writers, paths)):
        with writer as bag:
            bag.write('/tf', 5, bag.tf_message(5, 'map', 'base_link', 1.0 + k, 0.0, 0.0))
        with AnyReader([path]) as reader:
            (conn, _, raw), = reader.messages()
            msg = reader.deserialize(raw, conn.msgtype)
        assert msg.transforms[0].transform.translation.x == 1.0 + k
