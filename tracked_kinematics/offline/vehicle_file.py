"""
Vehicle files on the command line: the options of simulate_bag and icr_map.

Re-exports the loader of :mod:`tracked_kinematics.params.vehicles` for the tools.
"""

from __future__ import annotations

import argparse

from tracked_kinematics.params.vehicles import (load_vehicle, resolve, robot_from_values,
                                                shipped_vehicles, VEHICLE_DEFAULTS,
                                                VEHICLE_PARAMS, vehicle_path, VehicleFile)
import yaml

__all__ = ['VEHICLE_DEFAULTS', 'VEHICLE_PARAMS', 'VehicleFile', 'add_vehicle_arguments',
           'fixed', 'load_vehicle', 'overrides_from_args', 'parse_key_value', 'resolve',
           'robot_from_values', 'shipped_vehicles', 'vehicle_path']


# Command-line helpers shared by simulate_bag and icr_map ------------------------------------


def fixed(value: float, digits: int = 3) -> str:
    """Format a number in fixed point without a negative zero (``-0.000``)."""
    return f'{round(float(value), digits) + 0.0:.{digits}f}'


def parse_key_value(text: str):
    """Parse ``KEY=VALUE`` (the value as YAML: numbers, strings, booleans)."""
    key, sep, value = text.partition('=')
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f'expected KEY=VALUE, got {text!r}')
    try:
        return key.strip(), yaml.safe_load(value)
    except yaml.YAMLError:
        raise argparse.ArgumentTypeError(f'cannot read the value of {text!r}') from None


def _friction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not 0.01 <= value <= 5.0:   # rubber on dry concrete ~1, ice ~0.05
        raise argparse.ArgumentTypeError(f'must be in [0.01, 5], got {text}')
    return value


def add_vehicle_arguments(parser, positional: bool = False) -> None:
    """
    Add the vehicle and terrain options to a parser or argument group.

    ``positional``: the vehicle as an optional positional argument instead of ``--vehicle``.
    """
    help_vehicle = 'vehicle YAML file or shipped vehicle name (auriga_alpha, packbot)'
    if positional:
        parser.add_argument('vehicle', nargs='?', default='auriga_alpha', help=help_vehicle)
    else:
        parser.add_argument('--vehicle', default='auriga_alpha', help=help_vehicle)
    parser.add_argument('--mu-x', type=_friction, default=argparse.SUPPRESS,
                        help='friction coefficient along the tracks, 0.01-5 (overrides the '
                             'file)')
    parser.add_argument('--mu-y', type=_friction, default=argparse.SUPPRESS,
                        help='friction coefficient across the tracks, 0.01-5 (overrides the '
                             'file)')
    parser.add_argument('--terrain', default=argparse.SUPPRESS,
                        help='terrain name written to the outputs (overrides the file)')
    parser.add_argument('--set', action='append', type=parse_key_value,
                        default=argparse.SUPPRESS, metavar='KEY=VALUE',
                        help='override any vehicle parameter, e.g. --set centre_of_mass.z=0.4 '
                             '(repeatable)')


_FLAG_PARAMS = (('mu_x', 'friction.mu_x'), ('mu_y', 'friction.mu_y'),
                ('terrain', 'friction.terrain'),
                ('ticks_per_rev', 'encoders.ticks_per_revolution'),
                ('encoder_noise', 'encoders.velocity_noise'))


def overrides_from_args(args) -> dict:
    """Vehicle parameter overrides given on a command line (``--set`` and the shortcuts)."""
    overrides = dict(getattr(args, 'set', ()))
    for flag, key in _FLAG_PARAMS:
        value = getattr(args, flag, None)
        if value is not None:
            overrides[key] = value
    return overrides
