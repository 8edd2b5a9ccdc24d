"""Parameter values (dotted ROS names to plain values) to core objects, and back."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
import math
import re
from typing import Any

from tracked_kinematics.core.command import CommandLimits
from tracked_kinematics.core.covariance import TrackNoise
from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag, PidMotor
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.gyro import GyroConfig
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.noise_model import NoiseModel

from .spec import check_values, missing_message, resolve
from .tables import (COMMAND_LIMIT_PARAMS, DECELERATION_LIMITS, DRIVETRAIN_DEFAULTS,
                     DRIVETRAIN_PARAMS, GYRO_NOISE_PARAMS, GYRO_PARAMS, LIMIT_FIELDS,
                     NOISE_PARAMS, TERRAIN_PARAMS)


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

    ``max_speed`` is the command speed limit in m/s (a vehicle's ``max_track_speed``). Raises
    :class:`InvalidParameters` with every problem, in ROS names (also an unstable PID loop).
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
    """Return the ``drivetrain.*`` values of a drive-train model (no acceleration limit is 0)."""
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

    ``track_width`` is required; the ICRs default to ideal drive, the scales to 1 (see
    docs/parameters.md). Raises :class:`InvalidParameters` with every problem, in ROS names.
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
    Return the command limits of cmd_vel_translator parameter values.

    0, NaN, ``inf`` or a missing limit becomes ``inf``; a deceleration limit of either sign means
    its magnitude, and 0/NaN/missing means the acceleration limit. Raises
    :class:`InvalidParameters` when a limit is not a number or a table check fails.
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


def gyro_config_from_values(values: Mapping[str, Any]) -> GyroConfig:
    """
    Return how odometry_node reads its gyro, from its parameters or a terrain file's values.

    The keys of :data:`.tables.GYRO_PARAMS` (their defaults for the missing ones; 0 for
    ``imu_saturation`` and ``imu_max_jump`` turns those gates off), checked by that table.
    What :func:`~tracked_kinematics.core.gyro.replay` must be given to reproduce the
    node (evaluate_model ``--fuse-imu``). Raises :class:`InvalidParameters` naming a value the
    table refuses.
    """
    problems = check_values(GYRO_PARAMS, values)
    if problems:
        raise InvalidParameters('; '.join(problems))
    value = {spec.name: values.get(spec.name, spec.default) for spec in GYRO_PARAMS}
    return GyroConfig(
        imu_delay=value['imu_delay'], gyro_scale=value['gyro_scale'],
        gyro_noise=value['covariance.gyro_noise'], timeout=value['imu_timeout'],
        gyro_bias=value['gyro_bias'], gyro_bias_sigma=value['gyro_bias_sigma'],
        saturation=value['imu_saturation'] or math.inf,
        max_jump=value['imu_max_jump'] or math.inf, adapt=value['adapt_slip'])


def noise_model_from_values(values: Mapping[str, Any]) -> NoiseModel:
    """
    Return the noise model odometry_node publishes with, from its parameters or a terrain file.

    The keys of :data:`.tables.NOISE_PARAMS` (their defaults for the missing ones, as the node
    has them), checked by that table; the track random walk is the mean of
    ``covariance.k_left`` and ``covariance.k_right`` (identify_icr writes the same value into
    both). Raises :class:`InvalidParameters` naming a value the table refuses.
    """
    problems = check_values(NOISE_PARAMS, values)
    if problems:
        raise InvalidParameters('; '.join(problems))
    value = {spec.name: float(values.get(spec.name, spec.default)) for spec in NOISE_PARAMS}
    return NoiseModel(track=0.5 * (value['covariance.k_left'] + value['covariance.k_right']),
                      turn=value['covariance.turn'], slip=value['covariance.slip'],
                      timing=value['covariance.timing'], floor=value['covariance.floor'],
                      scale=value['covariance.scale'])


def track_noise_from_values(values: Mapping[str, Any]) -> TrackNoise:
    """
    Return the tracks' random walk odometry_node publishes with, from a terrain file.

    ``covariance.k_left``, ``covariance.k_right`` and ``covariance.floor`` (the node's
    defaults for the missing ones).
    """
    value = {spec.name: float(values.get(spec.name, spec.default)) for spec in NOISE_PARAMS
             if spec.name in ('covariance.k_left', 'covariance.k_right', 'covariance.floor')}
    return TrackNoise(value['covariance.k_left'], value['covariance.k_right'],
                      value['covariance.floor'])


def gyro_noise_model_from_values(values: Mapping[str, Any]) -> NoiseModel:
    """
    Return the noise model odometry_node publishes with while its heading is the gyro's.

    :func:`noise_model_from_values` with the keys of :data:`.tables.GYRO_NOISE_PARAMS` that are
    set (-1, or missing: the encoders' ``slip`` and ``timing``; ``drift`` 0): a file without
    them publishes as before. Raises :class:`InvalidParameters` naming a value refused.
    """
    model = noise_model_from_values(values)
    problems = check_values(GYRO_NOISE_PARAMS, values)
    if problems:
        raise InvalidParameters('; '.join(problems))
    set_ = {spec.name.rsplit('.', 1)[1]: float(values.get(spec.name, spec.default))
            for spec in GYRO_NOISE_PARAMS}
    return replace(model, **{term: value for term, value in set_.items() if value != -1.0})
