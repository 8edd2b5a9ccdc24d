"""calibration_drive's finisher: the fit API in a worker process, the report's command line."""

import json
import threading
import time

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.core.recording import from_stamped_rows
from tracked_kinematics.offline.calibration_files import (
    CalibrationFiles, command, INTERRUPTED)
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
