"""calibration_drive's finisher: the fit API in a worker process, the report's command line."""

import json
import threading
import time

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.recording import from_stamped_rows
from tracked_kinematics.offline.calibration_files import (
    CalibrationFiles, command, FITTED_KEYS, INTERRUPTED)
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.params import read_params_file

RADIUS = 0.1
TOPICS = {'joint_names': ['left_sprocket_joint', 'right_sprocket_joint'],
          'joint_states': '/robot/joint_states', 'reference': '/robot/ground_truth/odom',
          'cmd_vel': '/robot/cmd_vel', 'reference_kind': 'pose',
          'steps': [{'kind': 'straight', 'v': 0.3, 'w': 0.0, 'duration': 5.0}],
          'events': [{'t': 0.0, 'state': 'running', 'reason': ''}]}


class Log:
    """The node's logger, as lines."""

    def __init__(self):
        self.lines = []

    def info(self, message):
        self.lines.append(('info', message))

    def warning(self, message):
        self.lines.append(('warning', message))

    def error(self, message):
        self.lines.append(('error', message))


def recording(duration, seed=1):
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=duration, enc_rate=50.0, seed=seed)
    ns = (1_700_000_000e9 + np.round(rec.enc_t * 1e9)).astype(np.int64).tolist()
    gt_ns = (1_700_000_000e9 + np.round(rec.gt_t * 1e9)).astype(np.int64).tolist()
    return from_stamped_rows(
        encoder=list(zip(ns, rec.left.tolist(), rec.right.tolist())),
        pose=list(zip(gt_ns, rec.gt_x.tolist(), rec.gt_y.tolist(), rec.gt_yaw.tolist())),
        cmd=[(t, 0.3, 0.1) for t in ns[::5]])


def values(tmp_path, bag=True):
    return {'output': str(tmp_path / 'fit.yaml'), 'bag': str(tmp_path / 'bag') if bag else '',
            'force': False, 'terrain': 'floor', 'reference': 'pose', 'duration': 60.0,
            'geofence_radius': 3.0, 'max_speed': 0.5, 'max_yaw_rate': 1.0, 'track_width': B,
            'sprocket_radius': RADIUS, 'left_joints': ['left_sprocket_joint'],
            'right_joints': ['right_sprocket_joint']}


def test_a_drive_is_fitted_and_the_report_gives_the_identify_icr_command(tmp_path):
    files = CalibrationFiles(values(tmp_path))
    log = Log()
    status, fitted = files(recording(120.0), TOPICS, log)
    assert status == 0
    written = read_params_file(tmp_path / 'fit.yaml')
    assert fitted == {k: written[k] for k in fitted}
    assert written['identification.drive.bag'] == str((tmp_path / 'bag').resolve())
    assert ('info', f'wrote {tmp_path / "fit.yaml"} and {tmp_path / "fit.json"}') in log.lines
    assert any(level == 'info' and text.startswith('identify_icr: 1 bag(s)')
               for level, text in log.lines)
    report = json.loads((tmp_path / 'fit.json').read_text())
    assert report['tool'] == 'calibration_drive'
    said = report['calibration_drive']['identify_icr'].split()
    assert said[:2] == ['identify_icr', str((tmp_path / 'bag').resolve())]
    # The command line says what the fit did: identify_icr's parser gives the same options.
    options = files.options(tmp_path / 'bag', TOPICS, 'TERRAIN.yaml')
    parsed = identify_icr.options_from_args(identify_icr.build_parser().parse_args(said[1:]))
    assert parsed.encoders.topic == options.encoders.topic == TOPICS['joint_states']
    assert (parsed.encoders.left_joints, parsed.encoders.right_joints) == \
        (options.encoders.left_joints, options.encoders.right_joints)
    assert parsed.encoders.mode == options.encoders.mode
    options = options.__class__(**{
        **{k: getattr(options, k) for k in options.__slots__},
        'bags': parsed.bags, 'params': parsed.params, 'encoders': parsed.encoders})
    assert parsed == options


def test_the_command_of_an_imu_reference(tmp_path):
    files = CalibrationFiles({**values(tmp_path), 'terrain': '', 'reference': 'imu'})
    topics = {**TOPICS, 'reference': '/robot/imu/data', 'reference_kind': 'imu'}
    options = files.options('b', topics, 'base.yaml')
    assert options.ground_truth is None and options.imu_topic == '/robot/imu/data'
    argv = command(options, 'BAG', 'o.yaml', 'o.json')
    assert argv[-2:] == ['--imu-topic', '/robot/imu/data'] and '--terrain' not in argv
    parsed = identify_icr.options_from_args(identify_icr.build_parser().parse_args(argv[1:]))
    assert parsed.imu_topic == options.imu_topic and parsed.ground_truth is None


def test_a_failed_fit_writes_nothing_and_logs_why(tmp_path):
    files = CalibrationFiles(values(tmp_path, bag=False))
    log = Log()
    status, fitted = files(recording(4.0), TOPICS, log)
    assert (status, fitted) == (3, None)
    assert ('error', 'identify_icr: error: too little motion: 4 of 4 segments move (need 10); '
            'drive longer, or check the encoder topic and sprocket radius') in log.lines
    assert list(tmp_path.iterdir()) == []


def test_cancel_ends_the_fit_at_once_and_nothing_is_written(tmp_path):
    files = CalibrationFiles(values(tmp_path, bag=False))
    log = Log()
    cancelled = []

    def cancel_when_the_worker_runs():
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline:
            process = files._process
            if process is not None and process.is_alive():
                cancelled.append(time.monotonic())
                files.cancel()
                return
            time.sleep(0.01)

    canceller = threading.Thread(target=cancel_when_the_worker_runs)
    canceller.start()
    status, fitted = files(recording(3000.0), TOPICS, log)
    ended = time.monotonic()
    canceller.join()
    assert cancelled, 'the worker never ran'
    assert (status, fitted) == (INTERRUPTED, None)
    # Ended at once: the fit of 50 minutes of driving takes 10 s and more (14 s here).
    assert ended - cancelled[0] < 3.0
    assert list(tmp_path.iterdir()) == []   # no output, no report, no staged or temporary file
    assert files._process is None


IMU_TOPICS = {**TOPICS, 'reference': '/robot/imu/data', 'reference_kind': 'imu',
              'imu_frame_id': 'imu_link'}
UPSIDE_DOWN = 3.14159   # imu_mount.roll of an IMU with z down, as a user types it


def gyro_recording(z_sign, orientation=False, duration=120.0):
    """
    Return a drive with a gyro whose raw angular_velocity.z is ``z_sign`` times the yaw rate.

    With ``orientation`` the messages carry the IMU's orientation in ENU (z down for
    ``z_sign`` -1: the heading's turn followed by a half turn about x).
    """
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=duration, enc_rate=50.0,
                   gt_rate=100.0, seed=1)
    ns = (1_700_000_000e9 + np.round(rec.enc_t * 1e9)).astype(np.int64).tolist()
    rate = np.diff(np.unwrap(rec.gt_yaw)) / np.diff(rec.gt_t)
    gyro_ns = (1_700_000_000e9 + np.round(rec.gt_t[1:] * 1e9)).astype(np.int64).tolist()
    c, s = np.cos(0.5 * rec.gt_yaw[1:]), np.sin(0.5 * rec.gt_yaw[1:])
    zeros = np.zeros_like(c)
    q = np.column_stack([c, s, zeros, zeros] if z_sign < 0 else [zeros, zeros, s, c])
    cov0 = 0.01 if orientation else -1.0
    # Rows as the node records them: the heading rate it used, the message as it came.
    return from_stamped_rows(
        encoder=list(zip(ns, rec.left.tolist(), rec.right.tolist())),
        imu=[(t, w, *qq, cov0, 0.0, 0.0, z_sign * w)
             for t, w, qq in zip(gyro_ns, rate.tolist(), q.tolist())],
        cmd=[(t, 0.3, 0.1) for t in ns[::5]])


def imu_values(tmp_path, roll):
    return {**values(tmp_path), 'reference': 'imu', 'imu_mount.roll': roll,
            'imu_mount.pitch': 0.0, 'imu_mount.yaw': 0.0}


@pytest.mark.parametrize('orientation', [
    # Without an orientation the mount alone turns the rate: the same path, make stress.
    pytest.param(False, marks=pytest.mark.long), True])
def test_an_upside_down_imu_fits_as_the_upright_one_through_its_mount(tmp_path, orientation):
    fits = {}
    for name, z_sign, roll in (('upright', 1.0, 0.0), ('upside_down', -1.0, UPSIDE_DOWN)):
        (tmp_path / name).mkdir()
        files = CalibrationFiles(imu_values(tmp_path / name, roll))
        status, fits[name] = files(gyro_recording(z_sign, orientation), IMU_TOPICS, Log())
        assert status == 0, name
    for key in FITTED_KEYS:
        assert fits['upside_down'][key] == pytest.approx(fits['upright'][key], abs=1e-9)
    # The terrain file carries the mount (as identify_icr --imu-mount writes it), the report
    # the command line that fits the kept bag the same way.
    written = read_params_file(tmp_path / 'upside_down' / 'fit.yaml')
    assert (written['imu_mount.roll'], written['imu_mount.pitch'], written['imu_mount.yaw']) \
        == (UPSIDE_DOWN, 0.0, 0.0)
    assert 'imu_mount.roll' not in read_params_file(tmp_path / 'upright' / 'fit.yaml')
    said = json.loads((tmp_path / 'upside_down' / 'fit.json').read_text())[
        'calibration_drive']['identify_icr'].split()
    at = said.index('--imu-mount')
    assert said[at + 1:at + 4] == ['3.14159', '0.0', '0.0']
    parsed = identify_icr.options_from_args(identify_icr.build_parser().parse_args(said[1:]))
    assert parsed.imu_mount == (UPSIDE_DOWN, 0.0, 0.0)
    upright = json.loads((tmp_path / 'upright' / 'fit.json').read_text())
    assert '--imu-mount' not in upright['calibration_drive']['identify_icr']
    # The bag is the raw record: the gyro's z as it came (down), in its own frame.
    with AnyReader([tmp_path / 'upside_down' / 'bag']) as reader:
        conns = [c for c in reader.connections if c.topic == IMU_TOPICS['reference']]
        msgs = [reader.deserialize(raw, c.msgtype)
                for c, _, raw in reader.messages(connections=conns)]
    recorded = gyro_recording(-1.0, orientation)
    assert {m.header.frame_id for m in msgs} == {'imu_link'}
    np.testing.assert_array_equal([m.angular_velocity.z for m in msgs],
                                  recorded.gyro_omega[:, 2])
    assert np.all(recorded.gyro_omega[:, 2] == -recorded.gyro_rate)


def test_an_upside_down_imu_without_its_mount_is_refused(tmp_path):
    # The mirrored gyro read as it came: the fit refuses the swapped sign, writes nothing.
    files = CalibrationFiles(imu_values(tmp_path, 0.0))
    log = Log()
    status, fitted = files(gyro_recording(-1.0), IMU_TOPICS, log)
    assert (status, fitted) == (4, None)
    assert any(level == 'error' and 'gyro sign swapped' in text for level, text in log.lines)
    assert not (tmp_path / 'fit.yaml').exists()
