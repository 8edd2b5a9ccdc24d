"""offline.bags.playback: the messages play_bag publishes, read from a bag (no ROS graph)."""

import math

import pytest
from tracked_kinematics.offline.bags.playback import BagPlayback
from tracked_kinematics.offline.bags.writer import BagWriter
from tracked_kinematics.offline.errors import BagError

T0 = 1_700_000_000_000_000_000


def write(path, storage='sqlite3'):
    """Write 10 s: /a (Float64) at 10 Hz from 0 s, /b (Twist) at 1 Hz from 0.5 s."""
    with BagWriter(path, storage) as bag:
        events = [(T0 + k * 100_000_000, '/a', k) for k in range(100)]
        events += [(T0 + 500_000_000 + k * 1_000_000_000, '/b', k) for k in range(10)]
        for stamp, topic, k in sorted(events):
            bag.write(topic, stamp, bag.float64(float(k)) if topic == '/a'
                      else bag.twist(float(k), 0.0))
    return path


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_the_whole_bag_in_time_order_as_cdr_bytes(tmp_path, storage):
    playback = BagPlayback(write(tmp_path / 'bag', storage))
    assert [(t.name, t.msgtype, t.count) for t in playback.topics] == [
        ('/a', 'std_msgs/msg/Float64', 100), ('/b', 'geometry_msgs/msg/Twist', 10)]
    messages = list(playback.messages())
    assert len(messages) == playback.message_count == 110
    times = [m.time_ns for m in messages]
    assert times == sorted(times) and times[0] == T0 and playback.start_ns == T0
    assert math.isinf(playback.end_ns)
    # CDR with its encapsulation header, as rmw publishes it: a Float64 is 4 + 8 bytes.
    first = messages[0]
    assert first.topic == '/a' and isinstance(first.data, bytes) and len(first.data) == 12


def test_a_window_and_a_topic(tmp_path):
    playback = BagPlayback(write(tmp_path / 'bag'), topics=['/b'], start=2.0, duration=3.0)
    assert [(t.name, t.count) for t in playback.topics] == [('/b', 3)]   # 2.5, 3.5, 4.5 s
    assert [m.time_ns - T0 for m in playback.messages()] == [
        2_500_000_000, 3_500_000_000, 4_500_000_000]


@pytest.mark.parametrize('kwargs, text', [
    ({'topics': ['/c']}, 'no topic /c; topics present: /a (std_msgs/msg/Float64), /b'),
    ({'start': 20.0}, '--start 20 s is beyond the bag, which lasts 9.900 s'),
    ({'start': 0.55, 'duration': 0.01}, 'no message of the chosen topics'),
    ({'start': -1.0}, '--start must be'),
    ({'duration': 0.0}, '--duration must be > 0'),
])
def test_what_cannot_be_played_is_one_line(tmp_path, kwargs, text):
    with pytest.raises(BagError) as err:
        BagPlayback(write(tmp_path / 'bag'), **kwargs)
    assert text in str(err.value) and '\n' not in str(err.value)


def test_a_ros1_bag_says_how_to_convert_it(tmp_path):
    path = write(tmp_path / 'run.bag', 'rosbag1')
    with pytest.raises(BagError, match='is a ROS 1 bag') as err:
        BagPlayback(path)
    assert 'rosbags-convert' in str(err.value)


def test_missing_not_a_bag_and_corrupt(tmp_path):
    with pytest.raises(BagError, match='bag not found'):
        BagPlayback(tmp_path / 'nothing')
    (tmp_path / 'folder').mkdir()
    with pytest.raises(BagError, match='is not a bag'):
        BagPlayback(tmp_path / 'folder')
    bag = write(tmp_path / 'bag')
    for db in bag.glob('*.db3'):
        db.write_bytes(b'not sqlite' * 100)
    with pytest.raises(BagError, match='cannot read bag'):
        BagPlayback(bag)
