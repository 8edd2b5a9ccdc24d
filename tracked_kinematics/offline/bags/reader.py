"""
Read a bag into one :class:`~tracked_kinematics.core.recording.Recording`, in one pass.

:func:`read_recording` is the one bag reader of the package: identify_icr, evaluate_model,
identify_drivetrain and the demo read every bag with it, once, asking for the streams they
use (encoders always; ground truth, IMU, GNSS, commands as asked). rosbag2 directories
(sqlite3, mcap) and ROS 1 ``.bag`` files are opened by :mod:`.opening`, streamed by the one
message loop of :mod:`.streaming`, each message reduced to a few numbers in growing columns
(:mod:`.columns`) by its decoder (:mod:`.joint_states`, :mod:`.side_streams`,
:mod:`.ground_truth`, :mod:`.imu_gnss`, :mod:`.commands`). What the streams are:
:mod:`.sources`.

Time 0 is the first encoder sample of the bag (after both sides have started, for per-side
topics): the encoders are the one stream every recording has, so a stream's times do not
depend on which other streams were read, and ``t0_ns`` keeps the stamp of time 0. The other
streams may start before it (negative times).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tracked_kinematics.core.errors import SensorDataError
from tracked_kinematics.core.imu_frame import mount_rotation
from tracked_kinematics.core.recording import Recording
from tracked_kinematics.offline.errors import BagError

from .commands import Commands
from .ground_truth import GroundTruth
from .imu_gnss import Gnss, Imu, IMU_TYPES
from .opening import guarded
from .sources import CommandSource, EncoderSource, GroundTruthSource
from .streaming import encoder_stream, read_streams

IMU_AUTO = 'auto'
"""``imu_topic`` of :func:`read_recording`: the bag's one sensor_msgs/Imu topic, if any."""


def read_recording(path, encoders: EncoderSource, *,
                   ground_truth: GroundTruthSource | None = None,
                   imu_topic: str | None = None, gnss_topic: str | None = None,
                   commands: CommandSource | None = None,
                   progress: bool = False, imu_mount=(0.0, 0.0, 0.0)) -> Recording:
    """
    Read the encoders and the streams asked for of one bag, in one pass.

    Times are seconds from the first encoder sample (the module's time-0 rule); ``t0_ns`` is
    its stamp. The measured track speeds (``speed_t``, ``speeds``) are filled when the
    JointStates carry velocities.

    Parameters
    ----------
    path : path-like
        rosbag2 directory or ROS 1 ``.bag`` file.
    encoders : EncoderSource
        Where the track encoders are.
    ground_truth : GroundTruthSource, optional
        A pose: ground truth or a pose reference (``gt_*``).
    imu_topic : str, optional
        sensor_msgs/Imu, read as odometry_node reads it: the heading's rate (``gyro_rate``),
        and the heading of the orientation (``gyro_yaw``) when every message gives one that
        turns (:mod:`.imu_gnss`). :data:`IMU_AUTO`: the bag's one Imu topic, none when it has
        none or several, and no gyro (not an error) when that topic has no messages;
        ``gyro_topic`` says which.
    gnss_topic : str, optional
        sensor_msgs/NavSatFix or nav_msgs/Odometry positions (``gnss_*``).
    commands : CommandSource, optional
        The track commands (``command_*``, held until the next); cmd_vel also gives the body
        twists (``cmd_vel_*``), so ``cmd_vel_t is not None`` tells which kind was read.
        ``auto`` reads whichever the bag has, nothing when it has neither (unless
        ``required``).
    progress : bool
        Show a progress bar on stderr.
    imu_mount : tuple of float
        ``(roll, pitch, yaw)``, rad: the IMU's frame in ``base_link`` as a URDF joint's rpy,
        odometry_node's ``imu_mount.*``
        (:func:`~tracked_kinematics.core.imu_frame.mount_rotation`).

    Raises
    ------
    BagError
        For a missing or unreadable bag, a missing topic, joint or transform, a topic of
        another type, or too few samples; the message is one line.
    SensorDataError
        For an Imu topic without messages (named, not :data:`IMU_AUTO`), a GNSS without a fix.

    """
    streams = (ground_truth, (imu_topic, mount_rotation(*imu_mount)), gnss_topic, commands)
    return guarded(Path(path), _read, encoders, streams, progress)


def read_recordings(paths, encoders: EncoderSource, **streams) -> list[Recording]:
    """Read several bags, one :class:`Recording` each, by :func:`read_recording`."""
    return [read_recording(p, encoders, **streams) for p in paths]


def _read(reader, path, encoders, streams, progress) -> Recording:
    ground_truth, (imu_topic, mount), gnss_topic, commands = streams
    ref_ns = reader.start_time
    enc, enc_conns = encoder_stream(reader, path, encoders, ref_ns)
    auto = imu_topic == IMU_AUTO
    if auto:
        found = sorted({c.topic for c in reader.connections if c.msgtype in IMU_TYPES})
        imu_topic = found[0] if len(found) == 1 else None
    decoders = {}
    if imu_topic:
        decoders['imu'] = Imu(imu_topic, path, ref_ns, mount)
    if gnss_topic:
        decoders['gnss'] = Gnss(gnss_topic, path, ref_ns)
    if ground_truth is not None:
        decoders['pose'] = GroundTruth(ground_truth, path, ref_ns)
    if commands is not None and commands.kind != 'none':
        decoders['commands'] = Commands(commands, path, ref_ns)
    read_streams(reader, path, enc, enc_conns, list(decoders.values()), progress)
    return _assemble(path, enc, decoders, ref_ns, auto)


def _assemble(path, enc, decoders, ref_ns: int, auto: bool) -> Recording:
    """Put the decoded streams on the one clock: seconds from the first encoder sample."""
    enc_t, left, right = enc.travel()
    t0 = enc_t[0]

    def seconds(t):
        return (np.asarray(t) - t0) * 1e-9

    fields = {}
    speeds = enc.velocities()
    if speeds is not None:
        fields.update(speed_t=seconds(speeds[0]), speeds=np.column_stack(speeds[1:]))
    if 'pose' in decoders:
        t, x, y, yaw = decoders['pose'].poses()
        fields.update(gt_t=seconds(t), gt_x=x, gt_y=y, gt_yaw=yaw)
    if 'imu' in decoders:
        fields['gyro_topic'] = decoders['imu'].topic
        try:
            t, rate, yaw = decoders['imu'].gyro()
        except SensorDataError:
            if not auto:
                raise
        else:
            fields.update(gyro_t=seconds(t), gyro_rate=rate, gyro_yaw=yaw)
    if 'gnss' in decoders:
        t, x, y = decoders['gnss'].positions()
        fields.update(gnss_t=seconds(t), gnss_x=x, gnss_y=y)
    if 'commands' in decoders:
        found = decoders['commands'].commands()
        if found is not None:
            fields.update(command_t=seconds(found[0]), commands=found[1])
        if decoders['commands'].kind == 'cmd_vel':
            twists = decoders['commands'].body_twists()
            fields.update(cmd_vel_t=seconds(twists[:, 0]), cmd_vel=twists[:, 1:])
    try:
        return Recording(seconds(enc_t), left, right, t0_ns=int(ref_ns + round(t0)),
                         name=str(path), **fields)
    except ValueError as err:
        raise BagError(f'{path}: {err}') from None
