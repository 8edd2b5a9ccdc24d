"""Reading DDC values as rcl reads them (DdcError names the key and value), writing ours."""

from __future__ import annotations

from collections.abc import Mapping
import math

from tracked_kinematics.offline.errors import DdcError

# Significant digits of the values written: 0.4 * 1.5 / 2 is written 0.3, not
# 0.30000000000000004 (a relative change of 1e-16, far below any odometry tolerance).
_DIGITS = 15


def clean(value: float) -> float:
    """Round to the significant digits written (``0.30000000000000004 -> 0.3``)."""
    return float(f'{value:.{_DIGITS}g}')


def fmt(value) -> str:
    """Format a parameter value as the report shows it (YAML spelling)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        if math.isnan(value):
            return '.nan'
        if math.isinf(value):
            return '.inf' if value > 0 else '-.inf'
        return repr(clean(value))
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(fmt(v) for v in value) + ']'
    return str(value)


def read_number(key: str, value) -> float:
    """Read a DDC number: int, float, or a string rcl reads as a double (``nan``, ``1e3``)."""
    if isinstance(value, bool):
        raise DdcError(f'{key} must be a number, got {fmt(value)}')
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        text = value.strip().lower()
        text = {'.nan': 'nan', '.inf': 'inf', '+.inf': 'inf', '-.inf': '-inf'}.get(text, text)
        try:
            return float(text)
        except ValueError:
            pass
        if '$(' in value:
            raise DdcError(f'{key} is a launch substitution ({value}); give the number itself')
    raise DdcError(f'{key} must be a number, got {value!r}')


def read_positive(p: Mapping, key: str, default: float | None = None, unit: str = '') -> float:
    """Read a finite number > 0; ``default`` when the key is absent, else it is required."""
    if key not in p:
        if default is None:
            raise DdcError(f'{key} is missing (diff_drive_controller refuses to start without '
                           'it too)')
        return default
    value = read_number(key, p[key])
    if not (math.isfinite(value) and value > 0.0):
        raise DdcError(f'{key} must be a finite number > 0{unit}, got {fmt(p[key])}')
    return value


def read_bool(key: str, value) -> bool:
    """Read a boolean, or the string ``true`` / ``false`` in any case."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in ('true', 'false'):
        return value.strip().lower() == 'true'
    raise DdcError(f'{key} must be true or false, got {value!r}')


def read_text(key: str, value) -> str:
    """Read a string."""
    if not isinstance(value, str):
        raise DdcError(f'{key} must be a string, got {value!r}')
    return value


def read_joints(key: str, value) -> list[str]:
    """Read joint names: one name or a non-empty list of non-empty names."""
    names = [value] if isinstance(value, str) else value
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise DdcError(f'{key} must be a list of joint names, got {value!r}')
    if not names:
        raise DdcError(f'{key} is empty (diff_drive_controller refuses that too)')
    if any(not n.strip() for n in names):
        raise DdcError(f'{key} contains an empty joint name: {value!r}')
    return list(names)
