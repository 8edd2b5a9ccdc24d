"""
What the offline tools share below their command lines: warnings, inputs, reports, statuses.

The command lines (:mod:`tracked_kinematics.offline.cli`) and the libraries they call (the
fit of :mod:`tracked_kinematics.offline.identification`, the calibration drive's
:mod:`tracked_kinematics.offline.calibration_files`) both use these.
"""

from __future__ import annotations

import json
import sys

import numpy as np
from tracked_kinematics.core.errors import (
    ExcitationError, IdentificationError, TrackedKinematicsError)
from tracked_kinematics.offline.bags import EncoderSource
from tracked_kinematics.offline.errors import UsageError
from tracked_kinematics.params import read_params_file, unknown_terrain_parameters
from tracked_kinematics.params.dimensions import check_same_vehicle, dimensions_of

EXIT_INPUT, EXIT_EXCITATION, EXIT_FIT = 2, 3, 4
"""Exit statuses of the identification tools: bad input, too little excitation, failed fit."""


def exit_status(err: BaseException) -> int | None:
    """
    Return the exit status of one of the package's errors, or None for another exception.

    :data:`EXIT_EXCITATION` for too little excitation, :data:`EXIT_FIT` for a fit that
    failed, :data:`EXIT_INPUT` for any other
    :class:`~tracked_kinematics.core.errors.TrackedKinematicsError` and for an
    :class:`OSError`.
    """
    if isinstance(err, ExcitationError):
        return EXIT_EXCITATION
    if isinstance(err, IdentificationError):
        return EXIT_FIT
    if isinstance(err, (TrackedKinematicsError, OSError)):
        return EXIT_INPUT
    return None


def error_line(prog: str, message) -> str:
    """Return ``PROG: error: MESSAGE`` on one line, as the tools print an error."""
    return f'{prog}: error: {" ".join(str(message).split())}'


def warn(prog: str, message: str) -> None:
    """Print ``PROG: warning: MESSAGE`` on stderr (one line)."""
    print(f'{prog}: warning: {" ".join(str(message).split())}', file=sys.stderr)


def warn_unknown_terrain_keys(prog: str, path, values) -> None:
    """Warn about names of a terrain file that look like typos of known ones."""
    for message in unknown_terrain_parameters(values):
        warn(prog, f'{path}: {message}')


def read_base_file(prog: str, path) -> dict:
    """Read a ``--params`` base terrain file (``{}`` without one), warning about its typos."""
    if not path:
        return {}
    values = read_params_file(path)
    warn_unknown_terrain_keys(prog, path, values)
    return values


def refuse_another_vehicle(path, values, track_width=None, sprocket_radius=None) -> None:
    """
    Refuse ``--track-width`` / ``--sprocket-radius`` that disagree with the file beside them.

    ``values`` are the file's at ``path`` (read; None reads them, and leaves an unreadable
    file to the tool's own reading and message). Raises VehicleMismatch (exit status 2)
    naming both sources (:func:`tracked_kinematics.params.dimensions.check_same_vehicle`).
    """
    if not path:
        return
    if values is None:
        try:
            values = read_params_file(path)
        except (OSError, TrackedKinematicsError):
            return
    in_file = (str(path), dimensions_of(values))
    check_same_vehicle(('--track-width', {'track_width': track_width}), in_file)
    check_same_vehicle(('--sprocket-radius', {'sprocket_radius': sprocket_radius}), in_file)


def require_vehicle(given, where: str = '--params') -> None:
    """
    Refuse a run that lacks the vehicle's dimensions, as the nodes do (no default vehicle).

    Parameters
    ----------
    given : mapping
        Flag name (``--track-width``) to value, None when neither the flag nor ``where``
        gave it.
    where : str
        Where else the values may come from, for the message.

    Raises
    ------
    UsageError
        Naming every missing flag.

    """
    missing = [flag for flag, value in given.items() if value is None]
    if missing:
        raise UsageError(f'{" and ".join(missing)} {"is" if len(missing) == 1 else "are"} '
                         f'needed (or {where} with them): there is no default vehicle, as '
                         'diff_drive_controller needs wheel_separation and wheel_radius')


def checked_encoders(encoders: EncoderSource) -> EncoderSource:
    """
    Return ``encoders`` after refusing a joint listed for both tracks.

    Raises
    ------
    UsageError
        Naming the joints.

    """
    both = set(encoders.left_joints) & set(encoders.right_joints)
    if both:
        raise UsageError(f'--left-joints and --right-joints both list {", ".join(sorted(both))}')
    return encoders


IMU_MOUNT_KEYS = ('imu_mount.roll', 'imu_mount.pitch', 'imu_mount.yaw')
"""odometry_node's mount of the IMU in ``base_frame`` (URDF rpy, rad), as files carry it."""


def imu_mount_of(option, files) -> tuple[float, float, float]:
    """
    Return the IMU's mount ``(roll, pitch, yaw)``, rad: ``--imu-mount``, else the files'.

    ``files`` are ``(path, values)`` of the parameter files the tool reads; those carrying
    ``imu_mount.*`` keys (a missing axis is 0, as odometry_node takes it) must agree with each
    other and with ``option`` (None: not given), so that the gyro is read as the node given
    the same file reads it. Raises UsageError naming the two sources that disagree or a value
    that is no angle.
    """
    found = []
    for path, values in files:
        if not any(key in values for key in IMU_MOUNT_KEYS):
            continue
        mount = tuple(values.get(key, 0.0) for key in IMU_MOUNT_KEYS)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                   and abs(v) <= 2.0 * np.pi for v in mount):
            raise UsageError(f'{path}: imu_mount.roll/pitch/yaw must be numbers in '
                             f'[-2 pi, 2 pi] rad, got {mount}')
        found.append((str(path), tuple(float(v) for v in mount)))
    if option is not None:
        found.insert(0, ('--imu-mount', tuple(float(v) for v in option)))
    for source, mount in found[1:]:
        if mount != found[0][1]:
            raise UsageError(f'{found[0][0]} gives the IMU mount (roll, pitch, yaw) '
                             f'{found[0][1]} rad, {source} {mount}: give one mounting')
    return found[0][1] if found else (0.0, 0.0, 0.0)


def json_ready(value):
    """Return ``value`` for strict JSON: numpy as Python, a non-finite number as None."""
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if np.isfinite(value) else None
    return value


def report_json(report) -> str:
    """
    Return a JSON report as text: strict JSON, which every parser reads.

    numpy arrays as lists, numpy scalars as Python numbers, and a number that is not finite
    (a score with nothing to score, an unbounded error) as ``null``: Python's ``NaN`` and
    ``Infinity`` are no JSON.
    """
    return json.dumps(json_ready(report), indent=2, allow_nan=False,
                      default=lambda o: float(o)) + '\n'
