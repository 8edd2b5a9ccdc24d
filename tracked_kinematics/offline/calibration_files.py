"""
The files of a calibration drive: the recording as a bag, the fit, the terrain file, the report.

:class:`CalibrationFiles` is the finisher that the ``calibration_drive`` console script gives
its node (the node, in the ``ros`` ring, writes no file itself). At start it checks the
output paths (docs/output-files.md): ``output``, the report beside it (``OUT.json``) and the
``bag`` directory. At the end of the drive it

1. writes the recording as an MCAP bag (:class:`~tracked_kinematics.offline.bags.writer.
   BagWriter`): ``/joint_states`` with one joint per side whose position is the cumulative
   encoder travel the node integrated divided by the sprocket radius (so any encoder input
   mode reads back the same), the reference (``nav_msgs/Odometry`` on the pose topic, or
   ``sensor_msgs/Imu`` on the IMU topic) with its own stamps, and ``cmd_vel``. With ``bag``
   it is renamed onto that path (kept even when the fit fails: the drive can be fitted again
   with ``identify_icr``); without, it lives in a temporary directory removed at the end;
2. runs ``identify_icr`` on that bag, as its command line (a process of its own, which
   :meth:`CalibrationFiles.cancel` ends on a signal), with the node's terrain values as
   ``--params``; the command is written into the report, so ``identify_icr`` on the bag
   gives the same result;
3. writes ``output`` and the report together (:class:`~tracked_kinematics.offline.outputs.
   Outputs`: atomic, all or none, an existing file replaced only with ``force``), the
   terrain file with an ``identification.drive.*`` record of the drive, the report with a
   ``calibration_drive`` section.
"""

from __future__ import annotations

from datetime import datetime, timezone
import json
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile

import numpy as np
from tracked_kinematics.offline.bags.writer import BagWriter
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.offline.cli.common import report_json
from tracked_kinematics.offline.outputs import check_output, Outputs
from tracked_kinematics.offline.terrain_file import terrain_text
from tracked_kinematics.params import (
    icr_from_values, read_params_file, TERRAIN_PARAMS, write_params_file)

TOOL = 'calibration_drive'
#: Keys of the node's values that go into the base file of the fit.
_BASE_KEYS = tuple(spec.name for spec in TERRAIN_PARAMS) + ('left_joints', 'right_joints')
#: The status of a fit ended by :meth:`CalibrationFiles.cancel` (as identify_icr's on SIGINT).
INTERRUPTED = 130
#: The terrain values a fit sets, and that push_to sends.
FITTED_KEYS = ('icr.y_left', 'icr.y_right', 'icr.x', 'scale.left', 'scale.right')


def report_path(output) -> Path:
    """Return the report path beside a terrain file: ``OUT.yaml`` -> ``OUT.json``."""
    output = Path(output)
    return output.with_suffix('.json') if output.suffix != '.json' else \
        output.with_name(output.name + '.report.json')


class CalibrationFiles:
    """
    Check the outputs at start; at the end write the bag, fit, write the results.

    Parameters
    ----------
    values : mapping
        The node's parameter values (``output``, ``bag``, ``force``, ``terrain``, the terrain
        and encoder values, ``reference`` and the drive's settings).

    Raises
    ------
    OutputError
        When an output path may not be written (one line naming it).

    """

    def __init__(self, values):
        self.values = dict(values)
        self.force = bool(values['force'])
        self.output = check_output('output', values['output'], self.force)
        self.report = check_output('output (its report)', report_path(self.output), self.force)
        self.bag = check_output('bag', values['bag'], directory=True) if values['bag'] \
            else None
        self._cancelled = False
        self._process = None
        if self.values['reference'] == 'imu' and not _has_imu_reference():
            raise ValueError(
                'reference imu: this identify_icr cannot fit from a gyro yet (no --imu-topic); '
                'use reference:=pose')

    def cancel(self) -> None:
        """End a fit under way (a signal): the call returns :data:`INTERRUPTED` soon."""
        self._cancelled = True
        process = self._process
        if process is not None and process.poll() is None:
            process.terminate()

    def __call__(self, recording, topics, log):
        """Write everything; return ``(exit status, fitted values or None)``."""
        if self.bag is not None:
            outputs = Outputs(force=False)
            outputs.add('bag', self.bag, directory=True)
            with outputs:
                with outputs.path('bag') as tmp:
                    write_bag(tmp, recording, topics, self.values['sprocket_radius'])
            log.info(f'wrote the recording to {self.bag}')
            return self._fit(self.bag, topics, log)
        with tempfile.TemporaryDirectory(prefix='.calibration_drive-',
                                         dir=self.output.parent) as tmp:
            bag = Path(tmp) / 'recording'
            write_bag(bag, recording, topics, self.values['sprocket_radius'])
            return self._fit(bag, topics, log)

    def command(self, bag, topics, base, output, report) -> list[str]:
        """Return the identify_icr arguments that fit the bag."""
        argv = [str(bag), '--output', str(output), '--report', str(report),
                '--params', str(base), '--encoder-topic', topics['joint_states'],
                '--left-joints', topics['joint_names'][0],
                '--right-joints', topics['joint_names'][1]]
        if topics['reference_kind'] == 'pose':
            argv += ['--ground-truth-topic', topics['reference']]
        else:
            argv += ['--imu-topic', topics['reference']]
        if self.values['terrain']:
            argv += ['--terrain', self.values['terrain']]
        return argv

    def _fit(self, bag, topics, log):
        work = Path(tempfile.mkdtemp(prefix='.calibration_drive-fit-', dir=self.output.parent))
        try:
            base = work / 'base.yaml'
            write_params_file(base, {k: self.values[k] for k in _BASE_KEYS if k in self.values})
            staged, staged_report = work / 'fit.yaml', work / 'fit.json'
            argv = self.command(bag, topics, base, staged, staged_report)
            if self._cancelled:
                return INTERRUPTED, None
            # identify_icr as a process of its own: the node can end it at once on a signal
            # (cancel); whatever it staged lies in ``work``, removed below either way.
            self._process = subprocess.Popen(
                [sys.executable, '-m', 'tracked_kinematics.offline.cli.identify_icr', *argv],
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            out, err = self._process.communicate()
            status = self._process.returncode
            if self._cancelled or status < 0:
                return INTERRUPTED, None
            for line in out.splitlines():
                if line.strip() and not line.startswith('wrote '):
                    log.info(line)
            for line in err.splitlines():
                if line.strip() and status:
                    log.error(line)
                elif line.strip():
                    log.warning(line)
            if status != 0:
                log.error(f'the fit failed (identify_icr exit status {status}): nothing '
                          'written' + (f'; the recording is kept in {self.bag}'
                                       if self.bag else ''))
                return status, None
            return 0, self._write(staged, staged_report, bag, topics, argv, log)
        finally:
            shutil.rmtree(work, ignore_errors=True)

    def _write(self, staged, staged_report, bag, topics, argv, log):
        values = read_params_file(staged)
        kept = str(self.bag.resolve()) if self.bag else None
        if kept:
            values['identification.bags'] = [kept]
        else:   # the temporary bag is gone (and an empty list is no ROS parameter)
            values.pop('identification.bags', None)
        drive = {'reference': self.values['reference'], 'reference_topic': topics['reference'],
                 'duration': float(self.values['duration']),
                 'geofence_radius': float(self.values['geofence_radius']),
                 'max_speed': float(self.values['max_speed']),
                 'max_yaw_rate': float(self.values['max_yaw_rate']),
                 'bag': kept or 'not kept (no bag parameter)'}
        values.update({f'identification.drive.{k}': v for k, v in drive.items()})
        icr_from_values(values)
        report = json.loads(staged_report.read_text())
        report['tool'] = TOOL
        report['bags'] = [kept] if kept else []
        report['calibration_drive'] = {
            **drive, 'steps': topics.get('steps', []), 'events': topics.get('events', []),
            'identify_icr': ' '.join(['identify_icr', kept or 'BAG', *_portable(
                argv[1:], self.output, report_path(self.output))])}
        date = datetime.now(timezone.utc).isoformat(timespec='seconds')
        with Outputs(force=self.force) as outputs:
            outputs.add('output', self.output)
            outputs.add('report', self.report)
            outputs.write_text('output', terrain_text(values, tool=TOOL, date=date))
            outputs.write_text('report', report_json(report))
        log.info(f'wrote {self.output} and {self.report}')
        return {k: float(values[k]) for k in FITTED_KEYS}


def _portable(argv, output, report):
    """Return the identify_icr options for the report, with the final output paths."""
    out, skip = [], False
    for i, arg in enumerate(argv):
        if skip:
            skip = False
            continue
        if arg in ('--output', '--report', '--params'):
            out += [arg, {'--output': str(output), '--report': str(report),
                          '--params': 'TERRAIN.yaml'}[arg]]
            skip = True
        else:
            out.append(arg)
    return out


def _has_imu_reference() -> bool:
    """Whether identify_icr has the gyro reference (``--imu-topic``)."""
    parser = identify_icr.build_parser()
    return any('--imu-topic' in action.option_strings for action in parser._actions)


def write_bag(path, recording, topics, sprocket_radius: float) -> None:
    """
    Write a calibration drive's recording as an MCAP bag.

    Parameters
    ----------
    path : path-like
        New rosbag2 directory.
    recording : Recording
        What the drive recorded (:func:`~tracked_kinematics.core.recording.from_stamped_rows`).
    topics : mapping
        ``joint_states``, ``joint_names`` (left, right), ``reference``, ``reference_kind``
        (``pose`` or ``imu``), ``cmd_vel``.
    sprocket_radius : float
        m; joint position = travel / radius.

    """
    rec = recording
    with BagWriter(path, 'mcap') as bag:
        names = list(topics['joint_names'])
        for t, left, right in zip(rec.stamps_ns(rec.enc_t).tolist(),
                                  (rec.left / sprocket_radius).tolist(),
                                  (rec.right / sprocket_radius).tolist()):
            bag.write(topics['joint_states'], t, bag.joint_state(t, names, (left, right)))
        if topics['reference_kind'] == 'pose':
            for t, x, y, yaw in zip(*([] if rec.gt_t is None else [
                    rec.stamps_ns(rec.gt_t).tolist(), rec.gt_x.tolist(), rec.gt_y.tolist(),
                    rec.gt_yaw.tolist()])):
                bag.write(topics['reference'], t, bag.odometry(t, x, y, yaw))
        elif rec.gyro_t is not None:
            imu_type = bag.typestore.types['sensor_msgs/msg/Imu']
            types = bag.typestore.types
            vec = types['geometry_msgs/msg/Vector3']
            quat = types['geometry_msgs/msg/Quaternion']
            for t, rate, q, cov0 in zip(rec.stamps_ns(rec.gyro_t).tolist(),
                                        rec.gyro_rate.tolist(), rec.gyro_quaternion.tolist(),
                                        rec.gyro_quaternion_cov0.tolist()):
                covariance = np.zeros(9)
                covariance[0] = cov0
                msg = imu_type(header=bag.header(t, 'base_link'),
                               orientation=quat(x=q[0], y=q[1], z=q[2], w=q[3]),
                               orientation_covariance=covariance,
                               angular_velocity=vec(x=0.0, y=0.0, z=rate),
                               angular_velocity_covariance=np.zeros(9),
                               linear_acceleration=vec(x=0.0, y=0.0, z=0.0),
                               linear_acceleration_covariance=np.zeros(9))
                bag.write(topics['reference'], t, msg)
        if rec.cmd_vel_t is not None:
            for t, (v, w) in zip(rec.stamps_ns(rec.cmd_vel_t).tolist(), rec.cmd_vel.tolist()):
                bag.write(topics['cmd_vel'], t, bag.twist(v, w))
