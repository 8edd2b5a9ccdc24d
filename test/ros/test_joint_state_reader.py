"""JointStateReader reads from serialised JointState what rclpy's deserialisation reads."""

import math
import struct

from hypothesis import given
from hypothesis import strategies as st
import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from tracked_kinematics.ros.encoder_input import JointStateReader

reading = st.floats(width=64)  # NaN and inf included: the reader passes them on as they are
text = st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'),
               max_size=12)


def joint_state(frame, names, sec, nanosec, position, velocity, effort):
    msg = JointState()
    msg.header.frame_id = frame
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.name = list(names)
    msg.position, msg.velocity, msg.effort = list(position), list(velocity), list(effort)
    return msg


def bits(values):
    """Return the values as bytes: NaN then equals itself, and -0.0 differs from 0.0."""
    return struct.pack(f'{len(values)}d', *values)


def assert_reads(reader, msg):
    sec, nanosec, names, position, velocity = reader.read(serialize_message(msg))
    assert (sec, nanosec) == (msg.header.stamp.sec, msg.header.stamp.nanosec)
    assert names == list(msg.name)
    assert bits(position) == bits(msg.position) and bits(velocity) == bits(msg.velocity)


layouts = st.tuples(text, st.lists(text, max_size=4), st.integers(0, 3), st.integers(0, 3),
                    st.integers(0, 3))
stamps = st.tuples(st.integers(-2**31, 2**31 - 1), st.integers(0, 2**32 - 1))


@given(st.lists(st.tuples(layouts, stamps, st.lists(reading, min_size=9, max_size=9)),
                min_size=1, max_size=6), st.integers(1, 4))
def test_reads_what_rclpy_reads_whatever_the_layouts(messages, repeats):
    # Each layout (frame id, names, array lengths) repeated: the first is read by rclpy, the
    # repeats in place; a change of layout between two messages is read right too.
    reader = JointStateReader()
    for (frame, names, n_position, n_velocity, n_effort), stamp, values in messages:
        for k in range(repeats):
            shifted = values[k:] + values[:k]
            assert_reads(reader, joint_state(frame, names, *stamp, shifted[:n_position],
                                             shifted[3:3 + n_velocity],
                                             shifted[6:6 + n_effort]))


def test_a_repeated_layout_is_read_in_place():
    reader = JointStateReader()
    names = ['left_sprocket_joint', 'right_sprocket_joint']
    first = joint_state('base_link', names, 5, 6, [0.1, 0.2], [1.0, 2.0], [])
    assert isinstance(reader.read(serialize_message(first))[3], type(first.position))
    for i in range(3):
        msg = joint_state('base_link', names, 7 + i, 8, [0.3 * i, math.nan], [3.0, -0.0], [])
        sec, nanosec, read_names, position, velocity = reader.read(serialize_message(msg))
        assert isinstance(position, tuple)  # struct.unpack_from, not rclpy
        assert (sec, nanosec, read_names) == (7 + i, 8, names)
        assert bits(position) == bits(msg.position) and bits(velocity) == bits(msg.velocity)
    # Another length of the velocities (or of the effort, which moves nothing read) changes
    # the layout: read by rclpy again, right.
    for velocity, effort in (([], []), ([1.0], []), ([1.0], [2.0, 3.0])):
        assert_reads(reader, joint_state('base_link', names, 1, 2, [0.5, 0.6], velocity, effort))


def test_padding_is_not_part_of_the_layout():
    # CDR's padding bytes are not initialised: a writer may send other garbage there in each
    # message. Here (frame id '', these names): after the frame id's NUL, after the second
    # name's, and before the positions' elements (aligned to 8).
    reader = JointStateReader()
    names = ['left_sprocket_joint', 'right_sprocket_joint']
    data = serialize_message(joint_state('', names, 1, 2, [0.5, 0.25], [], []))
    reader.read(data)
    msg = joint_state('', names, 3, 4, [1.5, -2.0], [], [])
    garbled = bytearray(serialize_message(msg))
    assert garbled[76:80] == b'\x02\x00\x00\x00'  # the count of the positions
    for padding in (17, 18, 19, 73, 74, 75, 80, 81, 82, 83):
        garbled[padding] ^= 0x5A
    sec, nanosec, read_names, position, velocity = reader.read(bytes(garbled))
    assert isinstance(position, tuple)
    assert (sec, nanosec, read_names, position, velocity) == (3, 4, names, (1.5, -2.0), ())


@pytest.mark.parametrize('data', [b'', b'\x00\x01\x00\x00', b'\x00\x01\x00\x00' + b'\xff' * 40,
                                  b'not a JointState at all'])
def test_bytes_that_are_no_joint_state_read_as_none(data):
    assert JointStateReader().read(data) is None
