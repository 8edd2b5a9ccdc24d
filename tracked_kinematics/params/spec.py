"""
Parameter specifications: :class:`ParamSpec` and the checks its tables use.

Each :class:`ParamSpec` carries a parameter's ROS name, default, unit, description and check,
in the spirit of generate_parameter_library's YAML in ros2_controllers. Nodes declare their
parameters from the tables of :mod:`.tables` (with descriptors, so ``ros2 param describe``
explains them) and validate with the same checks at start and in their set-parameters
callback; the command lines validate terrain files with them.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import math
import re
from typing import Any


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


def in_range(value, low: float | None, high: float | None, unit: str = '') -> str | None:
    """
    Check: a number within ``[low, high]`` (either bound may be None).

    Not a number, and NaN, fail too; the message gives the range with its unit.
    """
    problem = finite(value) if not _is_inf(value) else None
    if problem:
        return problem
    lo = -math.inf if low is None else low
    hi = math.inf if high is None else high
    if lo <= value <= hi:
        return None
    unit = f' {unit}' if unit else ''
    if low is None:
        return f'must be <= {hi:g}{unit}, got {value!r}'
    if high is None:
        return f'must be >= {lo:g}{unit}, got {value!r}'
    return f'must be in [{lo:g}, {hi:g}]{unit}, got {value!r}'


def means_no_limit(value) -> bool:
    """Tell whether a limit value says "no limit": 0, NaN or +inf (not a bool)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and (value == 0 or math.isnan(value) or value == math.inf))


def _is_inf(value) -> bool:
    return isinstance(value, float) and math.isinf(value)


_NAME_TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*\Z')


def ros_name(value) -> str | None:
    """
    Check: a valid ROS 2 topic or service name (relative, absolute or private ``~/``).

    The rules of rcl's name validation: tokens of letters, digits and underscores that do
    not start with a digit, separated by single slashes, no double underscore, no trailing
    slash.
    """
    if not isinstance(value, str) or not value:
        return f'must be a non-empty ROS name, got {value!r}'
    if value == '~':
        return None
    body = value[2:] if value.startswith('~/') else value[1:] if value[0] == '/' else value
    if '__' not in body and all(_NAME_TOKEN.match(token) for token in body.split('/')):
        return None
    return (f'must be a valid ROS name (letters, digits, _ and /, no token starting with a '
            f'digit, no "__", no trailing /), got {value!r}')


def node_name(value) -> str | None:
    """Check: a valid ROS 2 node name, optionally with its namespace (``/ns/node``)."""
    problem = ros_name(value)
    if problem or value.startswith('~'):
        return problem or f'must be a node name, not a private name, got {value!r}'
    return None


def frame_id(value) -> str | None:
    """
    Check: a usable tf2 frame id.

    Non-empty, printable, no whitespace, no leading ``/`` (tf2 rejects it) and at most 255
    characters.
    """
    if not isinstance(value, str) or not value:
        return f'must be a non-empty frame id, got {value!r}'
    if value.startswith('/'):
        return f'must not start with "/" (tf2 frame ids are relative), got {value!r}'
    if len(value) > 255 or not value.isprintable() or any(c.isspace() for c in value):
        return f'must be printable, without spaces, at most 255 characters, got {value!r}'
    return None


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
    low, high : float, optional
        Physically meaningful range of a number, inclusive; published as the parameter's
        ``FloatingPointRange`` / ``IntegerRange`` (``ros2 param describe`` shows it) and
        checked after ``check``. A value outside is refused at start and at runtime: a rate
        of 1e-10 Hz or a radius of 5e-324 m is a number, not a vehicle.
    no_limit : bool
        A limit whose ``0``, ``NaN`` (diff_drive_controller's ``.NAN``) and ``inf`` say "no
        limit" (or, for a deceleration, "as the acceleration limit"; the description says
        which): those three pass the range check (which bounds every other value), and
        the range is published as the descriptor's ``additional_constraints`` text instead
        of a ``FloatingPointRange`` (rclpy refuses NaN and inf against one).

    """

    name: str
    default: Any
    description: str
    unit: str = ''
    check: Callable[[Any], str | None] | None = None
    read_only: bool = False
    low: float | None = None
    high: float | None = None
    no_limit: bool = False

    def validate(self, value) -> str | None:
        """Return an error message naming the parameter, or None when ``value`` is valid."""
        problem = None if self.check is None else self.check(value)
        if problem is None and self.has_range and not (self.no_limit and means_no_limit(value)):
            problem = in_range(value, self.low, self.high, self.unit)
            if problem and self.no_limit:
                problem += ' (or 0, .NAN, .inf: see its description)'
        return None if problem is None else f'{self.name} {problem}'

    @property
    def has_range(self) -> bool:
        """Whether the spec bounds its (numeric) value."""
        return self.low is not None or self.high is not None

    @property
    def full_description(self) -> str:
        """Return the description with the unit, as shown to users."""
        return f'{self.description} [{self.unit}]' if self.unit else self.description


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
