"""
One vehicle, given twice: its dimensions must agree (a terrain file of another robot is refused).

Where a tool or a node takes the track width and the sprocket radius from two places (a
terrain file and an option, a terrain file and a vehicle file, two terrain files, a file and a
``-p``), :func:`check_same_vehicle` refuses values that differ by more than rounding: the
Auriga's terrain file on the Warthog's data gives distances a third of the truth, without a
word otherwise. The nodes' start (``ros.main``) lists every source with
:func:`dimension_conflicts`. docs/model.md, "One vehicle, given twice".
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import math

from tracked_kinematics.core.errors import InvalidParameters

DIMENSIONS = ('track_width', 'sprocket_radius')
"""The vehicle's dimensions that two sources must agree on, m."""
DIMENSION_KEYS = DIMENSIONS

RELATIVE_TOLERANCE = 0.01
"""Two values agree within 1 % of the larger (0.54 for 0.5385 is rounding; 0.5 is not) ..."""

ABSOLUTE_TOLERANCE = 0.0005
"""... or within half a millimetre (a value rounded to the millimetre)."""


class VehicleMismatch(InvalidParameters):
    """Two sources give the same vehicle dimension different values (beyond rounding)."""


def dimensions_of(values: Mapping) -> dict:
    """
    Return ``{'track_width': ..., 'sprocket_radius': ...}`` of a terrain or vehicle file's values.

    Terrain files and node parameters name the radius ``sprocket_radius``, vehicle files
    ``encoders.sprocket_radius``; a dimension that is absent (or not a number) is None.
    """
    radius = values.get('sprocket_radius', values.get('encoders.sprocket_radius'))
    return {'track_width': _number(values.get('track_width')), 'sprocket_radius': _number(radius)}


def _number(value) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def same_dimension(a: float, b: float) -> bool:
    """Return whether two values of a dimension (m) agree to rounding (see the tolerances)."""
    # 1e-12: the decimal tolerances are not exact in binary (0.033 - 0.0325 > 0.0005).
    return abs(a - b) <= max(RELATIVE_TOLERANCE * max(abs(a), abs(b)), ABSOLUTE_TOLERANCE) + 1e-12


def check_same_vehicle(first: tuple[str, Mapping], second: tuple[str, Mapping],
                       keys=DIMENSIONS) -> None:
    """
    Refuse two sources of a vehicle's dimensions that disagree beyond rounding.

    Parameters
    ----------
    first, second : (str, mapping)
        Each source's name as the user knows it (``'--track-width'``, a file's path,
        ``'-p track_width'``) and its values: dimension name to value (m), None or absent
        where the source does not give it (:func:`dimensions_of` reads a file's values).
    keys : sequence of str
        The dimensions to compare.

    Raises
    ------
    VehicleMismatch
        One line naming the dimension, both values and both sources.

    """
    (name_a, values_a), (name_b, values_b) = first, second
    for key in keys:
        a, b = _number(values_a.get(key)), _number(values_b.get(key))
        if a is None or b is None or same_dimension(a, b):
            continue
        raise VehicleMismatch(
            f'{key} {a:g} m from {name_a} and {b:g} m from {name_b} differ by '
            f'{100 * abs(a - b) / max(abs(a), abs(b)):.0f} %, more than rounding (1 %): two '
            'different vehicles? give the values of the vehicle the data come from, once, or '
            'make the two sources agree')


def dimension_conflicts(sources: Iterable[tuple[str, Mapping]],
                        keys: Iterable[str] = DIMENSIONS) -> list[str]:
    """
    Return one message per dimension that two of several sources give differently.

    Parameters
    ----------
    sources : iterable of (str, mapping)
        Where the values come from, in the words a user knows (``params file grass.yaml``,
        ``-p track_width:=1.08``), and the values it gives (dotted names). A value that is
        not a finite number is passed over (its own check refuses it).
    keys : iterable of str
        The dimensions compared (:data:`DIMENSIONS`).

    Returns
    -------
    list of str
        Empty when every dimension given more than once agrees (:func:`same_dimension`);
        else, per dimension, the first source that disagrees with the first one that gave
        it, both named.

    """
    sources = list(sources)
    problems = []
    for key in keys:
        given = [(where, _number(values[key])) for where, values in sources if key in values]
        given = [(where, value) for where, value in given if value is not None]
        for where, value in given[1:]:
            first_where, first = given[0]
            if not same_dimension(first, value):
                problems.append(
                    f'{key} is {first:g} m in {first_where} but {value:g} m in {where}: one '
                    f'vehicle has one {key} (they differ by more than rounding, '
                    f'{RELATIVE_TOLERANCE:.0%} or {ABSOLUTE_TOLERANCE * 1e3:g} mm); is one of '
                    'them the file of another robot?')
                break
    return problems
