"""
Parameter specifications: :class:`ParamSpec` and the checks its tables use.

Each :class:`ParamSpec` carries a parameter's ROS name, default, unit, description and check,
in the spirit of generate_parameter_library's YAML in ros2_controllers. Nodes declare their
parameters from the tables of :mod:`.tables` (with descriptors, so ``ros2 param describe``
explains them) and validate with the same checks at start and in their set-parameters
callback; the command lines validate terrain files with them. Every check carries its rule
in words (``check.words``, set by :func:`described_as`) for the generated parameter reference.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
import math
from typing import Any


def described_as(words: str) -> Callable[[Callable], Callable]:
    """
    Return a decorator that attaches a check's rule in words, as the parameter docs show it.

    Parameters
    ----------
    words : str
        The rule, short: ``'> 0'``, ``'>= 0, 0 = no limit'``.

    """
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

    """

    name: str
    default: Any
    description: str
    unit: str = ''
    check: Callable[[Any], str | None] | None = None
    read_only: bool = False

    def validate(self, value) -> str | None:
        """Return an error message naming the parameter, or None when ``value`` is valid."""
        if self.check is None:
            return None
        problem = self.check(value)
        return None if problem is None else f'{self.name} {problem}'

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
