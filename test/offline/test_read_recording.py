"""
The one bag reader (issue 36): every stream of a bag in one pass, one time-0 rule.

read_recording reads encoders, pose, gyro, GNSS and commands into one Recording; the times of
a stream do not depend on which other streams are read; identify_icr, evaluate_model and
identify_drivetrain open each bag once and get the same streams from it.
"""

from helpers.vehicle_sim import AURIGA, B, simulate, write_bag
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.integration import stamp_ns
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.sim.sensors import GnssModel, GyroModel
from tracked_kinematics.offline import bag_simulation as sim
from tracked_kinematics.offline.bags import (
    BagError, CommandSource, EncoderSource, GroundTruthSource, IMU_AUTO, opening,
    read_recording, reader)
from tracked_kinematics.offline.cli import evaluate_model, identify_drivetrain, identify_icr

ENC = EncoderSource(sprocket_radius=0.1)
T0 = 1_700_000_000 * 10**9
GT = GroundTruthSource('/ground_truth/pose')
STREAMS = {'pose': ('gt_t', 'gt_x', 'gt_y', 'gt_yaw'), 'gyro': ('gyro_t', 'gyro_rate'),
           'gnss': ('gnss_t', 'gnss_x', 'gnss_y'), 'commands': ('command_t', 'commands')}
ALONE = {'pose': {'ground_truth': GT}, 'gyro': {'imu_topic': '/imu/data'},
         'gnss': {'gnss_topic': '/gnss/fix'}, 'commands': {'commands': CommandSource()}}


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """Simulate a minute of a quasi-static Auriga-alpha with every stream (gyro, GNSS)."""
    return sim.simulate_bag(
        tmp_path_factory.mktemp('every') / 'every', overrides={'centre_of_mass.z': 0.0},
        duration=60.0, seed=5,
        imu=GyroModel(rate=100.0, bias=0.01, noise_std=0.005, latency=0.05),
        gnss=GnssModel(rate=5.0, noise_std=0.5, dropout=0.05))


@pytest.fixture(scope='module')
def staggered(tmp_path_factory):
    """
    Ten seconds of a steady arc whose streams start at different times (s after T0).

    Gyro 0.2, setpoints 0.3, pose 0.5, GNSS 0.7, encoders 1.0: under the old readers' rules
    (the first sample of the streams read; the bag's start) each reader had its own time 0.
    """
    from tracked_kinematics.offline.bags import BagWriter
    path = tmp_path_factory.mktemp('staggered') / 'staggered'
    v, w = 0.5, 0.2
    v_left, v_right = v - w * B / 2, v + w * B / 2
    with BagWriter(path, 'sqlite3') as out:
        streams = (
            ('/joint_states', 1.0, 50, lambda n, t: out.joint_state(
                n, ['left_sprocket_joint', 'right_sprocket_joint'],
                [v_left * t / 0.1, v_right * t / 0.1])),
            (GT.topic, 0.5, 10, lambda n, t: out.pose_stamped(
                n, np.sin(w * t) * v / w, (1 - np.cos(w * t)) * v / w, w * t)),
            ('/imu/data', 0.2, 100, lambda n, t: out.imu(n, w)),
            ('/gnss/fix', 0.7, 5, lambda n, t: out.nav_sat_fix(n, 46.0 + 1e-6 * t, -71.0, 10.0)),
            ('/left_track/setpoint', 0.3, 20, lambda n, t: out.float64(v_left)),
            ('/right_track/setpoint', 0.3, 20, lambda n, t: out.float64(v_right)))
        for topic, start, rate, message in streams:
            for k in range(int((10.0 - start) * rate)):
                stamp = T0 + round((start + k / rate) * 1e9)
                out.write(topic, stamp, message(stamp, start + k / rate))
    return path


def header_stamps(path, topic):
    """Return the header stamps (ns) of a topic's messages, in bag order."""
    with AnyReader([path]) as bag_reader:
        conns = [c for c in bag_reader.connections if c.topic == topic]
        return np.array([stamp_ns(m.header.stamp.sec, m.header.stamp.nanosec)
                         for m in (bag_reader.deserialize(raw, c.msgtype)
                                   for c, _, raw in bag_reader.messages(connections=conns))])


def test_one_pass_reads_every_stream_on_the_encoders_clock(bag):
    rec = read_recording(bag.bag, ENC, ground_truth=GT, imu_topic='/imu/data',
                         gnss_topic='/gnss/fix', commands=CommandSource())
    for names in (*STREAMS.values(), ('speed_t', 'speeds')):
        assert all(getattr(rec, n) is not None for n in names), names
    assert rec.gyro_topic == '/imu/data' and rec.cmd_vel_t is None
    # Time 0 is the first encoder sample; t0_ns its stamp; every stream on that clock.
    enc = header_stamps(bag.bag, '/joint_states')
    assert rec.enc_t[0] == 0.0 and rec.t0_ns == enc[0]
    np.testing.assert_array_equal(rec.stamps_ns(rec.enc_t), enc)
    np.testing.assert_array_equal(rec.stamps_ns(rec.gyro_t), header_stamps(bag.bag, '/imu/data'))
    np.testing.assert_array_equal(rec.stamps_ns(rec.gt_t), header_stamps(bag.bag, GT.topic))
    assert len(rec.enc_t) == len(bag.run.t)
    np.testing.assert_allclose(rec.speeds, bag.run.joint_velocity * 0.1, atol=1e-12)


def test_a_stream_read_alone_has_the_same_times(staggered):
    every = read_recording(staggered, ENC, ground_truth=GT, imu_topic='/imu/data',
                           gnss_topic='/gnss/fix', commands=CommandSource())
    # Time 0 is the first encoder sample, 1 s after T0; the others start before it.
    assert every.t0_ns == T0 + 10**9
    for name, start in (('enc_t', 0.0), ('gyro_t', -0.8), ('command_t', -0.7), ('gt_t', -0.5),
                        ('gnss_t', -0.3)):
        assert getattr(every, name)[0] == pytest.approx(start, abs=1e-9), name
    for stream, names in STREAMS.items():
        alone = read_recording(staggered, ENC, **ALONE[stream])
        assert alone.t0_ns == every.t0_ns
        for name in ('enc_t', 'left', 'right', *names):
            np.testing.assert_array_equal(getattr(alone, name), getattr(every, name))
        others = [n for s, ns in STREAMS.items() if s != stream for n in ns]
        assert all(getattr(alone, n) is None for n in others)


def test_imu_auto_takes_the_one_imu_topic(bag, tmp_path):
    auto = read_recording(bag.bag, ENC, imu_topic=IMU_AUTO)
    named = read_recording(bag.bag, ENC, imu_topic='/imu/data')
    assert auto.gyro_topic == '/imu/data'
    np.testing.assert_array_equal(auto.gyro_rate, named.gyro_rate)
    # A bag without an Imu topic: no gyro and no error with auto, a one-line error named.
    path = tmp_path / 'no_imu'
    write_bag(path, simulate(ConstantIcr(B), np.array(AURIGA), duration=5.0, seed=2), 'mcap')
    rec = read_recording(path, EncoderSource(), imu_topic=IMU_AUTO)
    assert rec.gyro_t is None and rec.gyro_topic == ''
    with pytest.raises(BagError, match='no topic /imu/data for the IMU; topics present: '):
        read_recording(path, EncoderSource(), imu_topic='/imu/data')


@pytest.fixture
def spy(monkeypatch):
    """Count the bags opened and keep every Recording read, per tool run."""
    seen = {'opened': [], 'read': []}

    class CountingReader(AnyReader):
        def __init__(self, paths, *args, **kwargs):
            seen['opened'].extend(paths)
            super().__init__(paths, *args, **kwargs)

    def guarded(path, read, *args):
        found = opening.guarded(path, read, *args)
        seen['read'].append(found)
        return found

    monkeypatch.setattr(opening, 'AnyReader', CountingReader)
    monkeypatch.setattr(reader, 'guarded', guarded)
    return seen


def run_tool(tool, argv, spy, capsys):
    """Run a tool's main; return the bags it opened and the recordings it read."""
    spy['opened'].clear()
    spy['read'].clear()
    status = tool.main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert status == 0, err
    return list(spy['opened']), list(spy['read'])


def test_each_tool_opens_the_bag_once_and_reads_the_same_streams(bag, tmp_path, spy, capsys):
    vehicle = ['--sprocket-radius', '0.1', '--track-width', '0.42']
    terrain = tmp_path / 'terrain.yaml'
    # identify_icr with a pose also reads the bag's one gyro (imu_delay, gyro_scale): before
    # issue 36 it opened the bag three times (topic list, pose, gyro).
    opened, (icr,) = run_tool(identify_icr, [bag.bag, '--ground-truth-topic', GT.topic,
                                             '--output', terrain, '--accept-uncertain',
                                             *vehicle], spy, capsys)
    assert opened == [bag.bag] and icr.gyro_topic == '/imu/data'
    # evaluate_model --fuse-imu read the bag a second time for the gyro.
    opened, (evaluation,) = run_tool(evaluate_model, [bag.bag, '--params', terrain,
                                                      '--ground-truth-topic', GT.topic,
                                                      '--fuse-imu', '/imu/data'], spy, capsys)
    assert opened == [bag.bag]
    opened, (drive,) = run_tool(identify_drivetrain, [bag.bag, '--output',
                                                      tmp_path / 'drive.yaml', *vehicle[:2]],
                                spy, capsys)
    assert opened == [bag.bag]
    shared = {('enc_t', 'left', 'right', 'speed_t', 'speeds', 't0_ns'): (icr, evaluation, drive),
              (*STREAMS['pose'], *STREAMS['gyro']): (icr, evaluation),
              STREAMS['commands']: (evaluation, drive)}
    for names, recordings in shared.items():
        for name in names:
            for other in recordings[1:]:
                np.testing.assert_array_equal(getattr(other, name),
                                              getattr(recordings[0], name), err_msg=name)
