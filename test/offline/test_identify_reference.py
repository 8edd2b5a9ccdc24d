"""simulate_bag --imu/--gnss and identify_icr without ground truth, end to end, bad input."""

import json
import math

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.sim.sensors import GnssModel, GyroModel
from tracked_kinematics.core.sim.simulation import TwistTable
from tracked_kinematics.offline import bag_simulation as sim
from tracked_kinematics.offline.bags import EncoderSource, read_recording
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.offline.vehicle_file import load_vehicle
from tracked_kinematics.params import read_params_file

VEHICLE = ['--sprocket-radius', '0.1', '--track-width', '0.42']
BIAS, LATENCY = 0.01, 0.08
# Quasi-static (no load transfer): constant ICRs describe the vehicle, as the fits assume.
FLAT = {'centre_of_mass.z': 0.0}


@pytest.fixture(scope='module')
def table():
    return TwistTable(load_vehicle('auriga_alpha', FLAT).robot.vehicle)


@pytest.fixture(scope='module')
def field(tmp_path_factory, table):
    """Four minutes of a quasi-static Auriga-alpha, a biased, late gyro and a 0.5-m GNSS."""
    path = tmp_path_factory.mktemp('field') / 'field'
    return sim.simulate_bag(
        path, overrides=FLAT, duration=240.0, seed=4, table=table, gt_rate=10.0,
        imu=GyroModel(rate=100.0, bias=BIAS, noise_std=0.005, latency=LATENCY),
        gnss=GnssModel(rate=5.0, noise_std=0.5, dropout=0.05))


def run(argv, capsys):
    status = identify_icr.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err.strip()


def identified(argv, out, capsys):
    """Run identify_icr writing ``out``, which must succeed; return its values and stdout."""
    status, text, err = run([*argv, '--output', out], capsys)
    assert status == 0, err
    return read_params_file(out), text


def test_the_simulated_bag_carries_imu_and_gnss_as_robots_do(field):
    truth = read_params_file(field.truth)
    assert truth['simulation.imu.bias'] == BIAS
    assert truth['simulation.imu.latency'] == LATENCY
    assert truth['simulation.gnss.noise_std'] == 0.5
    with AnyReader([field.bag]) as reader:
        imu = [c for c in reader.connections if c.topic == '/imu/data']
        gnss = [c for c in reader.connections if c.topic == '/gnss/fix']
        assert imu[0].msgtype == 'sensor_msgs/msg/Imu'
        assert gnss[0].msgtype == 'sensor_msgs/msg/NavSatFix'
        first = next(reader.messages(connections=imu))
        msg = reader.deserialize(first[2], imu[0].msgtype)
        assert msg.orientation_covariance[0] == -1.0
        assert msg.linear_acceleration_covariance[0] == -1.0
        status = [reader.deserialize(raw, c.msgtype).status.status
                  for c, _, raw in reader.messages(connections=gnss)]
    assert set(status) == {-1, 0} and 0.01 < status.count(-1) / len(status) < 0.12
    rec = read_recording(field.bag, EncoderSource(sprocket_radius=0.1), imu_topic='/imu/data',
                         gnss_topic='/gnss/fix')
    # The gyro reads the true rate of LATENCY s before its stamp, plus its bias.
    steps = np.clip(np.searchsorted(field.run.t, rec.gyro_t - LATENCY, side='right') - 1, 0,
                    len(field.run.twist) - 1)
    error = rec.gyro_rate - field.run.twist[steps, 2]
    assert np.median(error) == pytest.approx(BIAS, abs=0.002)
    # The fixes, back in the local plane, are the true path within the GNSS noise.
    t, x, y = rec.positions
    true_x = np.interp(t, field.run.t, field.run.pose[:, 0])
    assert np.std(x - true_x) == pytest.approx(0.5, rel=0.15)


def test_imu_only_fits_heading_and_holds_the_rest(field, tmp_path, capsys):
    out, report = tmp_path / 'imu.yaml', tmp_path / 'imu.json'
    values, text = identified([field.bag, '--imu-topic', '/imu/data', '--report', report,
                               *VEHICLE], out, capsys)
    assert 'held (--params or ideal drive): distance_scale' in text
    assert values['identification.reference'] == 'imu'
    assert values['identification.determined'] == ['chi', 'scale_ratio']
    assert values['identification.held'] == ['distance_scale', 'icr.x', 'icr_offset']
    assert values['identification.imu_delay'] == pytest.approx(LATENCY, abs=0.01)
    assert values['identification.gyro_bias_per_bag'][0] == pytest.approx(BIAS, abs=1e-3)
    true = field.truth_icr
    ratio = values['scale.right'] / values['scale.left']
    assert ratio == pytest.approx(true.scale_right / true.scale_left, abs=0.01)
    assert values['icr.x'] == 0.0 and values['icr.y_left'] == -values['icr.y_right']
    doc = json.loads(report.read_text())
    assert doc['reference'] == 'imu' and doc['held'] == values['identification.held']


def test_gnss_fits_the_distance_scale(field, tmp_path, capsys):
    values, _ = identified([field.bag, '--imu-topic', '/imu/data', '--gnss-topic', '/gnss/fix',
                            *VEHICLE], tmp_path / 'gnss.yaml', capsys)
    assert values['identification.reference'] == 'imu+gnss'
    assert 'distance_scale' in values['identification.determined']
    # Against the fit to the true pose (the best constant-ICR scales of this run; the
    # averaged stationary model differs, the ICRs of this vehicle move in fast turns).
    pose, _ = identified([field.bag, '--ground-truth-topic', '/ground_truth/pose', '--holdout',
                          '0', *VEHICLE], tmp_path / 'pose.yaml', capsys)
    scale = 0.5 * (values['scale.left'] + values['scale.right'])
    assert scale == pytest.approx(0.5 * (pose['scale.left'] + pose['scale.right']), abs=0.02)
    # Without GNSS the scale is held at 1.
    assert field_imu_only(field, tmp_path, capsys) == pytest.approx(2.0, abs=1e-12)


def field_imu_only(field, tmp_path, capsys):
    values, _ = identified([field.bag, '--imu-topic', '/imu/data', *VEHICLE],
                           tmp_path / 'imu_only.yaml', capsys)
    return values['scale.left'] + values['scale.right']


def bad_bag(field, path, rates=None, fixes=None, every=1):
    """Write the field run again, with given gyro readings (every ``every``-th step), or fixes."""
    run_ = field.run
    gyro = (run_.t[::every], rates[::every]) if rates is not None else None
    sim.write_run(path, run_, gyro=gyro, gnss=fixes)
    return path


@pytest.mark.parametrize('kind, match', [('zeros', 'no angular velocity'),
                                         ('nan', 'no angular velocity'),
                                         ('saturated', 'saturated')])
def test_an_unusable_gyro_is_one_line_and_no_output(field, tmp_path, capsys, kind, match):
    w = np.r_[field.run.twist[:, 2], 0.0]
    rates = {'zeros': np.zeros(w.size), 'nan': np.full(w.size, np.nan),
             'saturated': np.clip(w, -0.3, 0.3)}[kind]
    bag = bad_bag(field, tmp_path / kind, rates=rates, every=5)   # a 40-Hz gyro: enough
    out = tmp_path / 'out.yaml'
    status, text, err = run([bag, '--imu-topic', '/imu/data', '--output', out, *VEHICLE],
                            capsys)
    assert status == 2
    assert len(err.splitlines()) == 1 and match in err and err.startswith('identify_icr: error')
    assert not out.exists()


def test_a_gnss_without_fix_is_refused(field, tmp_path, capsys):
    t = field.run.t[::20]
    fixes = (t, np.zeros(t.size), np.zeros(t.size), np.zeros(t.size), np.full(t.size, -1))
    w = np.r_[field.run.twist[:, 2], 0.0]
    bag = bad_bag(field, tmp_path / 'nofix', rates=w, fixes=fixes)
    out = tmp_path / 'out.yaml'
    status, _, err = run([bag, '--imu-topic', '/imu/data', '--gnss-topic', '/gnss/fix',
                          '--output', out, *VEHICLE], capsys)
    assert status == 2 and 'no fix' in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_a_straight_drive_that_turns_is_refused(field, tmp_path, capsys):
    out = tmp_path / 'straight.yaml'
    status, _, err = run([field.bag, '--imu-topic', '/imu/data', '--straight-distance', '50',
                          '--output', out, *VEHICLE], capsys)
    assert status == 3 and 'not a straight drive' in err
    assert not out.exists()


@pytest.mark.parametrize('argv, match', [
    (['--gnss-topic', '/gnss/fix'], '--imu-topic'),
    ([], '--ground-truth-topic'),
    (['--imu-topic', '/imu/data', '--spin-in-place'], '--spin-in-place'),
    (['--imu-topic', '/imu/data', '--model', 'general_slip'], 'ground-truth pose'),
])
def test_options_without_a_heading_reference_are_refused(field, tmp_path, capsys, argv, match):
    status, _, err = run([field.bag, *argv, '--output', tmp_path / 'o.yaml', *VEHICLE], capsys)
    assert status == 2 and match in err


def test_an_imu_delay_the_node_would_refuse_is_refused(tmp_path, capsys):
    # odometry_node's imu_delay is in [-1, 1] s; the option was [-5, 5] s: a file with 3 s
    # would have been written, and refused where it is used.
    with pytest.raises(SystemExit) as stop:
        identify_icr.main(['unused', '--imu-topic', '/imu/data', '--imu-delay', '3',
                           '--output', str(tmp_path / 'o.yaml'), *VEHICLE])
    assert stop.value.code == 2
    assert 'argument --imu-delay: must be in [-1, 1] s, got 3' in capsys.readouterr().err


def test_evaluate_model_takes_the_same_imu_delay(field, tmp_path, capsys):
    # evaluate_model --imu-delay: the gyro reference's delay, in the node's range as above.
    from tracked_kinematics.offline.cli import evaluate_model
    common = [str(field.bag), '--params', str(field.truth), '--sprocket-radius', '0.1']
    with pytest.raises(SystemExit) as stop:
        evaluate_model.main([*common, '--imu-topic', '/imu/data', '--imu-delay', '3'])
    assert stop.value.code == 2
    assert 'argument --imu-delay: must be in [-1, 1] s, got 3' in capsys.readouterr().err
    # Without the gyro as the reference there is nothing for it to time.
    status = evaluate_model.main([*common, '--ground-truth-topic', '/ground_truth/pose',
                                  '--imu-delay', '0.08'])
    assert status == 2
    assert '--imu-delay goes with --imu-topic' in capsys.readouterr().err
    report = tmp_path / 'r.json'
    assert evaluate_model.main([*common, '--imu-topic', '/imu/data', '--imu-delay',
                                str(LATENCY), '--report', str(report)]) == 0, \
        capsys.readouterr().err
    assert json.loads(report.read_text())['recordings'][0]['imu_delay_s'] == LATENCY


def test_evaluate_model_scores_heading_only_against_a_gyro(field, tmp_path, capsys):
    from tracked_kinematics.offline.cli import evaluate_model
    model = tmp_path / 'imu.yaml'
    assert run([field.bag, '--imu-topic', '/imu/data', '--output', model, *VEHICLE],
               capsys)[0] == 0
    reports = {}
    for name, ref in (('imu', ['--imu-topic', '/imu/data']),
                      ('pose', ['--ground-truth-topic', '/ground_truth/pose'])):
        reports[name] = tmp_path / f'{name}.json'
        status = evaluate_model.main([str(field.bag), *ref, '--params', str(model),
                                      '--sprocket-radius', '0.1', '--report',
                                      str(reports[name])])
        out, err = capsys.readouterr()
        assert status == 0, err
        assert ('heading only' in out) == (name == 'imu')
    imu, pose = (json.loads(reports[k].read_text()) for k in ('imu', 'pose'))
    assert imu['reference'] == 'imu' and 'heading only' in imu['scored']
    for name in ('ideal', 'imu'):
        win = imu['models'][name]['odometry']['windows']['5']
        assert win['mean_position_error_m'] is None and win['p90_position_error_m'] is None
        assert imu['models'][name]['rpe_1m'] is None
        assert imu['models'][name]['odometry']['horizon']['mean_rmse_translation_m'] is None
        # The gyro scores heading as the pose does, within the pose's own noise (0.002 rad).
        heading = win['mean_heading_error_rad']
        truth = pose['models'][name]['odometry']['windows']['5']['mean_heading_error_rad']
        assert heading == pytest.approx(truth, rel=0.15, abs=0.002)
    assert pose['models']['imu']['odometry']['windows']['5']['mean_position_error_m'] > 0


def test_evaluate_model_needs_one_reference(field, tmp_path, capsys):
    from tracked_kinematics.offline.cli import evaluate_model
    status = evaluate_model.main([str(field.bag), '--params', str(field.truth),
                                  '--sprocket-radius', '0.1'])
    assert status == 2 and '--imu-topic' in capsys.readouterr().err


def test_a_measured_straight_fixes_the_distance_scale(field, table, tmp_path, capsys):
    from tracked_kinematics.core.sim.sensors import gyro_samples
    from tracked_kinematics.core.sim.simulation import simulate
    spec = load_vehicle('auriga_alpha', FLAT)
    t = np.arange(0.0, 40.0, 0.01)
    speed = 0.6 * np.clip(t - 1.0, 0.0, 1.0) * np.clip(38.0 - t, 0.0, 1.0)
    enc = spec.robot.encoders
    # Steered straight, as a driver would: the nominal speeds make equal true speeds.
    straight = simulate(spec.robot, np.column_stack([speed / enc.scale_left,
                                                     speed / enc.scale_right]), 0.01, table,
                        rng=np.random.default_rng(0))
    gyro = gyro_samples(straight.t, straight.twist[:, 2], GyroModel(bias=0.002, noise_std=0.002),
                        np.random.default_rng(1))
    bag = tmp_path / 'straight'
    sim.write_run(bag, straight, gyro=gyro)
    x, y = straight.pose[-1, :2] - straight.pose[0, :2]
    measured = float(np.hypot(x, y))
    values, text = identified([bag, '--imu-topic', '/imu/data', '--straight-distance',
                               f'{measured:.4f}', '--params', field.truth, '--sprocket-radius',
                               '0.1'], tmp_path / 'straight.yaml', capsys)
    assert values['identification.reference'] == 'imu+straight'
    assert 'distance_scale' in values['identification.determined']
    assert 'chi' in values['identification.held']
    true = field.truth_icr
    assert 0.5 * (values['scale.left'] + values['scale.right']) == pytest.approx(
        0.5 * (true.scale_left + true.scale_right), rel=0.005)
    assert 'straight drive:' in text
    # A straight does not time the gyro: its delay, not determined, is not written (0 before).
    assert values['identification.imu_delay_method'] == 'not determined'
    assert 'imu_delay' not in values


def test_gnss_as_odometry_of_navsat_transform(table, tmp_path, capsys):
    bag = sim.simulate_bag(tmp_path / 'navsat', overrides=FLAT, duration=120.0, seed=6,
                           table=table, ground_truth='odometry', gt_position_noise=0.02,
                           imu=GyroModel(bias=0.004, noise_std=0.003))
    values, _ = identified([bag.bag, '--imu-topic', '/imu/data', '--gnss-topic',
                            '/ground_truth/odom', *VEHICLE], tmp_path / 'navsat.yaml', capsys)
    assert values['identification.reference'] == 'imu+gnss'
    true = bag.truth_icr
    assert 0.5 * (values['scale.left'] + values['scale.right']) == pytest.approx(
        0.5 * (true.scale_left + true.scale_right), abs=0.01)


@pytest.mark.parametrize('orientation', ['turning', 'identity'])
def test_the_reader_takes_the_orientation_only_when_it_turns(field, tmp_path, orientation):
    from tracked_kinematics.offline.bags.writer import BagWriter
    run_ = field.run
    path = tmp_path / orientation
    t = run_.t[:3000]
    with BagWriter(path) as bag:
        for k, tk in enumerate(t):
            stamp = sim.START_NS + int(round(tk * 1e9))
            bag.write('/joint_states', stamp, bag.joint_state(
                stamp, sim.JOINTS, run_.joint_position[k].tolist()))
            yaw = float(run_.pose[k, 2]) if orientation == 'turning' else 0.0
            w = float(run_.twist[min(k, len(run_.twist) - 1), 2])
            bag.write('/imu/data', stamp, bag.imu(stamp, w, yaw=yaw))
    rec = read_recording(path, EncoderSource(sprocket_radius=0.1), imu_topic='/imu/data')
    # The rate as odometry_node reads it (about the vertical: the Imu's z rate on the level),
    # with an orientation or not.
    rates = run_.twist[np.minimum(np.arange(3000), len(run_.twist) - 1), 2]
    np.testing.assert_allclose(rec.gyro_rate, rates, atol=1e-9)
    if orientation == 'turning':
        assert np.allclose(np.unwrap(rec.gyro_yaw) - rec.gyro_yaw[0],
                           run_.pose[:3000, 2] - run_.pose[0, 2], atol=1e-6)
    else:
        assert rec.gyro_yaw is None


def test_the_reader_drops_garbage_gyro_samples_and_says_so(field, tmp_path, capsys):
    # Before: the NaN and 1e300 rates reached the fits: identify_icr's pose fit wrote no
    # imu_delay ("gt_yaw has non-finite values"), its gyro fit exited 4 ("the tracks or the
    # gyro sign swapped?") on 12 garbage samples in 6000.
    from tracked_kinematics.offline.bags.writer import BagWriter
    run_ = field.run
    path = tmp_path / 'garbage'
    t = run_.t[:1000]
    rates = run_.twist[:1000, 2].copy()
    bad = {100: math.nan, 200: 1e300, 300: -math.inf, 400: -1e20}
    with BagWriter(path) as bag:
        for k, tk in enumerate(t):
            stamp = sim.START_NS + int(round(tk * 1e9))
            bag.write('/joint_states', stamp, bag.joint_state(
                stamp, sim.JOINTS, run_.joint_position[k].tolist()))
            bag.write('/imu/data', stamp, bag.imu(stamp, bad.get(k, float(rates[k]))))
    rec = read_recording(path, EncoderSource(sprocket_radius=0.1), imu_topic='/imu/data')
    keep = ~np.isin(np.arange(1000), list(bad))
    np.testing.assert_allclose(rec.gyro_rate, rates[keep], atol=1e-9)
    assert len(rec.gyro_t) == 996
    assert ('4 of 1000 Imu messages on /imu/data dropped: their heading rate is not finite'
            in capsys.readouterr().err)


# The IMU's mounting (issue 35 item 3): the tools read the gyro as odometry_node does. ----


UPSIDE_DOWN = (3.14159, 0.0, 0.0)    # as a user types it: --imu-mount 3.14159 0 0


def mounted_bag(field, path, imu_of, samples=6000, pose=False):
    """
    Write the field run's first ``samples`` encoder samples, an Imu at each of them.

    ``imu_of(w, psi)`` gives ``(omega, quaternion or None)`` of the IMU for the true yaw rate
    ``w`` (rad/s, about the vertical: the run is on the level) and heading ``psi``. With
    ``pose``, the true pose on ``/gt`` (nav_msgs/Odometry) at every 10th sample.
    """
    from tracked_kinematics.offline.bags.writer import BagWriter
    run_ = field.run
    with BagWriter(path) as bag:
        for k, tk in enumerate(run_.t[:samples]):
            stamp = sim.START_NS + int(round(tk * 1e9))
            bag.write('/joint_states', stamp, bag.joint_state(
                stamp, sim.JOINTS, run_.joint_position[k].tolist()))
            omega, quaternion = imu_of(float(run_.twist[min(k, len(run_.twist) - 1), 2]),
                                       float(run_.pose[k, 2]))
            bag.write('/imu/data', stamp, bag.imu(stamp, 0.0, omega=omega,
                                                  quaternion=quaternion))
            if pose and k % 10 == 0:
                bag.write('/gt', stamp, bag.odometry(stamp, *run_.pose[k, :3].tolist()))
    return path


def rotation(*turns):
    """Return the scipy Rotation of (axis, angle) turns, the first outermost."""
    from scipy.spatial.transform import Rotation
    out = Rotation.identity()
    for axis, angle in turns:
        out = out * Rotation.from_euler(axis, angle)
    return out


# An IMU's reading of a level run turning at w with heading psi, mounted by the rotation M
# of its frame in base_link: omega = M^T (0, 0, w); its orientation (ENU) Rz(psi) M.
def mounted(mount, orientation):
    def imu_of(w, psi):
        omega = mount.inv().apply([0.0, 0.0, w])
        quaternion = (rotation(('z', psi)) * mount).as_quat() if orientation else None
        return tuple(omega), None if quaternion is None else tuple(quaternion)
    return imu_of


@pytest.mark.parametrize('orientation', [False, True])
def test_an_upside_down_imu_read_with_its_mount_is_the_upright_one(field, tmp_path,
                                                                   orientation):
    encoders = EncoderSource(sprocket_radius=0.1)
    upright = mounted_bag(field, tmp_path / 'upright', mounted(rotation(), orientation),
                          samples=3000)
    down = mounted_bag(field, tmp_path / 'down', mounted(rotation(('x', math.pi)),
                                                         orientation), samples=3000)
    right = read_recording(upright, encoders, imu_topic='/imu/data')
    as_is = read_recording(down, encoders, imu_topic='/imu/data')
    mount = read_recording(down, encoders, imu_topic='/imu/data', imu_mount=UPSIDE_DOWN)
    assert np.ptp(right.gyro_rate) > 0.5
    # Before: angular_velocity.z alone, the mount unknown: the rate mirrored.
    np.testing.assert_allclose(as_is.gyro_rate, -right.gyro_rate, atol=1e-9)
    np.testing.assert_allclose(mount.gyro_rate, right.gyro_rate, atol=1e-5)
    if orientation:
        # The orientation's heading through the mount: the upright one's.
        np.testing.assert_allclose(np.unwrap(mount.gyro_yaw - right.gyro_yaw), 0.0,
                                   atol=1e-5)


def test_identify_icr_fits_an_upside_down_gyro_given_its_mount(field, tmp_path, capsys):
    down = mounted_bag(field, tmp_path / 'down', mounted(rotation(('x', math.pi)), False))
    upright = mounted_bag(field, tmp_path / 'upright', mounted(rotation(), False))
    # Without its mount the gyro turns the other way: the fit refuses the sign (exit 4), as
    # before, when no mount could be given.
    status, _, err = run([down, '--imu-topic', '/imu/data', *VEHICLE, '--output',
                          tmp_path / 'refused.yaml'], capsys)
    assert status == 4 and 'sign swapped' in err, err
    assert not (tmp_path / 'refused.yaml').exists()
    values, _ = identified([down, '--imu-topic', '/imu/data', '--imu-mount',
                            *map(str, UPSIDE_DOWN), *VEHICLE], tmp_path / 'down.yaml', capsys)
    right, _ = identified([upright, '--imu-topic', '/imu/data', *VEHICLE],
                          tmp_path / 'upright.yaml', capsys)
    for key in ('icr.y_left', 'icr.y_right', 'scale.left', 'scale.right', 'imu_delay'):
        assert values[key] == pytest.approx(right[key], abs=1e-6), key
    # Written for odometry_node, which is to read the gyro as it was fitted.
    assert (values['imu_mount.roll'], values['imu_mount.pitch'],
            values['imu_mount.yaw']) == UPSIDE_DOWN
    assert 'imu_mount.roll' not in right


def test_a_pitched_imu_gives_the_world_vertical_rate(field, tmp_path):
    """An IMU pitched 20 deg in base_link: the rate about the vertical, as the node reads it."""
    encoders = EncoderSource(sprocket_radius=0.1)
    pitch = math.radians(20.0)
    mount = rotation(('y', pitch))
    truth = read_recording(mounted_bag(field, tmp_path / 'upright', mounted(rotation(), False),
                                       samples=3000), encoders, imu_topic='/imu/data').gyro_rate
    assert np.ptp(truth) > 0.5
    with_q = mounted_bag(field, tmp_path / 'orientation', mounted(mount, True), samples=3000)
    without = mounted_bag(field, tmp_path / 'rates', mounted(mount, False), samples=3000)
    given = (0.0, pitch, 0.0)
    # With the orientation, the heading's rate about the vertical, whatever the mount says ...
    for imu_mount in (given, (0.0, 0.0, 0.0)):
        rec = read_recording(with_q, encoders, imu_topic='/imu/data', imu_mount=imu_mount)
        np.testing.assert_allclose(rec.gyro_rate, truth, atol=1e-9)
    # ... without it, the body z rate: right through the mount, cos(20 deg) of it without
    # (before: angular_velocity.z alone, 6 % short with or without an orientation).
    rec = read_recording(without, encoders, imu_topic='/imu/data', imu_mount=given)
    np.testing.assert_allclose(rec.gyro_rate, truth, atol=1e-9)
    rec = read_recording(without, encoders, imu_topic='/imu/data')
    np.testing.assert_allclose(rec.gyro_rate, math.cos(pitch) * truth, atol=1e-9)


def test_evaluate_model_fuses_an_imu_that_has_an_orientation(field, tmp_path, capsys):
    """Before: an Imu with an orientation was read as its yaw alone, and --fuse-imu refused it."""
    from tracked_kinematics.offline.cli import evaluate_model
    figures = {}
    for orientation in (False, True):
        bag = mounted_bag(field, tmp_path / f'o{orientation}', mounted(rotation(), orientation),
                          pose=True)
        report = tmp_path / f'o{orientation}.json'
        status = evaluate_model.main([str(bag), '--ground-truth-topic', '/gt', '--fuse-imu',
                                      '/imu/data', '--params', str(field.truth),
                                      '--sprocket-radius', '0.1', '--report', str(report)])
        assert status == 0, capsys.readouterr().err
        entry = json.loads(report.read_text())['models'][f'{field.truth.stem}+imu']
        assert entry['gyro']['source_at_end'] == ['gyro']
        figures[orientation] = entry['odometry']['windows']['5']
    # On the level the heading's rate from the orientation is the z rate: the same figures.
    for key in ('mean_position_error_m', 'mean_heading_error_rad'):
        assert figures[True][key] == pytest.approx(figures[False][key], rel=1e-9)
