"""
Parameter values <-> core objects: the kinematic model, the drive train, the command limits.

Values are mappings of dotted ROS parameter names (``icr.y_left``) to plain values, as
:func:`tracked_kinematics.params.files.read_params_file` returns them and nodes hold them;
the functions here validate them against :mod:`.tables` and build the core's immutable
parameter objects, with errors in ROS names.
"""

from __future__ import annotations

from collections.abc import Mapping
import math
import re
from typing import Any

from tracked_kinematics.core.command import CommandLimits
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag, PidMotor
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.kinematics import IcrParams

from .spec import check_values, missing_message, resolve
from .tables import (COMMAND_LIMIT_PARAMS, DECELERATION_LIMITS, DRIVETRAIN_DEFAULTS,
                     DRIVETRAIN_PARAMS, LIMIT_FIELDS, TERRAIN_PARAMS)


_DRIVE_FIELDS = {'time_constant': 'drivetrain.time_constant', 'delay': 'drivetrain.delay',
                 'max_accel': 'drivetrain.max_accel', 'kp': 'drivetrain.pid.kp',
                 'ki': 'drivetrain.pid.ki', 'kd': 'drivetrain.pid.kd',
                 'inertia': 'drivetrain.motor.inertia', 'damping': 'drivetrain.motor.damping',
                 'resistance': 'drivetrain.motor.resistance',
                 'inductance': 'drivetrain.motor.inductance',
                 'motor_constant': 'drivetrain.motor.constant'}
_DRIVE_RE = re.compile(r'^(' + '|'.join(_DRIVE_FIELDS) + r')\b')


def drivetrain_from_values(values: Mapping[str, Any], max_speed: float = math.inf) -> DriveTrain:
    """
    Build and validate the drive-train model from ``drivetrain.*`` parameter values.

    Parameters
    ----------
    values : mapping
        Dotted parameter names to values; missing ``drivetrain.*`` ones take their defaults,
        other names are ignored.
    max_speed : float
        Speed limit of the commands, m/s (a vehicle's ``max_track_speed``).

    Returns
    -------
    DriveTrain

    Raises
    ------
    InvalidParameters
        With every problem found, in ROS parameter names (also an unstable PID loop).

    """
    v = {**DRIVETRAIN_DEFAULTS,
         **{k: val for k, val in values.items() if k in DRIVETRAIN_DEFAULTS}}
    problems = check_values(DRIVETRAIN_PARAMS, v)
    if problems:
        raise InvalidParameters('; '.join(problems))
    v = {k: float(val) if type(val) is int else val for k, val in v.items()}  # YAML's 1 is 1.0
    try:
        loop = None
        if v['drivetrain.loop'] == 'first_order':
            loop = FirstOrderLag(v['drivetrain.time_constant'])
        elif v['drivetrain.loop'] == 'pid_dc_motor':
            loop = PidMotor(
                kp=v['drivetrain.pid.kp'], ki=v['drivetrain.pid.ki'], kd=v['drivetrain.pid.kd'],
                inertia=v['drivetrain.motor.inertia'], damping=v['drivetrain.motor.damping'],
                resistance=v['drivetrain.motor.resistance'],
                inductance=v['drivetrain.motor.inductance'],
                motor_constant=v['drivetrain.motor.constant'])
        accel = v['drivetrain.max_accel']
        return DriveTrain(delay=v['drivetrain.delay'],
                          max_accel=accel if accel > 0 else math.inf, max_speed=max_speed,
                          loop=loop)
    except ValueError as err:
        message = _DRIVE_RE.sub(lambda m: _DRIVE_FIELDS[m.group(1)], str(err))
        if 'unstable' in message or 'at least one of' in message:
            message = f'drivetrain.pid: {message}'
        raise InvalidParameters(message) from None


def values_from_drivetrain(drive: DriveTrain) -> dict[str, Any]:
    """
    Return the ``drivetrain.*`` parameter values of a drive-train model.

    The inverse of :func:`drivetrain_from_values` (the speed limit is a vehicle parameter and
    is not written); no acceleration limit is written as 0.
    """
    values: dict[str, Any] = {
        'drivetrain.delay': float(drive.delay),
        'drivetrain.max_accel': float(drive.max_accel) if math.isfinite(drive.max_accel)
        else 0.0}
    loop = drive.loop
    if isinstance(loop, FirstOrderLag):
        values['drivetrain.loop'] = 'first_order'
        values['drivetrain.time_constant'] = float(loop.time_constant)
    elif isinstance(loop, PidMotor):
        values['drivetrain.loop'] = 'pid_dc_motor'
        values.update({_DRIVE_FIELDS[name]: float(getattr(loop, name)) for name in (
            'kp', 'ki', 'kd', 'inertia', 'damping', 'resistance', 'inductance',
            'motor_constant')})
    else:
        values['drivetrain.loop'] = 'ideal'
    return values


# IcrParams field -> ROS parameter name, to speak ROS in error messages.
_FIELD_TO_PARAM = {
    'track_width': 'track_width', 'y_left': 'icr.y_left', 'y_right': 'icr.y_right',
    'x': 'icr.x', 'scale_left': 'scale.left', 'scale_right': 'scale.right',
}
_FIELD_RE = re.compile(r'\b(' + '|'.join(sorted(_FIELD_TO_PARAM, key=len, reverse=True))
                       + r')\b(?!\.)')


def icr_from_values(values: Mapping[str, Any]) -> IcrParams:
    """
    Build and validate the kinematic model from terrain parameter values.

    The vehicle rule of every node and tool (docs/parameters.md): ``track_width`` has no
    default; ``icr.y_left`` / ``icr.y_right`` default to ``+-track_width / 2`` (ideal drive
    for the given width) and ``icr.x`` to 0 unless set; the scales default to 1.
    ``sprocket_radius`` is not part of the model: it is checked when given.

    Parameters
    ----------
    values : mapping
        ROS parameter names (``track_width``, ``icr.y_left``, ...) to values; other names
        are ignored.

    Returns
    -------
    IcrParams

    Raises
    ------
    InvalidParameters
        With every problem found, in ROS parameter names (also a missing ``track_width``).

    """
    merged, missing = resolve(TERRAIN_PARAMS, values)
    if 'track_width' in missing:
        raise InvalidParameters(missing_message(['track_width']))
    problems = check_values(TERRAIN_PARAMS, merged)
    if problems:
        raise InvalidParameters('; '.join(problems))
    try:
        return IcrParams(
            track_width=merged['track_width'], y_left=merged['icr.y_left'],
            y_right=merged['icr.y_right'], x=merged['icr.x'],
            scale_left=merged['scale.left'], scale_right=merged['scale.right'])
    except ValueError as err:
        raise InvalidParameters(
            _FIELD_RE.sub(lambda m: _FIELD_TO_PARAM[m.group(1)], str(err))) from None


def values_from_icr(icr: IcrParams, sprocket_radius: float) -> dict[str, float]:
    """Terrain parameter values (ROS names) of a kinematic model."""
    return {
        'track_width': icr.track_width, 'sprocket_radius': float(sprocket_radius),
        'icr.y_left': icr.y_left, 'icr.y_right': icr.y_right, 'icr.x': icr.x,
        'scale.left': icr.scale_left, 'scale.right': icr.scale_right,
    }


def limits_from_values(values: Mapping[str, Any]) -> CommandLimits:
    """
    Command limits from cmd_vel_translator parameter values.

    0, NaN (diff_drive_controller's ``.NAN``), ``.inf`` or a missing name is no limit, and
    becomes ``inf`` here: no NaN reaches the command path. A deceleration limit may be
    written with either sign (diff_drive_controller writes it negative) and means its
    magnitude; 0, NaN or a missing one is the matching acceleration limit.

    Raises
    ------
    InvalidParameters
        When a limit is not a number (message in ROS names), or one of the checks of
        :data:`~tracked_kinematics.params.tables.COMMAND_LIMIT_PARAMS` fails.

    """
    problems = check_values(COMMAND_LIMIT_PARAMS, values)
    if problems:
        raise InvalidParameters('; '.join(problems))
    limits = {}
    for name, field in LIMIT_FIELDS.items():
        value = values.get(name, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidParameters(f'{name} must be a number, got {value!r}')
        value = abs(float(value))
        if value == 0.0 or math.isnan(value):
            if name in DECELERATION_LIMITS:
                continue  # CommandLimits: None = the acceleration limit
            value = math.inf
        limits[field] = value
    return CommandLimits(**limits)
