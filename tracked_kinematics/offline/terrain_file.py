"""
The terrain file an identification writes: the base file, the fitted model, the fit's record.

Used by identify_icr and identify_drivetrain; see docs/tools/identify_icr.md and
docs/tools/identify_drivetrain.md.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
import math
from typing import Any

from tracked_kinematics.core.errors import FitError, InvalidParameters
from tracked_kinematics.offline.outputs import Outputs
from tracked_kinematics.params import params_text


def terrain_values(base_values: Mapping[str, Any], fitted: Mapping[str, Any], *, record: str,
                   extras: Mapping[str, Any], check: Callable[[Mapping[str, Any]], Any],
                   drop: Iterable[str] = ()) -> dict[str, Any]:
    """
    Merge the values of a terrain file written after a fit, and check them.

    ``fitted`` replaces the ``base_values`` (dotted names, keeping their place); the base's
    ``record.*`` and the names or ``prefix.`` entries of ``drop`` are dropped; ``extras`` are
    written as ``record.key`` (non-finite floats left out). ``check(values)`` builds the model,
    raising ``InvalidParameters``. Return the values in file order; FitError when they give no
    valid model (nothing is to be written).
    """
    dropped = (f'{record}.', *drop)
    values = {k: v for k, v in base_values.items()
              if not any(k.startswith(d) if d.endswith('.') else k == d for d in dropped)}
    values.update(fitted)
    for key, value in extras.items():
        if isinstance(value, float) and not math.isfinite(value):
            continue   # never write a non-finite value; the key is simply absent
        values[f'{record}.{key}'] = value
    try:
        check(values)
    except InvalidParameters as err:
        raise FitError(f'the identified model is invalid, nothing written: {err}') from None
    return values


def terrain_text(values: Mapping[str, Any], *, tool: str, date: str,
                 contents: str = 'Terrain parameters', note: str = '') -> str:
    """
    Return terrain values as a ``--params-file``'s text, with a header saying who wrote it.

    The header: ``contents`` first, then ``tool``, ``date`` (ISO 8601) and ``note`` lines.
    """
    comment = (f'{contents} written by {tool} (tracked_kinematics) on {date}.\n'
               'Load with: --ros-args --params-file THIS_FILE')
    if note:
        comment += '\n' + note
    return params_text(values, comment=comment)


def write_terrain_file(path, values: Mapping[str, Any], *, tool: str, date: str,
                       contents: str = 'Terrain parameters', note: str = '',
                       force: bool = False) -> None:
    """Write :func:`terrain_text` to ``path`` through :class:`Outputs` (atomically, ``force``)."""
    with Outputs(force=force) as out:
        out.add('--output', path)
        out.write_text('--output', terrain_text(values, tool=tool, date=date,
                                                contents=contents, note=note))
