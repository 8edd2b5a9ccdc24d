"""
What an ICR identification hands back: the terrain values, the JSON report, the printed table.

:class:`FitResult` is the value :func:`.api.fit` (through :func:`.poses.icr_from_poses` or
:func:`.references.icr_from_references`) returns; the pieces both assemble it from (the
terrain values with their ``identification.*`` record, the ICR model as the report gives it)
are here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timezone
import math
from pathlib import Path

from tracked_kinematics.offline.terrain_file import terrain_values
from tracked_kinematics.params import icr_from_values, values_from_icr

TOOL = 'identify_icr'
"""The tool named in the report and at the head of the table (``tool`` argument)."""


@dataclass(frozen=True)
class FitResult:
    """
    An ICR identification, ready to print and to write.

    Attributes
    ----------
    values : dict
        The terrain file's values: the base file's, the fitted model's, and the record of the
        fit under ``identification.*`` (checked by :func:`tracked_kinematics.params.
        icr_from_values`); for :func:`tracked_kinematics.offline.terrain_file.terrain_text`.
    note : str
        The terrain file's header comment ('' for none).
    report : dict
        The JSON report (docs/tools/identify_icr.md, "What it writes").
    lines : tuple of str
        The table, line by line, as the tool prints it (a line may start with a newline: a
        blank line before it).
    date : str
        When it was identified, ISO 8601 UTC, as the file and the report give it.
    identification : Identification or None
        The fit of the segments (:func:`tracked_kinematics.core.identify.identify`), for the
        plot; None for a spin-in-place or a reference calibration.

    """

    values: dict
    note: str
    report: dict
    lines: tuple
    date: str
    identification: object = field(default=None, repr=False)

    @property
    def text(self) -> str:
        """Return the table as printed: the lines joined, without a final newline."""
        return '\n'.join(self.lines)


def now() -> str:
    """Return the current UTC time as the files give it (ISO 8601, seconds)."""
    return datetime.now(timezone.utc).isoformat(timespec='seconds')


def bag_names(bags) -> list[str]:
    """Return the bags as the report and the file name them: absolute paths."""
    return [str(Path(b).resolve()) for b in bags]


def finite_or_none(value):
    """Return ``value``, or None for a float that is not finite (JSON has no NaN)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def icr_summary(icr) -> dict:
    """Return an ICR model as the report gives it, with chi and e."""
    return {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
            'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
            'chi': icr.chi, 'eccentricity': icr.eccentricity}


def yaml_values(base_values, icr, radius, terrain, extras) -> dict:
    """Merge base values without the old terrain name and record, the ICR model, its record."""
    fitted = values_from_icr(icr, radius)
    if terrain:
        fitted['terrain'] = terrain
    return terrain_values(base_values or {}, fitted, record='identification', extras=extras,
                          check=icr_from_values, drop=('terrain',))
