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
   ``sensor_msgs/Imu`` on the IMU topic, as it came: its angular velocity in its own frame)
   with its own stamps, and ``cmd_vel``. With ``bag``
   it is renamed onto that path (kept even when the fit fails: the drive can be fitted again
   with ``identify_icr``); without, it lives in a temporary directory removed at the end;
2. fits that bag with identify_icr's fit (:func:`tracked_kinematics.offline.identification.
   fit`, the node's terrain values as the base file) in a worker process of its own,
   spawned (never forked from the node's threads), which :meth:`CalibrationFiles.cancel`
   ends on a signal; the gyro is read through the node's ``imu_mount.*`` (``--imu-mount``:
   written to the terrain file); the equivalent ``identify_icr`` command is written into
   the report, so ``identify_icr`` on the bag gives the same result;
3. writes ``output`` and the report together (:class:`~tracked_kinematics.offline.outputs.
   Outputs`: atomic, all or none, an existing file replaced only with ``force``), the
   terrain file with an ``identification.drive.*`` record of the drive, the report with a
   ``calibration_drive`` section.
"""

from __future__ import annotations

import contextlib
from datetime import datetime, timezone
import io
import multiprocessing
from pathlib import Path
import shutil
import signal
import sys
import tempfile
import traceback

import numpy as np
from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource
from tracked_kinematics.offline.bags.writer import BagWriter
from tracked_kinematics.offline.identification import fit, FitOptions, TOOL as FIT_TOOL
from tracked_kinematics.offline.outputs import check_output, Outputs
from tracked_kinematics.offline.terrain_file import terrain_text
from tracked_kinematics.offline.tooling import (
    error_line, exit_status, IMU_MOUNT_KEYS, report_json)
from tracked_kinematics.params import icr_from_values, TERRAIN_PARAMS, write_params_file

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

    def cancel(self) -> None:
        """End a fit under way (a signal): the call returns :data:`INTERRUPTED` soon."""
        self._cancelled = True
        process = self._process
        if process is not None and process.is_alive():
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

    def options(self, bag, topics, base) -> FitOptions:
        """Return the options of the fit of the bag: identify_icr's defaults but these."""
        pose = topics['reference_kind'] == 'pose'
        return FitOptions(
            bags=(str(bag),), params=str(base),
            encoders=EncoderSource(topic=topics['joint_states'],
                                   left_joints=(topics['joint_names'][0],),
                                   right_joints=(topics['joint_names'][1],)),
            ground_truth=GroundTruthSource(topics['reference']) if pose else None,
            imu_topic=None if pose else topics['reference'],
            imu_mount=None if pose else self.imu_mount(),
            terrain=self.values['terrain'] or None)

    def imu_mount(self) -> tuple | None:
        """Return the node's ``imu_mount.*`` (roll, pitch, yaw), rad; None when all 0."""
        mount = tuple(float(self.values.get(key, 0.0)) for key in IMU_MOUNT_KEYS)
        return mount if any(mount) else None

    def _fit(self, bag, topics, log):
        work = Path(tempfile.mkdtemp(prefix='.calibration_drive-fit-', dir=self.output.parent))
        try:
            base = work / 'base.yaml'
            write_params_file(base, {k: self.values[k] for k in _BASE_KEYS if k in self.values})
            options = self.options(bag, topics, base)
            if self._cancelled:
                return INTERRUPTED, None
            status, found, out, err = self._run_worker(options)
            if self._cancelled or status is None:
                return INTERRUPTED, None
            for line in out.splitlines():
                if line.strip():
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
            return 0, self._write(*found, options, topics, log)
        finally:
            shutil.rmtree(work, ignore_errors=True)

    def _run_worker(self, options):
        """
        Fit in a spawned process; return ``(status, (values, report), stdout, stderr)``.

        The status is None when the process ended without an answer (:meth:`cancel`).
        """
        context = multiprocessing.get_context('spawn')
        receive, send = context.Pipe(duplex=False)
        process = context.Process(target=_fit_worker, args=(options, send), daemon=True,
                                  name='calibration_drive-fit')
        process.start()
        self._process = process
        send.close()    # the worker holds its end: its exit ends recv() below
        try:
            if self._cancelled:     # a signal before cancel() knew the process
                process.terminate()
            try:
                answer = receive.recv()
            except EOFError:
                answer = (None, None, '', '')
        finally:
            receive.close()
            process.join()
            self._process = None
        return answer

    def _write(self, values, report, options, topics, log):
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
        report['tool'] = TOOL
        report['bags'] = [kept] if kept else []
        report['calibration_drive'] = {
            **drive, 'steps': topics.get('steps', []), 'events': topics.get('events', []),
            'identify_icr': ' '.join(command(options, kept or 'BAG', self.output,
                                             report_path(self.output)))}
        date = datetime.now(timezone.utc).isoformat(timespec='seconds')
        with Outputs(force=self.force) as outputs:
            outputs.add('output', self.output)
            outputs.add('report', self.report)
            outputs.write_text('output', terrain_text(values, tool=TOOL, date=date))
            outputs.write_text('report', report_json(report))
        log.info(f'wrote {self.output} and {self.report}')
        return {k: float(values[k]) for k in FITTED_KEYS}


def command(options: FitOptions, bag, output, report) -> list[str]:
    """Return the identify_icr command line that fits ``bag`` as ``options`` do (the report's)."""
    encoders = options.encoders
    argv = [FIT_TOOL, str(bag), '--output', str(output), '--report', str(report),
            '--params', 'TERRAIN.yaml', '--encoder-topic', encoders.topic,
            '--left-joints', ','.join(encoders.left_joints),
            '--right-joints', ','.join(encoders.right_joints)]
    if options.ground_truth is not None:
        argv += ['--ground-truth-topic', options.ground_truth.topic]
    else:
        argv += ['--imu-topic', options.imu_topic]
    if options.imu_mount is not None:
        argv += ['--imu-mount', *map(repr, map(float, options.imu_mount))]
    if options.terrain:
        argv += ['--terrain', options.terrain]
    return argv


def _fit_worker(options: FitOptions, send) -> None:
    """
    Fit in the worker process; send ``(status, (values, report), stdout, stderr)``.

    SIGINT is ignored here (:meth:`CalibrationFiles.cancel` ends the process); what the fit
    prints is captured and sent, for the node to log.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    out, err = io.StringIO(), io.StringIO()
    found, status = None, 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            result = fit(options)
            found = (result.values, result.report)
            print(result.text)
        except Exception as error:   # noqa: B902 (every error goes to the node's log)
            status = exit_status(error)
            if status is None:      # a bug: its traceback, as a crashed tool shows it
                status = 1
                traceback.print_exc()
            else:
                print(error_line(FIT_TOOL, error), file=sys.stderr)
    send.send((status, found, out.getvalue(), err.getvalue()))
    send.close()


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
        (``pose`` or ``imu``), ``cmd_vel``; optionally ``imu_frame_id`` (the Imu's
        ``header.frame_id``, default ``base_link``). The Imu messages carry the recording's
        ``gyro_omega`` (the raw angular velocity) where it has one, else ``gyro_rate`` as z.
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
            frame = topics.get('imu_frame_id') or 'base_link'
            omega = rec.gyro_omega if rec.gyro_omega is not None else np.column_stack(
                [np.zeros_like(rec.gyro_rate), np.zeros_like(rec.gyro_rate), rec.gyro_rate])
            for t, w, q, cov0 in zip(rec.stamps_ns(rec.gyro_t).tolist(), omega.tolist(),
                                     rec.gyro_quaternion.tolist(),
                                     rec.gyro_quaternion_cov0.tolist()):
                covariance = np.zeros(9)
                covariance[0] = cov0
                msg = imu_type(header=bag.header(t, frame),
                               orientation=quat(x=q[0], y=q[1], z=q[2], w=q[3]),
                               orientation_covariance=covariance,
                               angular_velocity=vec(x=w[0], y=w[1], z=w[2]),
                               angular_velocity_covariance=np.zeros(9),
                               linear_acceleration=vec(x=0.0, y=0.0, z=0.0),
                               linear_acceleration_covariance=np.zeros(9))
                bag.write(topics['reference'], t, msg)
        if rec.cmd_vel_t is not None:
            for t, (v, w) in zip(rec.stamps_ns(rec.cmd_vel_t).tolist(), rec.cmd_vel.tolist()):
                bag.write(topics['cmd_vel'], t, bag.twist(v, w))
