"""offline.bag_reader: every storage, encoder kind and ground-truth type; one-line errors."""

import math

from helpers.vehicle_sim import AURIGA, B, simulate, write_bag
import numpy as np
import pytest
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.offline.bags import (
    BagError, columns, EncoderSource, GroundTruthSource, joint_states, read_recording)

GT = GroundTruthSource('/mocap/pose')


@pytest.fixture(scope='module')
def rec():
    """Drive 20 s: encoders at 50 Hz, ground truth at 10 Hz off the encoder grid."""
    return simulate(ConstantIcr(B), np.array(AURIGA), duration=20.0, enc_rate=50.0,
                    seed=1, gt_phase=0.007)


def bag_path(tmp_path, storage, name='run'):
    return tmp_path / (f'{name}.bag' if storage == 'rosbag1' else name)


def assert_same_recording(got, rec, travel_atol=1e-9):
    # Times are relative to the first encoder sample; travel up to a constant offset.
    t0 = rec.enc_t[0]
    np.testing.assert_allclose(got.enc_t, rec.enc_t - t0, atol=2e-9)
    np.testing.assert_allclose(got.left - got.left[0], rec.left - rec.left[0], atol=travel_atol)
    np.testing.assert_allclose(got.right - got.right[0], rec.right - rec.right[0],
                               atol=travel_atol)
    np.testing.assert_allclose(got.gt_t, rec.gt_t - t0, atol=2e-9)
    np.testing.assert_allclose(np.stack([got.gt_x, got.gt_y]), np.stack([rec.gt_x, rec.gt_y]),
                               atol=1e-12)
    np.testing.assert_allclose(np.angle(np.exp(1j * (got.gt_yaw - rec.gt_yaw))), 0, atol=1e-12)


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap', 'rosbag1'])
def test_joint_positions_in_every_storage(tmp_path, rec, storage):
    path = bag_path(tmp_path, storage)
    write_bag(path, rec, storage)
    got = read_recording(path, EncoderSource(), ground_truth=GT)
    assert_same_recording(got, rec)
    assert got.name == str(path)


@pytest.mark.parametrize('storage', ['sqlite3', 'rosbag1'])
def test_fast_path_equals_deserialising_every_message(tmp_path, rec, storage, monkeypatch):
    path = bag_path(tmp_path, storage)
    write_bag(path, rec, storage)
    fast = read_recording(path, EncoderSource(), ground_truth=GT)
    monkeypatch.setattr(joint_states._Layout, 'of', classmethod(lambda cls, raw, ros2: None))
    slow = read_recording(path, EncoderSource(), ground_truth=GT)
    for name in ('enc_t', 'left', 'right', 'gt_t', 'gt_x', 'gt_y', 'gt_yaw'):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))


@pytest.mark.parametrize('ground_truth', ['pose_with_covariance', 'odometry', 'tf'])
def test_ground_truth_types(tmp_path, rec, ground_truth):
    path = bag_path(tmp_path, 'mcap')
    write_bag(path, rec, 'mcap', ground_truth=ground_truth)
    source = GroundTruthSource('/tf', parent_frame='map') if ground_truth == 'tf' else GT
    assert_same_recording(read_recording(path, EncoderSource(), ground_truth=source), rec)


def test_tf_without_parent_takes_the_only_one(tmp_path, rec):
    path = bag_path(tmp_path, 'rosbag1')
    write_bag(path, rec, 'rosbag1', ground_truth='tf')
    assert_same_recording(read_recording(path, EncoderSource(),
                                         ground_truth=GroundTruthSource('/tf')), rec)
    with pytest.raises(BagError, match=r'ground-truth transforms odom -> base_link on /tf; '
                       r'transforms present: map -> base_link'):
        read_recording(path, EncoderSource(),
                       ground_truth=GroundTruthSource('/tf', parent_frame='odom'))


def test_tf_with_two_parents_asks_which(tmp_path):
    from tracked_kinematics.offline.bags import BagWriter
    path = tmp_path / 'two'
    with BagWriter(path, 'sqlite3') as bag:
        for k in range(5):
            t = 10**18 + k * 10**8
            bag.write('/joint_states', t, bag.joint_state(
                t, ['left_sprocket_joint', 'right_sprocket_joint'], [k, k]))
            bag.write('/tf', t, bag.tf_message(t, 'map', 'base_link', k, 0, 0))
            bag.write('/tf', t, bag.tf_message(t, 'odom', 'base_link', k, 0, 0))
    with pytest.raises(BagError, match='several transforms to base_link on /tf .map, odom are '
                       'parents.; choose one with --ground-truth-parent-frame'):
        read_recording(path, EncoderSource(), ground_truth=GroundTruthSource('/tf'))
    got = read_recording(path, EncoderSource(),
                         ground_truth=GroundTruthSource('/tf', parent_frame='/odom'))
    assert len(got.gt_t) == 5


def test_joint_velocities(tmp_path, rec):
    path = bag_path(tmp_path, 'sqlite3')
    write_bag(path, rec, 'sqlite3', encoder='velocities')
    got = read_recording(path, EncoderSource(), ground_truth=GT)
    # Trapezoidal travel of sampled speeds: close to, not equal to, the true travel.
    assert_same_recording(got, rec, travel_atol=0.05)
    np.testing.assert_allclose(np.diff(got.left), np.diff(rec.left), atol=2e-3)


@pytest.mark.parametrize('encoder, mode, atol', [('speeds', 'track_speeds', 0.05),
                                                 ('ticks', 'encoder_ticks', 2e-4)])
def test_per_side_topics(tmp_path, rec, encoder, mode, atol):
    path = bag_path(tmp_path, 'mcap')
    write_bag(path, rec, 'mcap', encoder=encoder)
    topics = {'track_speeds': ('/left_track/speed', '/right_track/speed'),
              'encoder_ticks': ('/left_track/ticks', '/right_track/ticks')}[mode]
    got = read_recording(path, EncoderSource(mode=mode, left_topic=topics[0],
                                             right_topic=topics[1]), ground_truth=GT)
    assert_same_recording(got, rec, travel_atol=atol)


def test_ground_truth_offset_moves_to_base_link(tmp_path, rec):
    # The mocap body sits 0.3 m ahead of and 0.1 m left of base_link, turned by 0.5 rad.
    ox, oy, oyaw = 0.3, 0.1, 0.5
    c, s = np.cos(rec.gt_yaw), np.sin(rec.gt_yaw)
    body = type(rec)(rec.enc_t, rec.left, rec.right, rec.gt_t, rec.gt_x + c * ox - s * oy,
                     rec.gt_y + s * ox + c * oy, np.angle(np.exp(1j * (rec.gt_yaw + oyaw))))
    path = bag_path(tmp_path, 'mcap')
    write_bag(path, body, 'mcap')
    got = read_recording(path, EncoderSource(),
                         ground_truth=GroundTruthSource('/mocap/pose', offset=(ox, oy, oyaw)))
    assert_same_recording(got, rec)


def test_missing_bag(tmp_path):
    with pytest.raises(BagError, match='^bag not found: .*nowhere$'):
        read_recording(tmp_path / 'nowhere', EncoderSource(), ground_truth=GT)


def test_missing_topic_lists_the_topics(tmp_path, rec):
    path = bag_path(tmp_path, 'mcap')
    write_bag(path, rec, 'mcap')
    with pytest.raises(BagError, match=r'no topic /vicon for the ground truth; topics present: '
                       r'/joint_states \(sensor_msgs/msg/JointState\), /mocap/pose'):
        read_recording(path, EncoderSource(), ground_truth=GroundTruthSource('/vicon'))
    with pytest.raises(BagError, match='topic /mocap/pose has type geometry_msgs/msg/PoseStamped;'
                       ' the encoders must be sensor_msgs/msg/JointState'):
        read_recording(path, EncoderSource(topic='/mocap/pose'), ground_truth=GT)


def test_unknown_joint_lists_the_names(tmp_path, rec):
    path = bag_path(tmp_path, 'sqlite3')
    write_bag(path, rec, 'sqlite3')
    with pytest.raises(BagError, match='joint left_wheel not in /joint_states; joint names '
                       'present: left_sprocket_joint, right_sprocket_joint'):
        read_recording(path, EncoderSource(left_joints=('left_wheel',)), ground_truth=GT)


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap', 'rosbag1'])
def test_truncated_bag_is_a_one_line_error(tmp_path, rec, storage):
    path = bag_path(tmp_path, storage)
    write_bag(path, rec, storage)
    if storage == 'rosbag1':
        data = path
    else:
        data = next(p for p in path.iterdir() if p.suffix in ('.db3', '.mcap'))
    data.write_bytes(data.read_bytes()[:len(data.read_bytes()) // 2])
    with pytest.raises(BagError) as err:
        read_recording(path, EncoderSource(), ground_truth=GT)
    message = str(err.value)
    assert '\n' not in message
    assert message.startswith(f'cannot read bag {path}') or 'fewer than' in message


def test_garbage_file_is_a_one_line_error(tmp_path):
    path = tmp_path / 'junk.bag'
    path.write_bytes(b'not a bag at all' * 10)
    with pytest.raises(BagError,
                       match=r'^cannot read bag .*junk.bag: .*\(truncated or corrupt\?\)$'):
        read_recording(path, EncoderSource(), ground_truth=GT)


def test_quaternion_yaw():
    class Q:
        def __init__(self, yaw):
            self.x, self.y, self.z, self.w = 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)
    for yaw in (-3.0, -0.5, 0.0, 1.2, 3.1):
        assert columns.quaternion_yaw(Q(yaw)) == pytest.approx(yaw)


def test_a_topic_of_the_wrong_type_is_one_grammatical_line():
    # Issue 31: "the IMU need sensor_msgs/msg/Imu".
    from types import SimpleNamespace
    from tracked_kinematics.offline.bags.opening import topic_connections
    reader = SimpleNamespace(connections=[SimpleNamespace(topic='/imu', msgtype='std_msgs/msg/X')])
    with pytest.raises(BagError) as raised:
        topic_connections(reader, 'run1', '/imu', ('sensor_msgs/msg/Imu',), 'IMU')
    assert str(raised.value) == ('run1: topic /imu has type std_msgs/msg/X; the IMU must be '
                                 'sensor_msgs/msg/Imu')
