"""
One table of the vehicle/terrain parameters, shared by nodes, command lines and YAML files.

Each :class:`ParamSpec` carries a parameter's ROS name, default, unit, description and check,
in the spirit of generate_parameter_library's YAML in ros2_controllers. Nodes declare their
parameters from these tables (with descriptors, so ``ros2 param describe`` explains them) and
validate with the same checks at start and in their set-parameters callback; the command
lines read and write the terrain YAML through the functions below.

The terrain YAML (../shared/INTERFACE.md)::

    /**:
      ros__parameters:
        track_width: 0.42
        sprocket_radius: 0.1
        icr: {y_left: 0.353, y_right: -0.425, x: 0.032}
        scale: {left: 1.0072, right: 1.0275}
        drivetrain: {loop: first_order, delay: 0.03, max_accel: 1.5, time_constant: 0.15}

The ``drivetrain.*`` keys (:data:`DRIVETRAIN_PARAMS`, optional) describe the response of the
tracks to their setpoints (Fink & Stump sec. III-B); vehicle files use the same keys.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import math
import os
import re
import tempfile
from typing import Any

from tracked_kinematics.core.drivetrain import DriveTrain, FirstOrderLag, LOOP_KINDS, PidMotor
from tracked_kinematics.core.kinematics import IcrParams
import yaml


def finite(value) -> str | None:
    """Check: a finite number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if not math.isfinite(value):
        return f'must be finite, got {value!r}'
    return None


def positive(value) -> str | None:
    """Check: a finite number > 0."""
    return finite(value) or (None if value > 0 else f'must be > 0, got {value!r}')


def non_negative(value) -> str | None:
    """Check: a finite number >= 0."""
    return finite(value) or (None if value >= 0 else f'must be >= 0, got {value!r}')


def one_of(choices) -> Callable[[Any], str | None]:
    """Return a check: a value among ``choices``."""
    choices = tuple(choices)

    def check(value) -> str | None:
        return None if value in choices else f'must be one of {", ".join(choices)}, got {value!r}'
    return check


@dataclass(frozen=True)
class ParamSpec:
    """
    One parameter: ROS name, default (its type is the parameter's type), meaning, check.

    Attributes
    ----------
    name : str
        ROS parameter name, dots for nesting (``icr.y_left``).
    default : bool, int, float, str or list of str
        Default value; its Python type is the parameter's type.
    description : str
        What it means, shown by ``ros2 param describe``.
    unit : str
        SI unit, or '' for none.
    check : callable, optional
        ``check(value) -> message or None``; the message says what is wrong.
    read_only : bool
        Fixed after start (topics, modes).

    """

    name: str
    default: Any
    description: str
    unit: str = ''
    check: Callable[[Any], str | None] | None = None
    read_only: bool = False

    def validate(self, value) -> str | None:
        """Return an error message naming the parameter, or None when ``value`` is valid."""
        if self.check is None:
            return None
        problem = self.check(value)
        return None if problem is None else f'{self.name} {problem}'

    @property
    def full_description(self) -> str:
        """Return the description with the unit, as shown to users."""
        return f'{self.description} [{self.unit}]' if self.unit else self.description


TERRAIN_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('track_width', 0.42, 'Distance between the track centrelines (L, B)', 'm',
              positive),
    ParamSpec('sprocket_radius', 0.1,
              'Drive sprocket radius: joint angle (rad) x radius = nominal track travel', 'm',
              positive),
    ParamSpec('icr.y_left', 0.21,
              'Lateral coordinate of the left tread ICR in base_link (> 0; track_width / 2 '
              'is ideal differential drive)', 'm', finite),
    ParamSpec('icr.y_right', -0.21,
              'Lateral coordinate of the right tread ICR in base_link (< 0)', 'm', finite),
    ParamSpec('icr.x', 0.0,
              'Longitudinal coordinate of both tread ICRs in base_link (+ ahead)', 'm', finite),
    ParamSpec('scale.left', 1.0, 'Left encoder correction: true speed = scale x nominal', '',
              positive),
    ParamSpec('scale.right', 1.0, 'Right encoder correction: true speed = scale x nominal', '',
              positive),
)

TERRAIN_DEFAULTS: dict[str, Any] = {spec.name: spec.default for spec in TERRAIN_PARAMS}


DRIVETRAIN_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('drivetrain.loop', 'first_order',
              'Speed loop: ideal, first_order (time_constant) or pid_dc_motor (pid, motor)', '',
              one_of(LOOP_KINDS)),
    ParamSpec('drivetrain.delay', 0.0, 'Command delay', 's', non_negative),
    ParamSpec('drivetrain.max_accel', 0.0, 'Acceleration limit of the input shaping; 0 = none',
              'm/s^2', non_negative),
    ParamSpec('drivetrain.time_constant', 0.1, 'Time constant of the first-order loop', 's',
              positive),
    ParamSpec('drivetrain.pid.kp', 56.49, 'Proportional gain K_p (Fink & Stump eq. 6)', '',
              non_negative),
    ParamSpec('drivetrain.pid.ki', 1.11, 'Integral gain K_i', '', non_negative),
    ParamSpec('drivetrain.pid.kd', 2.77, 'Derivative gain K_d', '', non_negative),
    ParamSpec('drivetrain.motor.inertia', 0.059, 'Rotor inertia J (Fink & Stump eq. 7)',
              'kg m^2', positive),
    ParamSpec('drivetrain.motor.damping', 0.456, 'Viscous friction b', 'N m s', non_negative),
    ParamSpec('drivetrain.motor.resistance', 0.254, 'Armature resistance R', 'Ohm', positive),
    ParamSpec('drivetrain.motor.inductance', 0.253, 'Armature inductance L', 'H', positive),
    ParamSpec('drivetrain.motor.constant', 0.0294, 'Torque / back-EMF constant K', 'N m/A',
              positive),
)

DRIVETRAIN_DEFAULTS: dict[str, Any] = {spec.name: spec.default for spec in DRIVETRAIN_PARAMS}

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
    ValueError
        With every problem found, in ROS parameter names (also an unstable PID loop).

    """
    v = {**DRIVETRAIN_DEFAULTS,
         **{k: val for k, val in values.items() if k in DRIVETRAIN_DEFAULTS}}
    problems = check_values(DRIVETRAIN_PARAMS, v)
    if problems:
        raise ValueError('; '.join(problems))
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
        raise ValueError(message) from None


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


def check_values(specs, values: Mapping[str, Any]) -> list[str]:
    """Messages for every value of ``values`` that fails the check of its spec in ``specs``."""
    by_name = {spec.name: spec for spec in specs}
    problems = []
    for name, value in values.items():
        spec = by_name.get(name)
        if spec is not None:
            problem = spec.validate(value)
            if problem:
                problems.append(problem)
    return problems


def icr_from_values(values: Mapping[str, Any]) -> IcrParams:
    """
    Build and validate the kinematic model from terrain parameter values.

    Parameters
    ----------
    values : mapping
        ROS parameter names (``track_width``, ``icr.y_left``, ...) to values; missing ones
        take their defaults.

    Returns
    -------
    IcrParams

    Raises
    ------
    ValueError
        With every problem found, in ROS parameter names.

    """
    merged = {**TERRAIN_DEFAULTS, **{k: v for k, v in values.items() if k in TERRAIN_DEFAULTS}}
    problems = check_values(TERRAIN_PARAMS, merged)
    if problems:
        raise ValueError('; '.join(problems))
    try:
        return IcrParams(
            track_width=merged['track_width'], y_left=merged['icr.y_left'],
            y_right=merged['icr.y_right'], x=merged['icr.x'],
            scale_left=merged['scale.left'], scale_right=merged['scale.right'])
    except ValueError as err:
        raise ValueError(_FIELD_RE.sub(lambda m: _FIELD_TO_PARAM[m.group(1)], str(err))) from None


def values_from_icr(icr: IcrParams, sprocket_radius: float) -> dict[str, float]:
    """Terrain parameter values (ROS names) of a kinematic model."""
    return {
        'track_width': icr.track_width, 'sprocket_radius': float(sprocket_radius),
        'icr.y_left': icr.y_left, 'icr.y_right': icr.y_right, 'icr.x': icr.x,
        'scale.left': icr.scale_left, 'scale.right': icr.scale_right,
    }


def flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested mapping -> dotted names (``{'icr': {'x': 1}} -> {'icr.x': 1}``)."""
    flat = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


def nest(flat: Mapping[str, Any]) -> dict[str, Any]:
    """Dotted names -> nested mapping; inverse of :func:`flatten`."""
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        node = tree
        *parents, leaf = name.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    return tree


def read_params_file(path: str | os.PathLike, node_name: str | None = None) -> dict[str, Any]:
    """
    Parameters of a ROS 2 params file, flattened to dotted names.

    Reads the ``/**`` section and, when ``node_name`` is given, that node's section on top,
    as ``--params-file`` would. A plain mapping without ``ros__parameters`` is read as is.

    Raises
    ------
    ValueError
        When the file is not a mapping of parameters (the message names the file).
    OSError
        When it cannot be read.

    """
    with open(path, encoding='utf-8') as stream:
        try:
            doc = yaml.safe_load(stream)
        except yaml.YAMLError as err:
            raise ValueError(f'{path}: not valid YAML ({err})') from None
    if not isinstance(doc, Mapping):
        raise ValueError(f'{path}: expected a mapping of parameters')
    sections = [section for section in doc.values()
                if isinstance(section, Mapping) and 'ros__parameters' in section]
    if not sections:
        return flatten(doc)
    flat: dict[str, Any] = {}
    for key, section in doc.items():
        if not isinstance(section, Mapping) or 'ros__parameters' not in section:
            continue
        if key in ('/**', '**') or (node_name is not None
                                    and key.lstrip('/').split('/')[-1] == node_name):
            flat.update(flatten(section['ros__parameters'] or {}))
    return flat


def write_params_file(path: str | os.PathLike, values: Mapping[str, Any],
                      comment: str | None = None) -> None:
    """
    Write parameters as a ``/**: ros__parameters:`` file, atomically.

    The file is written next to its destination and renamed over it, so a reader never
    sees a half-written file and a failure leaves any old file in place.

    Parameters
    ----------
    path : path-like
        Destination.
    values : mapping
        Dotted parameter names to plain values (numbers, strings, lists, nested mappings).
    comment : str, optional
        Lines written as a YAML comment at the top.

    """
    text = yaml.safe_dump({'/**': {'ros__parameters': nest(values)}}, sort_keys=False,
                          default_flow_style=False)
    if comment:
        text = ''.join(f'# {line}\n' for line in comment.splitlines()) + text
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix='.tmp-', suffix='.yaml', dir=directory)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as stream:
            stream.write(text)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
