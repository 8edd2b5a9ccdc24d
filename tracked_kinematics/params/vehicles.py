"""
Vehicle description files for the simulator: one table of parameters, YAML in, Robot out.

Shared by the offline tools and the ``tracked_simulator`` node; the format and shipped files
(``config/vehicles/``) are in docs/simulator.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
import os
from pathlib import Path
from typing import Any

from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.core.sim.dynamics import Vehicle
from tracked_kinematics.core.sim.simulation import Encoders, Robot
from tracked_kinematics.share import share_dir

from .files import read_params_file
from .spec import check_values, finite, non_negative, ParamSpec, positive
from .tables import DRIVETRAIN_PARAMS
from .values import drivetrain_from_values


def _text(value) -> str | None:
    return None if isinstance(value, str) else f'must be a string, got {value!r}'


VEHICLE_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('name', 'vehicle', 'Name used in reports and output files', '', _text),
    ParamSpec('track_width', 0.42, 'Distance between the track centrelines (L, B)', 'm',
              positive),
    ParamSpec('contact_length', 0.7, 'Length of the ground contact of one track', 'm',
              positive),
    ParamSpec('contact_width', 0.15, 'Width of one track belt', 'm', positive),
    ParamSpec('mass', 258.0, 'Vehicle mass', 'kg', positive),
    ParamSpec('centre_of_mass.x', 0.0, 'Centre of mass, forward of base_link', 'm', finite),
    ParamSpec('centre_of_mass.y', 0.0, 'Centre of mass, left of base_link', 'm', finite),
    ParamSpec('centre_of_mass.z', 0.0,
              "Height of the centre of mass; 0 = no inertia (the paper's quasi-static model), "
              '> 0 adds centripetal force and load transfer in turns', 'm', non_negative),
    ParamSpec('max_track_speed', 1.0, 'Largest track speed (commands are limited to it)', 'm/s',
              positive),
    ParamSpec('friction.terrain', 'hard_floor', 'Name of the terrain the friction describes',
              '', _text),
    ParamSpec('friction.mu_x', 0.6, 'Coulomb friction coefficient along the tracks', '',
              positive),
    ParamSpec('friction.mu_y', 0.75, 'Coulomb friction coefficient across the tracks', '',
              positive),
    *DRIVETRAIN_PARAMS,
    ParamSpec('encoders.sprocket_radius', 0.1,
              'Nominal sprocket radius: joint angle x radius = nominal track travel', 'm',
              positive),
    ParamSpec('encoders.ticks_per_revolution', 0.0,
              'Encoder ticks per sprocket revolution; 0 = no quantisation', '', non_negative),
    ParamSpec('encoders.scale.left', 1.0, 'True left track speed / nominal (encoder) speed', '',
              positive),
    ParamSpec('encoders.scale.right', 1.0, 'True right track speed / nominal speed', '',
              positive),
    ParamSpec('encoders.position_noise', 0.0, 'White noise on reported joint positions', 'rad',
              non_negative),
    ParamSpec('encoders.velocity_noise', 0.0, 'White noise on reported joint velocities',
              'rad/s', non_negative),
)

VEHICLE_DEFAULTS: dict[str, Any] = {spec.name: spec.default for spec in VEHICLE_PARAMS}


@dataclass(frozen=True)
class VehicleFile:
    """A loaded vehicle: its ``robot``, ``values`` (dotted, defaults filled) and ``path``."""

    robot: Robot
    values: dict
    path: Path | None

    @property
    def name(self) -> str:
        """Vehicle name."""
        return self.values['name']

    @property
    def terrain(self) -> str:
        """Terrain name of the friction coefficients."""
        return self.values['friction.terrain']


def shipped_vehicles() -> list[str]:
    """Names of the vehicle files shipped in ``config/vehicles/``."""
    try:
        folder = share_dir() / 'config' / 'vehicles'
    except FileNotFoundError:
        return []
    return sorted(p.stem for p in folder.glob('*.yaml'))


def resolve(name_or_path: str | os.PathLike) -> Path:
    """Return the path of a vehicle file or of a shipped vehicle named without path."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    if path.suffix == '' and path.parent == Path('.'):
        try:
            shipped = share_dir() / 'config' / 'vehicles' / f'{path.name}.yaml'
        except FileNotFoundError:
            shipped = None
        if shipped is not None and shipped.is_file():
            return shipped
    raise FileNotFoundError(
        f'no vehicle file {os.fspath(name_or_path)!r} (a path, or one of the shipped '
        f'vehicles: {", ".join(shipped_vehicles()) or "none found"})')


def vehicle_path(name_or_path: str | os.PathLike) -> Path | None:
    """Return the file :func:`resolve` finds, or None (for an output check)."""
    try:
        return resolve(name_or_path)
    except FileNotFoundError:
        return None


def robot_from_values(values: Mapping[str, Any]) -> Robot:
    """Build the simulated robot from dotted vehicle values (InvalidParameters names them)."""
    unknown = sorted(set(values) - set(VEHICLE_DEFAULTS))
    if unknown:
        raise InvalidParameters(f'unknown vehicle parameter(s) {", ".join(unknown)}; known: '
                                f'{", ".join(VEHICLE_DEFAULTS)}')
    v = {**VEHICLE_DEFAULTS, **values}
    problems = check_values(VEHICLE_PARAMS, v)
    if problems:
        raise InvalidParameters('; '.join(problems))
    v = {k: float(val) if type(val) is int else val for k, val in v.items()}  # YAML's 1 is 1.0
    try:
        vehicle = Vehicle(
            track_width=v['track_width'], contact_length=v['contact_length'],
            contact_width=v['contact_width'], mass=v['mass'], com_x=v['centre_of_mass.x'],
            com_y=v['centre_of_mass.y'], com_height=v['centre_of_mass.z'],
            mu_x=v['friction.mu_x'], mu_y=v['friction.mu_y'],
            max_track_speed=v['max_track_speed'], name=v['name'])
        drivetrain = drivetrain_from_values(v, max_speed=v['max_track_speed'])
        encoders = Encoders(
            sprocket_radius=v['encoders.sprocket_radius'],
            ticks_per_revolution=v['encoders.ticks_per_revolution'],
            scale_left=v['encoders.scale.left'], scale_right=v['encoders.scale.right'],
            position_noise=v['encoders.position_noise'],
            velocity_noise=v['encoders.velocity_noise'])
    except ValueError as err:
        raise InvalidParameters(_to_yaml_names(str(err))) from None
    return Robot(vehicle, drivetrain, encoders)


_FIELD_NAMES = {
    'com_x': 'centre_of_mass.x', 'com_y': 'centre_of_mass.y', 'com_height': 'centre_of_mass.z',
    'mu_x': 'friction.mu_x', 'mu_y': 'friction.mu_y',
    'ticks_per_revolution': 'encoders.ticks_per_revolution',
    'sprocket_radius': 'encoders.sprocket_radius', 'scale_left': 'encoders.scale.left',
    'scale_right': 'encoders.scale.right',
}


def _to_yaml_names(message: str) -> str:
    for field_name, param in _FIELD_NAMES.items():
        if message.startswith(field_name + ' ') or message.startswith(field_name + ' ='):
            return param + message[len(field_name):]
    return message


def load_vehicle(name_or_path: str | os.PathLike,
                 overrides: Mapping[str, Any] | None = None) -> VehicleFile:
    """
    Read a vehicle file (or a shipped vehicle by name) and build its robot.

    ``overrides`` maps dotted names to values that replace the file's (``friction.mu_y``). Raises
    FileNotFoundError, or InvalidParameters naming the file and the parameters.
    """
    path = resolve(name_or_path)
    try:
        values = read_params_file(path)
        values.update(overrides or {})
        robot = robot_from_values(values)
    except InvalidParameters as err:
        raise InvalidParameters(f'{path}: {err}') from None
    return VehicleFile(robot, {**VEHICLE_DEFAULTS, **values}, path)
