"""
Read encoder travel, ground-truth poses and setpoints from rosbags into plain arrays.

rosbag2 directories (sqlite3, mcap) and ROS 1 ``.bag`` files are read one bag at a time,
streaming only the topics asked for (:mod:`.opening`), each message reduced to a few numbers
in growing columns (:mod:`.columns`).

One message loop (:func:`.streaming.read_streams`) serves every reader: it feeds the encoder
messages to their decoder (:mod:`.joint_states`, :mod:`.side_streams`) and the others to the
decoder of the second stream, the ground truth (:mod:`.ground_truth`) for :func:`read_bag`,
the commands (:mod:`.commands`) for :func:`read_drive_bag`, both for
:func:`read_evaluation_bag`. What the streams are and how they are chosen: :mod:`.sources`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from tracked_kinematics.core.recording import Recording
from tracked_kinematics.offline.errors import BagError

from .commands import Commands
from .ground_truth import GroundTruth
from .opening import guarded
from .sources import CommandSource, EncoderSource, GroundTruthSource, SETPOINT_TOPICS
from .streaming import read_streams


class _GroundTruthAndCommands:
    """The ground truth and, when the bag has them, the commands: evaluate_model's stream."""

    def __init__(self, sources, path: Path, ref_ns: int):
        ground_truth, commands = sources
        self.ground_truth = GroundTruth(ground_truth, path, ref_ns)
        self.commands = Commands(commands, path, ref_ns, required=commands.kind != 'auto')
        self._command_ids: set = set()

    def connections(self, reader: AnyReader):
        """Return the connections of both streams (checked)."""
        ground_truth = self.ground_truth.connections(reader)
        commands = [c for c in self.commands.connections(reader) if c not in ground_truth]
        self._command_ids = {id(c) for c in commands}
        return ground_truth + commands

    def add(self, conn, msg, receive_ns) -> None:
        if id(conn) in self._command_ids:
            self.commands.add(conn, msg, receive_ns)
        else:
            self.ground_truth.add(conn, msg, receive_ns)


def read_bag(path, encoders: EncoderSource, ground_truth: GroundTruthSource,
             progress: bool = False) -> Recording:
    """
    Read one bag into a :class:`Recording`.

    Times are seconds from the first sample of either stream.

    Parameters
    ----------
    path : path-like
        rosbag2 directory or ROS 1 ``.bag`` file.
    encoders : EncoderSource
        Where the track encoders are.
    ground_truth : GroundTruthSource
        Where the ground-truth pose is.
    progress : bool
        Show a progress bar on stderr.

    Raises
    ------
    BagError
        For a missing or unreadable bag, a missing topic, joint or transform, or too few
        samples; the message is one line.

    """
    return guarded(Path(path), _read_recording, encoders, ground_truth, progress)


def _read_recording(reader, path, encoders, ground_truth, progress) -> Recording:
    enc, gt = read_streams(reader, path, encoders, GroundTruth, ground_truth, progress)
    enc_t, left, right = enc.travel()
    gt_t, x, y, yaw = gt.poses()
    t0 = min(enc_t[0], gt_t[0])
    return Recording((enc_t - t0) * 1e-9, left, right, (gt_t - t0) * 1e-9, x, y, yaw,
                     name=str(path))


def read_bags(paths, encoders: EncoderSource, ground_truth: GroundTruthSource,
              progress: bool = False) -> list[Recording]:
    """Read several bags, one :class:`Recording` each (see :func:`read_bag`)."""
    return [read_bag(p, encoders, ground_truth, progress) for p in paths]


def read_drive_bag(path, encoders: EncoderSource, setpoint_topics=SETPOINT_TOPICS,
                   progress: bool = False, commands: CommandSource | None = None) -> Recording:
    """
    Read the commanded and measured track speeds of one bag, to identify its drive train.

    Commands: std_msgs/Float64 setpoints per side (m/s of nominal track speed, as
    cmd_vel_translator publishes them), timed by the bag's receive time; or, with
    ``commands`` of kind ``cmd_vel`` (or ``auto`` on a bag without setpoints), the body twists
    of a geometry_msgs/Twist or TwistStamped topic through the ideal inverse ``v -/+ w B / 2``
    (TwistStamped timed by its stamp). Measured speeds: the joint velocities times the
    sprocket radius when the JointStates carry them, else the encoder travel differentiated
    between samples (stamped at the midpoints).

    Parameters
    ----------
    path, encoders, progress
        As :func:`read_bag`.
    setpoint_topics : pair of str
        Left and right setpoint topics (when ``commands`` is not given).
    commands : CommandSource, optional
        Where the commands are; default the setpoints on ``setpoint_topics``.

    Returns
    -------
    Recording
        With ``commands`` and, when the joints report them, ``speeds``
        (:meth:`~tracked_kinematics.core.recording.Recording.track_speeds`); times in seconds
        from the bag's start.

    Raises
    ------
    BagError
        For a missing or unreadable bag, a missing topic or joint, or too few messages.

    """
    if commands is None:
        commands = CommandSource('setpoints', tuple(setpoint_topics))
    elif commands.kind == 'none':
        raise ValueError('a drive-train bag needs commands')
    return guarded(Path(path), _read_drive, encoders, commands, progress)


def _read_drive(reader, path, encoders, commands, progress) -> Recording:
    enc, setpoints = read_streams(reader, path, encoders, Commands, commands, progress)
    t, left, right = enc.travel()
    speeds = enc.velocities()
    if speeds is None and len(t) < 2:
        raise BagError(f'{path}: fewer than two encoder samples')
    measured = {}
    if speeds is not None:
        speed_t, v_left, v_right = speeds
        measured = {'speed_t': np.asarray(speed_t) * 1e-9,
                    'speeds': np.column_stack([v_left, v_right])}
    command_t, values = setpoints.commands()
    return Recording(t * 1e-9, left, right, command_t=command_t * 1e-9, commands=values,
                     name=str(path), **measured)


def read_evaluation_bag(path, encoders: EncoderSource, ground_truth: GroundTruthSource,
                        commands: CommandSource = CommandSource('auto'),
                        progress: bool = False):
    """
    Read the encoders, the ground truth and, when the bag has them, the commands of one bag.

    One pass over the bag (evaluate_model). Times are seconds from the first sample of the
    encoders or the ground truth, as :func:`read_bag`.

    Returns
    -------
    recording : Recording
    commands : tuple or None
        ``(t, values, kind)``: times (s), ``(N, 2)`` nominal track commands (m/s) held until
        the next, and ``'setpoints'`` or ``'cmd_vel'``; None when the bag has none (with
        ``commands.kind`` ``auto`` or ``none``).

    Raises
    ------
    BagError
        As :func:`read_bag`; for commands of a kind asked for that the bag lacks; for cmd_vel
        without a track width.

    """
    return guarded(Path(path), _read_evaluation, encoders, (ground_truth, commands), progress)


def _read_evaluation(reader, path, encoders, sources, progress):
    enc, other = read_streams(reader, path, encoders, _GroundTruthAndCommands, sources, progress)
    enc_t, left, right = enc.travel()
    gt_t, x, y, yaw = other.ground_truth.poses()
    t0 = min(enc_t[0], gt_t[0])
    recording = Recording((enc_t - t0) * 1e-9, left, right, (gt_t - t0) * 1e-9, x, y, yaw,
                          name=str(path))
    found = other.commands.commands()
    if found is None:
        return recording, None
    command_t, values = found
    return recording, ((command_t - t0) * 1e-9, values, other.commands.kind)
