"""OdometrySerializer writes the message rclpy would: same size, same fields."""

from hypothesis import given
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from tracked_kinematics.core.covariance import ros_covariance
from tracked_kinematics.ros.odometry_message import OdometrySerializer

number = st.floats(allow_nan=False, allow_infinity=False, width=64)
upper = st.tuples(*[number] * 6)


def reference(frames, sec, nanosec, x, y, qz, qw, pose_cov, twist, twist_cov):
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = frames
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    pose = msg.pose.pose
    pose.position.x, pose.position.y = x, y
    pose.orientation.z, pose.orientation.w = qz, qw
    msg.pose.covariance = ros_covariance(pose_cov)
    (msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z) = twist
    msg.twist.covariance = ros_covariance(twist_cov)
    return msg


@pytest.mark.parametrize('frames', [('odom', 'base_link'), ('o', 'robot_1/base_footprint'),
                                    ('', 'x' * 37)])
@given(st.integers(-2**31, 2**31 - 1), st.integers(0, 999_999_999), number, number, number,
       number, upper, st.tuples(number, number, number), upper)
def test_fields_equal_rclpy_serialisation(frames, sec, nanosec, x, y, qz, qw, pose_cov, twist,
                                          twist_cov):
    values = (sec, nanosec, x, y, qz, qw, pose_cov, twist, twist_cov)
    serializer = OdometrySerializer(*frames)
    data = serializer.serialize(*values)
    expected = reference(frames, *values)
    # Same bytes but for CDR's alignment padding, which carries no value.
    assert len(data) == len(serialize_message(expected))
    assert deserialize_message(data, Odometry) == expected


def test_successive_messages_do_not_leak_values():
    serializer = OdometrySerializer('odom', 'base_link')
    serializer.serialize(1, 2, 3.0, 4.0, 0.6, 0.8, (1.0,) * 6, (5.0, 6.0, 7.0), (2.0,) * 6)
    data = serializer.serialize(9, 8, -1.0, 0.5, 0.0, 1.0, (0.0,) * 6, (0.0, 0.0, 0.1),
                                (0.5,) * 6)
    msg = deserialize_message(data, Odometry)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (9, 8)
    assert (msg.pose.pose.position.x, msg.pose.pose.position.y) == (-1.0, 0.5)
    assert msg.pose.pose.orientation.w == 1.0 and msg.pose.pose.orientation.x == 0.0
    np.testing.assert_array_equal(msg.pose.covariance, ros_covariance((0.0,) * 6))
    np.testing.assert_array_equal(msg.twist.covariance, ros_covariance((0.5,) * 6))
    assert msg.child_frame_id == 'base_link'


frame_text = st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'),
                     max_size=40)


@given(st.tuples(frame_text, frame_text), st.integers(-2**31, 2**31 - 1),
       st.integers(0, 2**32 - 1), number, upper)
def test_any_frame_ids_serialise(frames, sec, nanosec, x, pose_cov):
    # Issue 14 item 4: 'ZZZZ<<<<' (the bytes of the old stamp sentinel) killed the node.
    values = (sec, nanosec, x, -x, 0.6, 0.8, pose_cov, (x, 0.5, -x), pose_cov)
    data = OdometrySerializer(*frames).serialize(*values)
    assert deserialize_message(data, Odometry) == reference(frames, *values)


@pytest.mark.parametrize('frames', [('ZZZZ<<<<', 'base_ZZZZ<<<<'), ('odom_ZZZZ<<<<', 'b'),
                                    ('\u00e9' * 300, '<' * 8 + 'Z' * 4)])
def test_sentinel_like_frames(frames):
    values = (7, 9, 1.0, 2.0, 0.0, 1.0, (1.0,) * 6, (3.0, 4.0, 5.0), (2.0,) * 6)
    for _ in range(20):  # CDR padding is not initialised: a different garbage each time
        data = OdometrySerializer(*frames).serialize(*values)
        assert deserialize_message(data, Odometry) == reference(frames, *values)
