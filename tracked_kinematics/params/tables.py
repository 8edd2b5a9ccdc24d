"""
The parameter tables: one vocabulary for nodes, command lines, YAML files and the docs.

Terrain and drive train (Fink & Stump sec. III-B), encoder inputs and command limits; the
terrain file's keys are listed in docs/parameters.md (generated from these tables).
"""

from __future__ import annotations

import math
from typing import Any

from tracked_kinematics.core.command import TRACK_SPEED_ENVELOPE
from tracked_kinematics.core.covariance import TrackNoise
from tracked_kinematics.core.drivetrain import LOOP_KINDS
from tracked_kinematics.core.encoder_modes import ENCODER_DECODERS, JointStatesDecoder, TICK_TYPES
from tracked_kinematics.core.gyro import GyroConfig, PLAUSIBLE_RATE_JUMP, PLAUSIBLE_YAW_RATE
from tracked_kinematics.core.noise_model import PRIOR

from .spec import (Derived, described_as, finite, non_negative, one_of, ParamSpec, positive,
                   unknown_parameters)


def _half_track(sign: float) -> Derived:
    return Derived(f'{"+" if sign > 0 else "-"}track_width / 2',
                   lambda values: sign * 0.5 * float(values['track_width']))


TERRAIN_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('track_width', 0.42, 'Distance between the track centrelines (L, B)', 'm',
              positive, low=0.01, high=20.0, required=True),
    ParamSpec('sprocket_radius', 0.1,
              'Drive sprocket radius: joint angle (rad) x radius = nominal track travel', 'm',
              positive, low=0.005, high=5.0, required=True),
    ParamSpec('icr.y_left', 0.21,
              'Lateral coordinate of the left tread ICR in base_link (> 0; track_width / 2 '
              'is ideal differential drive)', 'm', finite, low=-100.0, high=100.0,
              derived=_half_track(1.0)),
    ParamSpec('icr.y_right', -0.21,
              'Lateral coordinate of the right tread ICR in base_link (< 0)', 'm', finite,
              low=-100.0, high=100.0, derived=_half_track(-1.0)),
    ParamSpec('icr.x', 0.0,
              'Longitudinal coordinate of both tread ICRs in base_link (+ ahead)', 'm', finite,
              low=-100.0, high=100.0),
    ParamSpec('scale.left', 1.0, 'Left encoder correction: true speed = scale x nominal', '',
              positive, low=0.1, high=10.0),
    ParamSpec('scale.right', 1.0, 'Right encoder correction: true speed = scale x nominal', '',
              positive, low=0.1, high=10.0),
)

# The ``default`` of each terrain spec. Only icr.x and the scales have real defaults:
# track_width and sprocket_radius are required and icr.y_* derived (see
# :func:`~tracked_kinematics.params.spec.resolve` and :func:`.values.icr_from_values`); their
# entries here are the Auriga's example values, kept for the offline tools' own command-line
# defaults until those follow the same rule. Nodes never use them.
TERRAIN_DEFAULTS: dict[str, Any] = {spec.name: spec.default for spec in TERRAIN_PARAMS}


DRIVETRAIN_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('drivetrain.loop', 'first_order',
              'Speed loop: ideal, first_order (time_constant) or pid_dc_motor (pid, motor)', '',
              one_of(LOOP_KINDS)),
    ParamSpec('drivetrain.delay', 0.0, 'Command delay', 's', non_negative, low=0.0, high=10.0),
    ParamSpec('drivetrain.max_accel', 0.0, 'Acceleration limit of the input shaping; 0 = none',
              'm/s^2', non_negative, low=0.0, high=1000.0),
    ParamSpec('drivetrain.time_constant', 0.1, 'Time constant of the first-order loop', 's',
              positive, low=1e-4, high=100.0),
    ParamSpec('drivetrain.pid.kp', 56.49, 'Proportional gain K_p (Fink & Stump eq. 6)', '',
              non_negative, low=0.0, high=1e6),
    ParamSpec('drivetrain.pid.ki', 1.11, 'Integral gain K_i', '', non_negative, low=0.0,
              high=1e6),
    ParamSpec('drivetrain.pid.kd', 2.77, 'Derivative gain K_d', '', non_negative, low=0.0,
              high=1e6),
    ParamSpec('drivetrain.motor.inertia', 0.059, 'Rotor inertia J (Fink & Stump eq. 7)',
              'kg m^2', positive, low=1e-9, high=1e3),
    ParamSpec('drivetrain.motor.damping', 0.456, 'Viscous friction b', 'N m s', non_negative,
              low=0.0, high=1e3),
    ParamSpec('drivetrain.motor.resistance', 0.254, 'Armature resistance R', 'Ohm', positive,
              low=1e-6, high=1e3),
    ParamSpec('drivetrain.motor.inductance', 0.253, 'Armature inductance L', 'H', positive,
              low=1e-9, high=1e3),
    ParamSpec('drivetrain.motor.constant', 0.0294, 'Torque / back-EMF constant K', 'N m/A',
              positive, low=1e-6, high=1e3),
)

DRIVETRAIN_DEFAULTS: dict[str, Any] = {spec.name: spec.default for spec in DRIVETRAIN_PARAMS}


# Encoder input ---------------------------------------------------------------------------

# The modes, their topics and message types are the decoders' (core.encoder_modes).
INPUT_MODES = tuple(ENCODER_DECODERS)
TICKS_TYPES = tuple(TICK_TYPES)
# Per-side topics of the track_speeds and encoder_ticks modes (relative names).
SIDE_TOPICS = {mode: decoder.topics for mode, decoder in ENCODER_DECODERS.items()
               if decoder.per_side}
JOINT_STATES_TOPIC = JointStatesDecoder.topics[0]
_MODE_TEXTS = [f'{mode} ({decoder.summary})' for mode, decoder in ENCODER_DECODERS.items()]


@described_as('at least one joint, no empty names')
def _joint_list(value):
    if not value:
        return 'must name at least one joint'
    if any(not name for name in value):
        return f'must not contain empty names, got {value!r}'
    return None


ENCODER_INPUT_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('input_mode', 'joint_states',
              f'Encoder input: {", ".join(_MODE_TEXTS[:-1])} or {_MODE_TEXTS[-1]}',
              check=one_of(INPUT_MODES), read_only=True),
    ParamSpec('left_joints', ['left_sprocket_joint'],
              'JointState joints of the left track, averaged', check=_joint_list),
    ParamSpec('right_joints', ['right_sprocket_joint'],
              'JointState joints of the right track, averaged', check=_joint_list),
    ParamSpec('ticks_type', 'int32', 'Message type of the tick counters: int32 or int64',
              check=one_of(TICKS_TYPES), read_only=True),
    ParamSpec('ticks_per_revolution', 4096.0,
              'Encoder ticks per sprocket revolution (after any gearing)', 'ticks/rev',
              positive, low=1.0, high=1e9),
    ParamSpec('max_dt', 0.5,
              'Longest gap between two velocity samples that is bridged (trapezoidal rule); '
              'a longer one restarts from the new sample. Positions and tick counters '
              'integrate across any gap: their travel is exact', 's', positive, low=1e-3,
              high=60.0),
    ParamSpec('max_plausible_speed', 10.0,
              'Fastest plausible track speed: an encoder step that implies a faster one (a '
              'counter restart, a glitch, garbage) is skipped with a warning', 'm/s', positive,
              low=0.01, high=1000.0),
)

ENCODER_INPUT_DEFAULTS: dict[str, Any] = {spec.name: spec.default
                                          for spec in ENCODER_INPUT_PARAMS}


# Command limits --------------------------------------------------------------------------


@described_as('>= 0; 0, NaN (.NAN) or .inf = no limit')
def limit_value(value) -> str | None:
    """Check: a limit, a number >= 0; 0, NaN (diff_drive_controller's ``.NAN``) or inf is none."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if math.isnan(value):
        return None
    if not value >= 0.0:
        return f'must be >= 0 (0, .NAN or .inf for no limit), got {value!r}'
    return None


@described_as('either sign (its magnitude); 0, NaN or .inf = as the acceleration limit')
def deceleration_value(value) -> str | None:
    """Check: a deceleration limit of either sign (diff_drive_controller writes it negative)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if value == -math.inf:
        return f'must not be -inf (.inf for no deceleration limit), got {value!r}'
    return None


_NO_LIMIT = '; 0, .NAN or .inf = no limit'
_DECEL = ('; either sign (diff_drive_controller writes it negative); 0 or .NAN = the '
          'acceleration limit, .inf = none')

#: Largest values of the limits, the physical range of a tracked vehicle: a setting beyond is
#: a mistake, not a vehicle. The speed range is the command path's envelope.
MAX_TRACK_SPEED = TRACK_SPEED_ENVELOPE  # m/s
MAX_TRACK_ACCEL = 100.0  # m/s^2, 10 g
MAX_YAW_RATE = 50.0  # rad/s, 8 turns a second
MAX_YAW_ACCEL = 1000.0  # rad/s^2

# Limit parameter -> field of CommandLimits.
LIMIT_FIELDS = {
    'max_track_speed': 'max_track_speed',
    'max_track_accel': 'max_track_accel',
    'max_track_decel': 'max_track_decel',
    'linear.x.max_velocity': 'max_linear_velocity',
    'linear.x.max_acceleration': 'max_linear_acceleration',
    'linear.x.max_deceleration': 'max_linear_deceleration',
    'angular.z.max_velocity': 'max_angular_velocity',
    'angular.z.max_acceleration': 'max_angular_acceleration',
    'angular.z.max_deceleration': 'max_angular_deceleration',
}

#: The deceleration limits among :data:`LIMIT_FIELDS`.
DECELERATION_LIMITS = ('max_track_decel', 'linear.x.max_deceleration',
                       'angular.z.max_deceleration')


def _limit(name, description, unit, high):
    return ParamSpec(name, 0.0, description + _NO_LIMIT, unit, limit_value, low=0.0,
                     high=high, no_limit=True)


def _deceleration(name, description, unit, high):
    return ParamSpec(name, 0.0, description + _DECEL, unit, deceleration_value, low=-high,
                     high=high, no_limit=True)


COMMAND_LIMIT_PARAMS: tuple[ParamSpec, ...] = (
    _limit('max_track_speed', 'Largest track speed setpoint; both tracks are scaled together '
           'so the path curvature is kept (the vehicle envelope, 30 m/s, applies without it)',
           'm/s', MAX_TRACK_SPEED),
    _limit('max_track_accel', 'Largest rate of change of a track speed setpoint away from '
           'zero', 'm/s^2', MAX_TRACK_ACCEL),
    _deceleration('max_track_decel', 'Largest rate of change of a track speed setpoint '
                  'toward zero', 'm/s^2', MAX_TRACK_ACCEL),
    _limit('linear.x.max_velocity', 'Largest |v_x| of the command; v_x and w are scaled '
           'together', 'm/s', MAX_TRACK_SPEED),
    _limit('linear.x.max_acceleration', 'Largest rate of change of v_x away from zero',
           'm/s^2', MAX_TRACK_ACCEL),
    _deceleration('linear.x.max_deceleration', 'Largest rate of change of v_x toward zero',
                  'm/s^2', MAX_TRACK_ACCEL),
    _limit('angular.z.max_velocity', 'Largest |w| of the command; v_x and w are scaled '
           'together', 'rad/s', MAX_YAW_RATE),
    _limit('angular.z.max_acceleration', 'Largest rate of change of w away from zero',
           'rad/s^2', MAX_YAW_ACCEL),
    _deceleration('angular.z.max_deceleration', 'Largest rate of change of w toward zero',
                  'rad/s^2', MAX_YAW_ACCEL),
)


# The odometry's noise model and gyro: odometry_node's parameters, a terrain file's keys ------

_DEFAULT_NOISE = TrackNoise()
_DEFAULT_GYRO = GyroConfig()


def _prior(term: str) -> float:
    """Return the noise model's prior of a term, to 12 digits (0.1 ** 2 is 0.01 here)."""
    return float(f'{getattr(PRIOR, term):.12g}')


NOISE_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('covariance.k_left', _DEFAULT_NOISE.k_left,
              'Variance of the left track travel per metre travelled', 'm^2/m', non_negative,
              low=0.0, high=1.0),
    ParamSpec('covariance.k_right', _DEFAULT_NOISE.k_right,
              'Variance of the right track travel per metre travelled', 'm^2/m',
              non_negative, low=0.0, high=1.0),
    ParamSpec('covariance.floor', _DEFAULT_NOISE.floor,
              'Variance added to each track travel per encoder sample', 'm^2', non_negative,
              low=0.0, high=1.0),
    ParamSpec('covariance.turn', _prior('turn'),
              'Variance of the heading per radian turned (slip varying from turn to turn; 0: '
              'off)', 'rad^2/rad', non_negative, low=0.0, high=1.0),
    ParamSpec('covariance.slip', _prior('slip'),
              'Variance of each position coordinate per radian turned on the spot (0: off)',
              'm^2/rad', non_negative, low=0.0, high=10.0),
    ParamSpec('covariance.timing', _prior('timing'),
              'Variance of the time of the odometry: the published pose covariance adds it '
              'times the current rates squared (0: off)', 's^2', non_negative,
              low=0.0, high=1.0),
    ParamSpec('covariance.scale', _prior('scale'),
              'Relative variance of the distance scale: the published position covariance adds '
              'it times the displacement since the start or the last reset squared (identify_icr '
              'writes the prior of a scale it could not fit; 0: off)', '', non_negative,
              low=0.0, high=1.0),
)
"""The noise model's constants (identify_icr fits them; odometry_node and evaluate_model read
them: :func:`.values.noise_model_from_values`)."""


@described_as("-1 (the encoders' value) or >= 0")
def _encoders_or_non_negative(value) -> str | None:
    """Check: -1 (unset: the encoders' constant) or a finite number >= 0."""
    if value == -1.0 and not isinstance(value, bool):
        return None
    problem = non_negative(value)
    return problem and f"must be -1 (the encoders' value) or >= 0, got {value!r}"


GYRO_NOISE_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('covariance.gyro_aided.slip', -1.0,
              "covariance.slip while the heading is the gyro's (identify_icr fits it on the "
              "gyro-aided odometry's windows; -1: covariance.slip)", 'm^2/rad',
              _encoders_or_non_negative, low=-1.0, high=10.0),
    ParamSpec('covariance.gyro_aided.timing', -1.0,
              "covariance.timing while the heading is the gyro's (-1: covariance.timing)",
              's^2', _encoders_or_non_negative, low=-1.0, high=1.0),
    ParamSpec('covariance.gyro_aided.drift', 0.0,
              "Relative variance of the displacement's length and direction since the start "
              "or the last reset while the heading is the gyro's: the published position "
              'covariance adds it times the displacement squared on each axis (a distance '
              'scale and a crab angle that persist; identify_icr fits it; 0: off)', '',
              non_negative, low=0.0, high=1.0),
)
"""The gyro-aided odometry's own noise constants (identify_icr fits them on the gyro-aided
windows of a pose fit whose bags carry a gyro; odometry_node with ``imu_topic`` and evaluate_model
``--fuse-imu`` read them: :func:`.values.gyro_noise_model_from_values`)."""

GYRO_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('covariance.gyro_noise', _DEFAULT_GYRO.gyro_noise,
              'White rate noise of the gyro, used until 2 s of standstill have measured it',
              'rad/s/sqrt(Hz)', non_negative, low=0.0, high=1.0),
    ParamSpec('imu_delay', _DEFAULT_GYRO.imu_delay,
              "Time by which the gyro's stamps are late on the encoders' (identify_icr's "
              'imu_delay, which it searches in [-0.5, 1] s; negative: the encoders trail the '
              'gyro; beyond 1 s the two clocks are not synchronised)', 's', finite,
              low=-1.0, high=1.0),
    ParamSpec('gyro_scale', _DEFAULT_GYRO.gyro_scale,
              'Gyro scale: measured rate over true rate', '', positive, low=0.5, high=2.0),
    ParamSpec('imu_timeout', _DEFAULT_GYRO.timeout,
              'Seconds without a gyro sample after which the heading falls back to the '
              'encoders', 's', positive, low=0.001, high=60.0),
    ParamSpec('imu_saturation', PLAUSIBLE_YAW_RATE,
              'Gyro readings at or beyond this |rate| are implausible: refused, heading from '
              'the encoders (default: beyond any ground vehicle, a 0.4-m wide robot pivoting '
              'at 2 m/s; 0: off)', 'rad/s', non_negative, low=0.0, high=1000.0),
    ParamSpec('imu_max_jump', PLAUSIBLE_RATE_JUMP,
              'Largest plausible change of the gyro rate between consecutive samples; '
              'beyond: refused (default: 100 rad/s^2, beyond what friction allows a ground '
              'vehicle, over a 20-Hz period; 0: off)', 'rad/s', non_negative, low=0.0,
              high=1000.0),
    ParamSpec('gyro_bias', _DEFAULT_GYRO.gyro_bias,
              "The gyro's bias before anything is measured (identify_icr's gyro fit)",
              'rad/s', finite, low=-1.0, high=1.0),
    ParamSpec('gyro_bias_sigma', _DEFAULT_GYRO.gyro_bias_sigma,
              'Uncertainty (1 sigma) of gyro_bias; 0: no prior, the bias is unknown until a '
              'standstill or the drive measures it', 'rad/s', non_negative, low=0.0,
              high=1.0),
    ParamSpec('adapt_slip', True,
              'Adapt the ICR spread online from the gyro (published on ~/icr)'),
)
"""How the gyro is read (odometry_node's ``imu_topic``; evaluate_model ``--fuse-imu``:
:func:`.values.gyro_config_from_values`)."""


# Names of a terrain file ---------------------------------------------------------------

TERRAIN_FILE_RECORDS = ('identification.', 'drivetrain_fit.', 'run_fit.', 'simulation.')
"""Prefixes of the records the tools write into a terrain file (provenance, statistics)."""
TERRAIN_FILE_NOTES = ('terrain', 'source', 'chi', 'eccentricity', 'vehicle',
                      'ground_truth_delay')
"""Other keys the tools write into a terrain file."""


def is_terrain_file_record(name: str) -> bool:
    """Return whether ``name`` is a record or note the tools write, not a parameter."""
    return name.startswith(TERRAIN_FILE_RECORDS) or name in TERRAIN_FILE_NOTES


_TERRAIN_GROUPS = ('icr.', 'scale.', 'drivetrain.', 'linear.', 'angular.')


def unknown_terrain_parameters(values) -> list[str]:
    """
    Return warnings for the names of a terrain file that look like typos of the known ones.

    Outside the tables' groups only names close to a known one are reported (a terrain file may
    carry node parameters); inside a group (``icr.yleft``) every unknown name is.
    """
    known = [spec.name for spec in (*TERRAIN_PARAMS, *DRIVETRAIN_PARAMS,
                                    *ENCODER_INPUT_PARAMS, *COMMAND_LIMIT_PARAMS)]
    known += list(TERRAIN_FILE_NOTES)
    names = [name for name in values if not is_terrain_file_record(name)]
    grouped = [name for name in names if name.startswith(_TERRAIN_GROUPS)]
    other = [name for name in names if not name.startswith(_TERRAIN_GROUPS)]
    ignored = ' is not used'
    return (unknown_parameters(grouped, known, ignored=ignored)
            + unknown_parameters(other, known, only_close=True, ignored=ignored))
