"""
One vehicle per run: its dimensions, given twice, must agree.

A terrain file of another robot beside the robot's own values (another file, a ``-p``, a
tool's ``--track-width``) gives distances off by their ratio, silently (the Auriga's file on
the Warthog's data: a third of the truth). Where ``track_width`` or ``sprocket_radius``
arrives from two sources, :func:`dimension_conflicts` names both when they differ beyond
rounding (:func:`same_dimension`). Used by the nodes' start (``ros.main``) and the tools.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import math
from typing import Any

#: The vehicle's dimensions that a terrain file and the robot's own values both give.
DIMENSION_KEYS = ('track_width', 'sprocket_radius')
#: Largest relative difference that is rounding (a value written with 3 significant digits).
RELATIVE_TOLERANCE = 0.005
#: Largest absolute difference that is rounding, m (a value written to the millimetre).
ABSOLUTE_TOLERANCE = 0.0005


def same_dimension(a: float, b: float) -> bool:
    """
    Return whether two values of one dimension (m) agree within rounding.

    Within 0.5 % of the larger or 0.5 mm: ``0.5384615`` and ``0.538`` agree, the Auriga's
    0.42 m and the Warthog's 1.08 m do not.
    """
    return math.isclose(a, b, rel_tol=RELATIVE_TOLERANCE, abs_tol=ABSOLUTE_TOLERANCE)


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def dimension_conflicts(sources: Iterable[tuple[str, Mapping[str, Any]]],
                        keys: Iterable[str] = DIMENSION_KEYS) -> list[str]:
    """
    Return one message per dimension that two sources give differently beyond rounding.

    Parameters
    ----------
    sources : iterable of (str, mapping)
        Where the values come from, in the words a user knows (``params file grass.yaml``,
        ``-p track_width:=1.08``, ``--track-width``), and the values it gives (dotted names).
        A value that is not a finite number is passed over (its own check refuses it).
    keys : iterable of str
        The dimensions compared (:data:`DIMENSION_KEYS`).

    Returns
    -------
    list of str
        Empty when every dimension given more than once agrees; else, per dimension, the
        first source that disagrees with the first one that gave it, both named.

    """
    sources = list(sources)
    problems = []
    for key in keys:
        given = [(where, _number(values[key])) for where, values in sources if key in values]
        given = [(where, value) for where, value in given if value is not None]
        if not given:
            continue
        first_where, first = given[0]
        for where, value in given[1:]:
            if not same_dimension(first, value):
                problems.append(
                    f'{key} is {first:g} m in {first_where} but {value:g} m in {where}: one '
                    f'vehicle has one {key} (they differ by more than rounding, '
                    f'{RELATIVE_TOLERANCE:.1%} or {ABSOLUTE_TOLERANCE * 1e3:g} mm); is one of '
                    'them the file of another robot?')
                break
    return problems
