"""Validation of the numeric fields of the core's frozen dataclasses."""

from __future__ import annotations

from dataclasses import fields
import math


def require_numbers(obj, finite=(), positive=(), non_negative=(), unbounded=()) -> None:
    """
    Convert the named numeric fields of a frozen dataclass to float and check them.

    ``finite``: any finite value; ``positive``: > 0; ``non_negative``: >= 0; ``unbounded``: may
    also be ``inf``. Raises ValueError naming the first offending field and its value.
    """
    names = {f.name for f in fields(obj)}
    for name in (*finite, *positive, *non_negative, *unbounded):
        assert name in names, name
        value = getattr(obj, name)
        if isinstance(value, bool):
            raise ValueError(f'{name} must be a number, got {value!r}')
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ValueError(f'{name} must be a number, got {value!r}') from None
        if math.isnan(value) or (math.isinf(value) and name not in unbounded):
            raise ValueError(f'{name} must be finite, got {value!r}')
        if name in positive and not value > 0.0:
            raise ValueError(f'{name} must be > 0, got {value!r}')
        if name in non_negative and not value >= 0.0:
            raise ValueError(f'{name} must be >= 0, got {value!r}')
        object.__setattr__(obj, name, value)
