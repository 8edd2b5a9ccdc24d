"""simulate_bag and icr_map: vehicle files, bags that rosbags reads back, the true model."""

from pathlib import Path
import signal
import subprocess
import sys

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.integration import relative_pose
from tracked_kinematics.core.models import ConstantIcr, IdealDiffDrive
from tracked_kinematics.offline.bag_simulation import simulate_bag, START_NS, truth_path
from tracked_kinematics.offline.cli import icr_map, simulate_bag as simulate_cli
from tracked_kinematics.offline.outputs import PROBE_MARK
from tracked_kinematics.offline.vehicle_file import load_vehicle, shipped_vehicles
from tracked_kinematics.params import icr_from_values, read_params_file

BIN = Path(sys.executable).parent


def read_bag(path, ground_truth_topic='/ground_truth/pose'):
    """Topics and types, joint states, setpoints and ground truth (header stamps in ns)."""
    out = {'js_t': [], 'js_pos': [], 'js_vel': [], 'sp': [], 'gt_t': [], 'gt': [],
           'stamps': []}
    with AnyReader([Path(path)]) as reader:
        out['types'] = {c.topic: c.msgtype for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            out['stamps'].append(stamp)
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == '/joint_states':
                out['names'] = list(msg.name)
                out['js_t'].append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
                out['js_pos'].append(np.array(msg.position))
                out['js_vel'].append(np.array(msg.velocity))
            elif conn.topic.endswith('/setpoint'):
                out['sp'].append((conn.topic, msg.data))
            elif conn.topic == ground_truth_topic:
                pose = msg.pose.pose if hasattr(msg.pose, 'pose') else msg.pose
                out['gt_t'].append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
                out['gt'].append((pose.position.x, pose.position.y,
                                  2.0 * np.arctan2(pose.orientation.z, pose.orientation.w)))
                out['gt_frame'] = msg.header.frame_id
    for key in ('js_t', 'js_pos', 'js_vel', 'gt_t', 'gt', 'stamps'):
        out[key] = np.array(out[key])
    return out


@pytest.fixture(scope='module')
def auriga_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp('sim') / 'auriga'
    return simulate_bag(path, 'auriga_alpha', duration=60.0, seed=4)


def test_shipped_vehicles_hold_the_papers_numbers():
    assert {'auriga_alpha', 'packbot'} <= set(shipped_vehicles())
    auriga = load_vehicle('auriga_alpha').robot
    # Martinez sec. 5.1: 258 kg, L 0.42 m, 0.7 x 0.15 m contact, 1 m/s; centre of mass
    # (-0.015, 0.04) m in the paper's frame (X right, Y forward) -> ROS (0.04, 0.015).
    veh = auriga.vehicle
    assert (veh.mass, veh.track_width, veh.contact_length, veh.contact_width) == (
        258.0, 0.42, 0.7, 0.15)
    assert (veh.com_x, veh.com_y, veh.max_track_speed) == (0.04, 0.015, 1.0)
    assert (auriga.encoders.scale_left, auriga.encoders.scale_right) == (1.0072, 1.0275)
    packbot = load_vehicle('packbot').robot
    # Fink & Stump: 18 kg, 2 m/s, drive train of Table II.
    assert (packbot.vehicle.mass, packbot.vehicle.max_track_speed) == (18.0, 2.0)
    assert packbot.drivetrain.delay == 0.049 and packbot.drivetrain.max_accel == 5.5
    assert packbot.drivetrain.loop.kp == 56.49


def test_vehicle_file_errors_name_the_parameter(tmp_path):
    with pytest.raises(ValueError, match='unknown vehicle parameter.*frictoin.mu_x'):
        load_vehicle('packbot', {'frictoin.mu_x': 1.0})
    with pytest.raises(ValueError, match='friction.mu_y must be > 0'):
        load_vehicle('packbot', {'friction.mu_y': 0.0})
    with pytest.raises(ValueError, match='centre_of_mass.x = 0.3 m'):
        load_vehicle('packbot', {'centre_of_mass.x': 0.3})
    with pytest.raises(ValueError, match='drivetrain.loop must be one of'):
        load_vehicle('packbot', {'drivetrain.loop': 'magic'})
    with pytest.raises(FileNotFoundError, match='auriga_alpha, packbot'):
        load_vehicle('tank')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('track_width: [1, 2\n')
    with pytest.raises(ValueError, match='bad.yaml: not valid YAML'):
        load_vehicle(bad)


def test_bag_holds_the_interface_topics(auriga_bag):
    data = read_bag(auriga_bag.bag)
    assert data['types'] == {
        '/joint_states': 'sensor_msgs/msg/JointState',
        '/left_track/setpoint': 'std_msgs/msg/Float64',
        '/right_track/setpoint': 'std_msgs/msg/Float64',
        '/ground_truth/pose': 'geometry_msgs/msg/PoseStamped'}
    assert data['names'] == ['left_sprocket_joint', 'right_sprocket_joint']
    assert data['gt_frame'] == 'map'
    # 100 Hz encoders, 50 Hz setpoints per side, 10 Hz ground truth over 60 s.
    assert len(data['js_t']) == 6001 and len(data['gt_t']) == 601
    assert sum(1 for topic, _ in data['sp'] if topic == '/left_track/setpoint') == 3001
    assert auriga_bag.messages['/joint_states'] == 6001
    assert np.all(np.diff(data['stamps']) >= 0)  # written in time order
    assert np.all(np.diff(data['js_t']) == 10_000_000)
    # Joint velocities are sprocket rad/s: radius 0.1 m, the Auriga's 1 m/s at most.
    assert np.max(np.abs(data['js_vel'])) < 10.5
    assert np.all(np.isfinite(data['js_pos'])) and np.all(np.isfinite(data['gt']))


def test_truth_yaml_is_a_valid_terrain_file_that_explains_the_bag(auriga_bag):
    assert auriga_bag.truth == truth_path(auriga_bag.bag)
    values = read_params_file(auriga_bag.truth)
    icr = icr_from_values(values)
    assert icr == auriga_bag.truth_icr
    assert (icr.scale_left, icr.scale_right) == (1.0072, 1.0275)
    assert values['vehicle'] == 'auriga_alpha' and values['simulation.seed'] == 4
    assert values['run_fit.y_left'] > 0.21
    # Odometry on the bag's encoders through the true model vs ideal differential drive,
    # compared with the ground truth over 1 s windows.
    data = read_bag(auriga_bag.bag)
    travel = np.diff(data['js_pos'], axis=0) * values['sprocket_radius']
    errors = {}
    for name, model, p in (('truth', ConstantIcr(0.42), ConstantIcr(0.42).from_icr(icr)),
                           ('ideal', IdealDiffDrive(0.42), ())):
        x, y, th = (np.r_[0.0, a] for a in model.integrate(p, *travel.T, 0.01))
        k = np.searchsorted(data['js_t'], data['gt_t'])
        a, b = k[:-10:10], k[10::10]
        gt = data['gt']
        i = np.arange(0, len(gt) - 10, 10)
        true_d = relative_pose(*gt[i].T, *gt[i + 10].T)
        odo_d = relative_pose(x[a], y[a], th[a], x[b], y[b], th[b])
        errors[name] = np.mean(np.hypot(true_d[0] - odo_d[0], true_d[1] - odo_d[1]))
    assert errors['truth'] < 0.01
    assert errors['ideal'] > 3 * errors['truth']


@pytest.mark.parametrize('storage, name, ground_truth', [
    ('mcap', 'run', 'odometry'), ('rosbag1', 'new/dir/run.bag', 'pose')])
def test_other_storages_and_odometry_ground_truth(tmp_path, storage, name, ground_truth):
    result = simulate_bag(tmp_path / name, 'packbot', manoeuvres='sweep', duration=10.0,
                          storage=storage, ground_truth=ground_truth, seed=1)
    topic = '/ground_truth/odom' if ground_truth == 'odometry' else '/ground_truth/pose'
    data = read_bag(result.bag, topic)
    expected = 'nav_msgs/msg/Odometry' if ground_truth == 'odometry' else \
        'geometry_msgs/msg/PoseStamped'
    assert data['types'][topic] == expected
    assert result.truth == (tmp_path / name).with_name('run.truth.yaml')
    np.testing.assert_allclose(data['gt'][-1, :2], result.run.gt_pose[-1, :2], atol=1e-12)
    assert np.ptp(data['gt'][:, 0]) > 1.0  # the sweep drove


def test_setpoints_are_the_commands_the_drive_train_got(tmp_path):
    # 30 Hz does not divide 100 Hz: each setpoint is stamped where its hold starts.
    result = simulate_bag(tmp_path / 'sp', 'packbot', duration=4.0, setpoint_rate=30.0,
                          gt_rate=5.0, seed=2)
    with AnyReader([result.bag]) as reader:
        conns = [c for c in reader.connections if c.topic == '/left_track/setpoint']
        setpoints = [(stamp, reader.deserialize(raw, c.msgtype).data)
                     for c, stamp, raw in reader.messages(connections=conns)]
    assert len(setpoints) == 121
    stamps = np.array([s for s, _ in setpoints]) - START_NS
    values = np.array([v for _, v in setpoints])
    k = np.round(stamps / 1e7).astype(int)
    # The recorded value is the command in force from that sample until the next setpoint.
    bounds = np.r_[k, len(result.run.t)]
    for j in range(len(k)):
        np.testing.assert_array_equal(result.run.commands[bounds[j]:bounds[j + 1], 0], values[j])
    np.testing.assert_allclose(stamps / 1e9, np.ceil(np.arange(121) / 0.3 - 1e-9) / 100)


def test_same_seed_same_bag_content(tmp_path):
    one = read_bag(simulate_bag(tmp_path / 'a', 'packbot', duration=5.0, seed=9).bag)
    two = read_bag(simulate_bag(tmp_path / 'b', 'packbot', duration=5.0, seed=9).bag)
    three = read_bag(simulate_bag(tmp_path / 'c', 'packbot', duration=5.0, seed=8).bag)
    np.testing.assert_array_equal(one['js_pos'], two['js_pos'])
    np.testing.assert_array_equal(one['gt'], two['gt'])
    assert not np.array_equal(one['js_pos'], three['js_pos'])


def test_cli_writes_bag_and_prints_the_true_model(tmp_path, capsys):
    rc = simulate_cli.main([str(tmp_path / 'cli'), '--vehicle', 'packbot', '--duration', '5',
                            '--mu-y', '0.9', '--terrain', 'rubber_mat', '--set',
                            'centre_of_mass.y=0.01', '--storage', 'mcap', '--gt-rate', '20',
                            '--gt-topic', '/mocap/pose', '--truth', str(tmp_path / 'true.yaml')])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert 'packbot on rubber_mat' in out and '/mocap/pose' in out and 'chi' in out
    values = read_params_file(tmp_path / 'true.yaml')
    assert values['terrain'] == 'rubber_mat'
    assert values['icr.y_left'] < -values['icr.y_right']  # mass on the left
    assert len(read_bag(tmp_path / 'cli', '/mocap/pose')['gt_t']) == 101


@pytest.mark.parametrize('argv, message', [
    (['--vehicle', 'tank'], 'no vehicle file'),
    (['--set', 'mass=-3'], 'mass must be > 0'),
    (['--storage', 'rosbag1'], 'needs a .bag file name'),
    (['--setpoint-rate', '200'], 'must not exceed the encoder rate'),
])
def test_cli_errors_are_one_line(tmp_path, capsys, argv, message):
    assert simulate_cli.main([str(tmp_path / 'out')] + argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith('simulate_bag: error: ') and '\n' not in err and message in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('argv, message', [
    (['--duration', '0'], '--duration: must be in [0.1, 36000] s, got 0'),
    (['--duration', '1e9'], '--duration: must be in [0.1, 36000] s, got 1e9'),
    (['--rate', '1e9'], '--rate: must be in [1, 2000] Hz, got 1e9'),
    (['--gt-rate', '0'], '--gt-rate: must be in [0.1, 1000] Hz'),
    (['--seed', '-1'], '--seed: must be in [0, 4,294,967,295], got -1'),
    (['--gt-noise-xy', 'inf'], '--gt-noise-xy: must be a finite number in [0, 1] m'),
    (['--mu-y', '0'], '--mu-y: must be in [0.01, 5], got 0'),
    # The gyro's and the GNSS receiver's values: checked here, trusted by the core's models.
    (['--imu', '--imu-rate', '0'], '--imu-rate: must be in [1, 2000] Hz, got 0'),
    (['--imu', '--imu-noise', '-1'], '--imu-noise: must be in [0, 1] rad/s, got -1'),
    (['--imu', '--imu-bias', 'nan'], '--imu-bias: must be a finite number'),
    (['--imu', '--imu-saturation', '0'], '--imu-saturation: must be in [0.01, 100] rad/s'),
    (['--gnss', '--gnss-dropout', '1.5'], '--gnss-dropout: must be in [0, 1], got 1.5'),
    (['--gnss', '--gnss-rate', '-1'], '--gnss-rate: must be in [0.1, 100] Hz, got -1'),
    (['--gnss', '--gnss-noise', 'inf'], '--gnss-noise: must be a finite number'),
    (['--gnss', '--gnss-status', 'none'], "--gnss-status: invalid choice: 'none'"),
])
def test_absurd_numbers_are_one_line_before_any_work(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        simulate_cli.main([str(tmp_path / 'out')] + argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count('\n') == 1 and message in err, err
    assert list(tmp_path.iterdir()) == []


def test_sample_count_is_bounded_before_allocating(tmp_path, capsys):
    # Each within its range, together 72 million samples: refused, naming both flags.
    assert simulate_cli.main([str(tmp_path / 'out'), '--duration', '36000', '--rate',
                              '2000', '--setpoint-rate', '50']) == 2
    err = capsys.readouterr().err
    assert err == ('simulate_bag: error: --duration 36000 s at --rate 2000 Hz is 72,000,000 '
                   'samples (at most 1,000,000); shorten --duration or lower --rate\n')
    assert list(tmp_path.iterdir()) == []


def test_cli_refuses_to_overwrite(tmp_path, capsys):
    (tmp_path / 'out').mkdir()
    assert simulate_cli.main([str(tmp_path / 'out'), '--duration', '1', '--force']) == 2
    assert 'OUT {} exists; choose a new path for the bag'.format(tmp_path / 'out') in \
        capsys.readouterr().err
    assert list((tmp_path / 'out').iterdir()) == []


def test_console_scripts_run(tmp_path):
    sim = subprocess.run([str(BIN / 'simulate_bag'), 'bag', '--vehicle', 'packbot',
                          '--duration', '3'], cwd=tmp_path, capture_output=True, text=True,
                         timeout=120)
    assert sim.returncode == 0, sim.stderr
    assert (tmp_path / 'bag' / 'metadata.yaml').is_file()
    assert (tmp_path / 'bag.truth.yaml').is_file()
    plot = subprocess.run([str(BIN / 'icr_map'), 'packbot', '--n', '7', '--plot', 'map.png'],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert plot.returncode == 0, plot.stderr
    assert 'averaged model: chi =' in plot.stdout
    assert (tmp_path / 'map.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_icr_map_outputs(tmp_path, capsys):
    rc = icr_map.main(['auriga_alpha', '--n', '11', '--csv', str(tmp_path / 'map.csv'),
                       '--output', str(tmp_path / 'avg.yaml'), '--set', 'centre_of_mass.z=0'])
    out = capsys.readouterr().out
    assert rc == 0
    assert '11 x 11 pairs' in out and 'x_ICRl' in out
    icr = icr_from_values(read_params_file(tmp_path / 'avg.yaml'))
    assert icr.chi == pytest.approx(0.515, abs=0.01)
    rows = (tmp_path / 'map.csv').read_text().splitlines()
    assert rows[0].startswith('v_left,v_right') and len(rows) == 1 + 11 * 11


def test_icr_map_errors(capsys):
    assert icr_map.main(['tank']) == 2
    assert capsys.readouterr().err.startswith('icr_map: error: no vehicle file')
    for argv, message in ((['--n', '1'], '--n: must be in [2, 101], got 1'),
                          (['--n', '100000'], '--n: must be in [2, 101], got 100000'),
                          (['--max-speed', '-1'], '--max-speed: must be in [0.01, 20] m/s'),
                          (['--max-speed', 'nan'], '--max-speed: must be a finite number')):
        with pytest.raises(SystemExit) as exc:
            icr_map.main(['packbot', *argv])
        err = capsys.readouterr().err
        assert exc.value.code == 2 and err.count('\n') == 1 and message in err, err


# Outputs: the truth file, --force, signals, a full disk (issue 14 items 9-11) -----------


def test_truth_file_needs_force_and_never_becomes_the_bag(tmp_path, capsys):
    truth = tmp_path / 'true.yaml'
    truth.write_text('mine\n')
    argv = [str(tmp_path / 'bag'), '--vehicle', 'packbot', '--duration', '2', '--truth',
            str(truth)]
    assert simulate_cli.main(argv) == 2
    assert f'--truth {truth} exists; use --force to replace it' in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ['true.yaml']
    assert simulate_cli.main(argv + ['--force']) == 0
    assert read_params_file(truth)['vehicle'] == 'packbot'
    assert sorted(p.name for p in tmp_path.iterdir()) == ['bag', 'true.yaml']
    assert simulate_cli.main([str(tmp_path / 'b2'), '--truth', str(tmp_path / 'b2')]) == 2
    assert '--truth and OUT name the same file' in capsys.readouterr().err


def test_a_full_disk_while_writing_the_bag_leaves_nothing(tmp_path, capsys, monkeypatch):
    import errno
    from tracked_kinematics.offline import outputs

    def full(path):
        raise OSError(errno.ENOSPC, 'No space left on device')
    monkeypatch.setattr(outputs, '_fsync_file', full)
    assert simulate_cli.main([str(tmp_path / 'bag'), '--vehicle', 'packbot', '--duration',
                              '2']) == 2
    assert capsys.readouterr().err.endswith('No space left on device\n')
    assert list(tmp_path.iterdir()) == []


def wait_for(condition, timeout=120.0):
    """Poll ``condition`` until it holds or the deadline passes; return whether it held."""
    import time
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return False


def start_long_run(tmp_path):
    """Start a simulate_bag console script that writes its bag for several seconds."""
    proc = subprocess.Popen([str(BIN / 'simulate_bag'), 'bag', '--vehicle', 'packbot',
                             '--duration', '1500'], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    # The bag's temporary directory, not the writability probe (``.bag.tmp-check-...``) that
    # comes and goes before it: a kill between the two found nothing left (a loaded machine).
    writing = wait_for(lambda: any(p.name.startswith('.bag.tmp-') and PROBE_MARK not in p.name
                                   for p in tmp_path.iterdir()))
    return proc, writing


@pytest.mark.parametrize('signum, status, reason', [
    (signal.SIGTERM, 143, 'terminated by SIGTERM'),
    # One handler for both: make stress sends SIGINT too.
    pytest.param(signal.SIGINT, 130, 'interrupted', marks=pytest.mark.long)])
def test_a_signal_while_writing_the_bag_leaves_nothing(tmp_path, signum, status, reason):
    proc, writing = start_long_run(tmp_path)
    try:
        assert writing, 'the bag was never being written'
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == status, err
    assert err == f'simulate_bag: error: {reason}\n'
    assert list(tmp_path.iterdir()) == []


def test_sigkill_while_writing_leaves_no_bag_that_blocks_a_rerun(tmp_path):
    proc, writing = start_long_run(tmp_path)
    try:
        assert writing, 'the bag was never being written'
        proc.kill()
        proc.communicate(timeout=120)
    finally:
        proc.kill()
    names = [p.name for p in tmp_path.iterdir()]
    # Only the hidden temporary directory: no bag without metadata.yaml at the target.
    assert len(names) == 1 and names[0].startswith('.bag.tmp-'), names
    rerun = subprocess.run([str(BIN / 'simulate_bag'), 'bag', '--vehicle', 'packbot',
                            '--duration', '2'], cwd=tmp_path, capture_output=True, text=True,
                           timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    assert (tmp_path / 'bag' / 'metadata.yaml').is_file()
    assert (tmp_path / 'bag' / 'bag.db3').is_file()   # named after the bag, not the temp


def test_icr_map_writes_all_outputs_or_none(tmp_path, capsys, monkeypatch):
    from tracked_kinematics.offline import plots

    def broken(path, *args):
        raise OSError(28, 'No space left on device')
    monkeypatch.setattr(plots, 'plot_icr_map', broken)
    argv = ['packbot', '--n', '5', '--csv', str(tmp_path / 'map.csv'), '--output',
            str(tmp_path / 'avg.yaml'), '--plot', str(tmp_path / 'map.png')]
    assert icr_map.main(argv) == 2
    assert capsys.readouterr().err == 'icr_map: error: [Errno 28] No space left on device\n'
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    assert icr_map.main(argv) == 0
    out = capsys.readouterr().out
    assert f'map written to {tmp_path / "map.csv"}' in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ['avg.yaml', 'map.csv', 'map.png']
    assert icr_map.main(argv) == 2   # all exist now: --force needed
    assert 'exists; use --force' in capsys.readouterr().err
    assert icr_map.main(argv + ['--force']) == 0
