"""
Parameter specifications: :class:`ParamSpec`, its checks and the default rule (:func:`resolve`).

Nodes declare their parameters from these specs (with descriptors) and validate with the same
checks at start and at runtime; see docs/parameters.md.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
import difflib
import math
import re
from typing import Any


def described_as(words: str) -> Callable[[Callable], Callable]:
    """Return a decorator that attaches a check's rule in words (``'> 0'``) for the docs."""
    def mark(check: Callable) -> Callable:
        check.words = words
        return check
    return mark


@described_as('finite')
def finite(value) -> str | None:
    """Check: a finite number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if not math.isfinite(value):
        return f'must be finite, got {value!r}'
    return None


@described_as('> 0')
def positive(value) -> str | None:
    """Check: a finite number > 0."""
    return finite(value) or (None if value > 0 else f'must be > 0, got {value!r}')


@described_as('>= 0')
def non_negative(value) -> str | None:
    """Check: a finite number >= 0."""
    return finite(value) or (None if value >= 0 else f'must be >= 0, got {value!r}')


def one_of(choices) -> Callable[[Any], str | None]:
    """Return a check: a value among ``choices``."""
    choices = tuple(choices)

    def check(value) -> str | None:
        return None if value in choices else f'must be one of {", ".join(choices)}, got {value!r}'
    check.choices = choices
    check.words = 'one of ' + ', '.join(choices)
    return check


def in_range(value, low: float | None, high: float | None, unit: str = '') -> str | None:
    """Check: a number within ``[low, high]`` (either bound may be None); NaN fails."""
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


def zero_or_at_least(low: float, unit: str = '') -> Callable[[Any], str | None]:
    """Return a check: 0 (a switch: off, every step, ...) or a number >= ``low``."""
    def check(value) -> str | None:
        problem = finite(value)
        if problem or value == 0 or value >= low:
            return problem
        return f'must be 0 or >= {low:g}{" " + unit if unit else ""}, got {value!r}'
    check.words = f'0 or >= {low:g}{" " + unit if unit else ""}'
    return check


def each(check: Callable[[Any], str | None]) -> Callable[[Any], str | None]:
    """Return a check of a list: ``check`` on every element, the first problem named."""
    def check_all(values) -> str | None:
        for i, value in enumerate(values):
            problem = check(value)
            if problem:
                return f'[{i}] {problem}'
        return None
    check_all.words = f'each: {getattr(check, "words", "checked")}'
    return check_all


def means_no_limit(value) -> bool:
    """Tell whether a limit value says "no limit": 0, NaN or +inf (not a bool)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and (value == 0 or math.isnan(value) or value == math.inf))


def _is_inf(value) -> bool:
    return isinstance(value, float) and math.isinf(value)


_NAME_TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*\Z')


@described_as('a valid ROS name')
def ros_name(value) -> str | None:
    """Check: a valid ROS 2 topic or service name (rcl's rules; relative, absolute or ``~/``)."""
    if not isinstance(value, str) or not value:
        return f'must be a non-empty ROS name, got {value!r}'
    if value == '~':
        return None
    body = value[2:] if value.startswith('~/') else value[1:] if value[0] == '/' else value
    if '__' not in body and all(_NAME_TOKEN.match(token) for token in body.split('/')):
        return None
    return (f'must be a valid ROS name (letters, digits, _ and /, no token starting with a '
            f'digit, no "__", no trailing /), got {value!r}')


@described_as('a valid node name')
def node_name(value) -> str | None:
    """Check: a valid ROS 2 node name, optionally with its namespace (``/ns/node``)."""
    problem = ros_name(value)
    if problem or value.startswith('~'):
        return problem or f'must be a node name, not a private name, got {value!r}'
    return None


@described_as('a tf2 frame id (no leading /, no blanks)')
def frame_id(value) -> str | None:
    """Check: a usable tf2 frame id (printable, no whitespace, no leading ``/``, <= 255 chars)."""
    if not isinstance(value, str) or not value:
        return f'must be a non-empty frame id, got {value!r}'
    if value.startswith('/'):
        return f'must not start with "/" (tf2 frame ids are relative), got {value!r}'
    if len(value) > 255 or not value.isprintable() or any(c.isspace() for c in value):
        return f'must be printable, without spaces, at most 255 characters, got {value!r}'
    return None


@dataclass(frozen=True)
class Derived:
    """
    A default computed from other parameters.

    ``text`` is the rule as users read it (``+track_width / 2``); ``value(values) -> default``
    may raise ``KeyError``, ``TypeError`` or ``ValueError``, which leaves the default out (the
    other values' checks report the problem).
    """

    text: str
    value: Callable[[Mapping[str, Any]], Any]


@dataclass(frozen=True)
class ParamSpec:
    """
    One parameter: ROS name, default (its type is the parameter's type), meaning, check.

    Attributes
    ----------
    name : str
        ROS parameter name, dots for nesting (``icr.y_left``).
    default : bool, int, float, str or list of str
        Default value; for a ``required`` or ``derived`` parameter only an example of the type.
    check : callable, optional
        ``check(value) -> message or None``.
    read_only : bool
        Fixed after start (topics, modes).
    low, high : float, optional
        Inclusive range, published as the descriptor's range and checked after ``check``.
    required : bool
        No default: a node refuses to start without a value.
    derived : Derived, optional
        Default computed from the other parameters until the parameter is set explicitly.
    no_limit : bool
        ``0``, ``NaN`` and ``inf`` mean "no limit" and pass the range check; the range is
        published as ``additional_constraints`` text (rclpy refuses NaN and inf in a range).

    """

    name: str
    default: Any
    description: str
    unit: str = ''
    check: Callable[[Any], str | None] | None = None
    read_only: bool = False
    low: float | None = None
    high: float | None = None
    required: bool = False
    derived: Derived | None = None
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
    def has_default(self) -> bool:
        """Whether ``default`` is the value used when none is given."""
        return not self.required and self.derived is None

    @property
    def default_text(self) -> str:
        """Return the default as users read it: a value, ``required`` or the derivation."""
        if self.required:
            return 'required, no default'
        if self.derived is not None:
            return f'default {self.derived.text} unless set'
        return f'default {self.default!r}'

    @property
    def full_description(self) -> str:
        """Return the description with the unit (and the default rule), as shown to users."""
        text = f'{self.description} [{self.unit}]' if self.unit else self.description
        return text if self.has_default else f'{text} ({self.default_text})'


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


def resolve(specs, given: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """
    Apply the default rule of ``specs`` to the values ``given``.

    Given values are kept unchecked; missing ones take their (derived) default; names no spec
    declares are left out.

    Returns
    -------
    values : dict
        A value for every spec that has one.
    missing : list of str
        Required parameters without a value, in table order.

    """
    specs = tuple(specs)
    values: dict[str, Any] = {}
    missing = []
    for spec in specs:
        if spec.name in given:
            values[spec.name] = given[spec.name]
        elif spec.required:
            missing.append(spec.name)
        elif spec.has_default:
            values[spec.name] = spec.default
    for spec in specs:
        if spec.derived is not None and spec.name not in values:
            try:
                values[spec.name] = spec.derived.value(values)
            except (KeyError, TypeError, ValueError):
                pass
    return values, missing


def missing_message(missing) -> str:
    """Return the one line that names required parameters without a value."""
    names = ' and '.join(missing) if len(missing) <= 2 else (
        ', '.join(missing[:-1]) + f' and {missing[-1]}')
    verb = 'has' if len(missing) == 1 else 'have'
    return (f"{names} {verb} no default: give the vehicle's own values (-p NAME:=VALUE or a "
            'terrain file with --params-file), as diff_drive_controller needs wheel_separation '
            'and wheel_radius')


def unknown_parameters(given: Iterable[str], known: Iterable[ParamSpec | str], *,
                       only_close: bool = False, ignored: str = ' ignored',
                       what: str = 'unknown parameter') -> list[str]:
    """
    Return one message per name in ``given`` that ``known`` does not hold, with the closest name.

    With ``only_close``, only names close to a known one (a typo) are reported: for files that may
    also hold other programs' parameters. ``ignored`` and ``what`` are the words after and before
    the name: ``unknown parameter 'track_widht' ignored (did you mean 'track_width'?)``.
    """
    names = [k if isinstance(k, str) else k.name for k in known]
    known_set = set(names)
    messages = []
    for name in dict.fromkeys(given):
        if name in known_set:
            continue
        close = difflib.get_close_matches(name, names, n=1, cutoff=0.8 if only_close else 0.6)
        if only_close and not close:
            continue
        hint = f' (did you mean {close[0]!r}?)' if close else ''
        messages.append(f'{what} {name!r}{ignored}{hint}')
    return messages


def typos(given: Iterable[str], own: Iterable[ParamSpec | str],
          others: Iterable[str] = ()) -> list[str]:
    """
    Return one message per name in ``given`` that is a misspelling of a name in ``own``.

    A misspelling is held by neither ``own`` nor ``others`` and lies in a namespace of ``own``
    (``icr.y_lft``) or is close to one of its names (``track_widht``).
    """
    names = [k if isinstance(k, str) else k.name for k in own]
    known = set(names) | set(others)
    spaces = {name[:i + 1] for name in names for i, c in enumerate(name) if c == '.'}
    messages = []
    for name in dict.fromkeys(given):
        if name in known:
            continue
        space = max((s for s in spaces if name.startswith(s)), key=len, default='')
        candidates = [n for n in names if n.startswith(space)] if space else names
        close = difflib.get_close_matches(name, candidates, n=1, cutoff=0.6 if space else 0.8)
        if not close and not space:
            continue
        hint = (f' (did you mean {close[0]!r}?)' if close
                else f' ({space}* holds {", ".join(sorted(candidates))})')
        messages.append(f'unknown {name!r}{hint}')
    return messages
