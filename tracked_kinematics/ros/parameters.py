"""
Declare a node's parameters from a table of :class:`~tracked_kinematics.params.ParamSpec`.

One table gives ``ros2 param describe`` its text, checks the values at start and answers
runtime changes (refused with the reason); ``required`` and ``derived`` defaults follow
:func:`tracked_kinematics.params.resolve`. See docs/parameters.md.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
import contextlib
import math
from typing import Any

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.node import Node
from rclpy.parameter import Parameter
from tracked_kinematics.params import missing_message, ParamSpec, typos
from tracked_kinematics.params.node_tables import NODE_PARAMS
from tracked_kinematics.params.tables import is_terrain_file_record

# Parameters every rclpy node declares itself.
NODE_PARAMETERS = ('use_sim_time', 'start_type_description_service')


def package_parameters() -> dict[str, tuple[ParamSpec, ...]]:
    """Return the parameters every node of this package declares, by node name."""
    return dict(NODE_PARAMS)


def package_parameter_names() -> frozenset[str]:
    """Return every name a node of this package declares, and those every rclpy node does."""
    return frozenset(spec.name for specs in package_parameters().values() for spec in specs) \
        | frozenset(NODE_PARAMETERS)


class ParameterError(ValueError):
    """Invalid parameters at start: the node cannot run with them."""


def _coerce(spec: ParamSpec, value):
    """Bring a parameter value to the spec's type (ints are accepted for doubles)."""
    if isinstance(spec.default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(spec.default, list):
        return list(value)
    return value


def _type_matches(spec: ParamSpec, value) -> bool:
    default = spec.default
    if isinstance(default, bool):
        return isinstance(value, bool)
    if isinstance(default, float):
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if isinstance(default, int):
        return isinstance(value, int) and not isinstance(value, bool)
    if isinstance(default, str):
        return isinstance(value, str)
    if isinstance(default, list):
        return isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value)
    return True


def describe(spec: ParamSpec, ranges: bool = True) -> ParameterDescriptor:
    """
    Build the descriptor of a parameter: its text, read-only flag and range.

    A limit (``spec.no_limit``) states its range in ``additional_constraints`` (NaN and inf lie
    outside any range); ``ranges=False`` leaves the range out.
    """
    descriptor = ParameterDescriptor(
        description=spec.full_description, read_only=spec.read_only,
        dynamic_typing=isinstance(spec.default, float))
    if not ranges:
        return descriptor
    if spec.has_range and spec.no_limit:
        # rclpy would refuse the NaN and inf that mean "no limit" against a range.
        low = '-inf' if spec.low is None else f'{spec.low:g}'
        high = 'inf' if spec.high is None else f'{spec.high:g}'
        unit = f' {spec.unit}' if spec.unit else ''
        descriptor.additional_constraints = (
            f'[{low}, {high}]{unit}; also 0, NaN (.NAN) or .inf (see the description)')
    elif spec.has_range and isinstance(spec.default, float):
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=-math.inf if spec.low is None else float(spec.low),
            to_value=math.inf if spec.high is None else float(spec.high), step=0.0)]
    elif (spec.has_range and isinstance(spec.default, int)
          and not isinstance(spec.default, bool)):
        descriptor.integer_range = [IntegerRange(
            from_value=-2**63 if spec.low is None else int(math.ceil(spec.low)),
            to_value=2**63 - 1 if spec.high is None else int(math.floor(spec.high)), step=0)]
    return descriptor


class ParameterTable:
    """
    The parameters of one node, declared from specs and kept valid.

    Parameters
    ----------
    validate : callable, optional
        ``validate(values)`` raising ``ValueError`` for an invalid combination (the ICR model as
        a whole); called at start and before every change.
    on_change : callable, optional
        ``on_change(values)`` called after a valid runtime change was accepted.

    Raises
    ------
    ParameterError
        When the values given at start are invalid; the message lists every problem.

    """

    def __init__(self, node, specs: Iterable[ParamSpec],
                 validate: Callable[[Mapping[str, Any]], None] | None = None,
                 on_change: Callable[[Mapping[str, Any]], None] | None = None):
        self._node = node
        self.specs = {spec.name: spec for spec in specs}
        self._validate = validate
        self._on_change = on_change
        values = {}
        problems = []
        missing = []
        # Derived parameters given at start or set at runtime by a user: they no longer
        # follow the parameters they are derived from.
        self.explicit: set[str] = set()
        for spec in self.specs.values():
            descriptor = describe(spec)
            try:
                value = node.declare_parameter(spec.name, self._declared_default(spec, descriptor),
                                               descriptor).value
            except Exception as err:  # noqa: BLE001 -- rclpy raises several types here
                problems.append(self._declare_problem(spec, err))
                continue
            if value is None and isinstance(spec.default, list):
                value = []
            if value is None:
                if spec.required:
                    missing.append(spec.name)
                continue  # derived: computed below
            if spec.derived is not None:
                self.explicit.add(spec.name)
            problem = self._check(spec, value)
            if problem:
                problems.append(problem)
            else:
                values[spec.name] = _coerce(spec, value)
        if missing:
            problems.insert(0, missing_message(missing))
        problems += self._typos()
        derived: dict[str, Any] = {}
        if not problems:
            derived = self._derive(values, set(values))
            for name, value in derived.items():
                problem = self._check(self.specs[name], value)
                if problem:
                    problems.append(f'{problem} (derived: {self.specs[name].default_text})')
            values.update(derived)
        if not problems and validate is not None:
            try:
                validate(values)
            except ValueError as err:
                problems.append(str(err))
        if problems:
            raise ParameterError('invalid parameters: ' + '; '.join(problems))
        if derived:
            node.set_parameters([Parameter(name, value=value) for name, value in derived.items()])
        self.values: dict[str, Any] = values
        self._pending: dict[str, Any] | None = None
        self._derived_now: set[str] = set()
        node.add_pre_set_parameters_callback(self._pre_set)
        node.add_on_set_parameters_callback(self._on_set)
        node.add_post_set_parameters_callback(self._post_set)

    def _typos(self) -> list[str]:
        """Name the given parameters that misspell the node's own: each refuses the start."""
        given = [name for name in getattr(self._node, '_parameter_overrides', {})
                 if not is_terrain_file_record(name)]
        return typos(given, [*self.specs, *NODE_PARAMETERS], package_parameter_names())

    def _declare_problem(self, spec: ParamSpec, err: Exception) -> str:
        """Say why a value given at start was refused, in the table's words if possible."""
        # rclpy refuses a value outside the descriptor's range before the table sees it;
        # its message does not say what was given, the table's check does.
        override = getattr(self._node, '_parameter_overrides', {}).get(spec.name)
        if override is not None and override.value is not None:
            problem = self._check(spec, override.value)
            if problem:
                return problem
        return f'{spec.name}: {" ".join(str(err).split())}'

    @staticmethod
    def _declared_default(spec: ParamSpec, descriptor: ParameterDescriptor):
        """Return the default to declare: the spec's, or none (only an override gives one)."""
        if spec.has_default:
            default = spec.default
            return Parameter.Type.STRING_ARRAY if isinstance(default, list) and not default \
                else default
        if descriptor.dynamic_typing:
            return None
        return Parameter.Type.from_parameter_value(spec.default)

    def _derive(self, values: Mapping[str, Any], given: set[str]) -> dict[str, Any]:
        """Return the values of derived specs not in ``given`` nor explicit, from ``values``."""
        out = {}
        for spec in self.specs.values():
            if spec.derived is None or spec.name in given or spec.name in self.explicit:
                continue
            try:
                out[spec.name] = _coerce(spec, spec.derived.value(values))
            except (KeyError, TypeError, ValueError):
                continue
        return out

    @staticmethod
    def _check(spec: ParamSpec, value) -> str | None:
        if not _type_matches(spec, value):
            return f'{spec.name} must be of the type of {spec.default!r}, got {value!r}'
        return spec.validate(_coerce(spec, value))

    def __getitem__(self, name: str):
        """Return the current value of a parameter."""
        return self.values[name]

    def _proposed(self, params) -> tuple[dict[str, Any], list[str]]:
        proposed = dict(self.values)
        problems = []
        for param in params:
            spec = self.specs.get(param.name)
            if spec is None:
                continue
            problem = self._check(spec, param.value)
            if problem:
                problems.append(problem)
            else:
                proposed[param.name] = _coerce(spec, param.value)
        return proposed, problems

    def _pre_set(self, params):
        """Add the derived parameters that follow a change of those they derive from."""
        proposed, problems = self._proposed(params)
        self._derived_now = set()
        if problems:
            return params
        derived = self._derive(proposed, {param.name for param in params})
        changed = [Parameter(name, value=value) for name, value in derived.items()
                   if value != self.values.get(name)]
        self._derived_now = {param.name for param in changed}
        return list(params) + changed

    def _on_set(self, params) -> SetParametersResult:
        proposed, problems = self._proposed(params)
        if not problems and self._validate is not None:
            try:
                self._validate(proposed)
            except ValueError as err:
                problems.append(str(err))
        if problems:
            self._pending = None
            reason = '; '.join(problems)
            self._node.get_logger().warn(f'refused parameter change: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        self._pending = proposed
        return SetParametersResult(successful=True)

    def _post_set(self, params) -> None:
        if self._pending is None:
            return
        self.values, self._pending = self._pending, None
        self.explicit |= {param.name for param in params
                          if param.name in self.specs and self.specs[param.name].derived
                          and param.name not in self._derived_now}
        self._derived_now = set()
        if self._on_change is not None:
            self._on_change(self.values)


@contextlib.contextmanager
def destroyed_on_failure(node: Node):
    """
    Destroy ``node`` when the block that builds it raises, before its context can be shut down.

    Left to the garbage collector, it could be destroyed after the context, where rcl can hang.
    """
    try:
        yield node
    except BaseException:
        Node.destroy_node(node)
        raise


def _guard_clock(node: 'TableNode') -> None:
    """
    Refuse /clock messages rclpy cannot take (``sec < 0``) instead of raising in spin.

    rclpy's TimeSource offers no hook, so its callback is wrapped; a refused message sets
    :meth:`TableNode.clock_fault` until a valid one arrives and counts in
    :meth:`TableNode.clock_refusals`.
    """
    source = node._time_source
    original = source.clock_callback

    def guarded(msg) -> None:
        if msg.clock.sec < 0:
            node._clock_invalid = (f'/clock message refused: negative time {msg.clock.sec} s '
                                   f'{msg.clock.nanosec} ns')
            node._clock_refused = (node._clock_refused[0] + 1, node._clock_invalid)
            node.get_logger().error(node._clock_invalid, throttle_duration_sec=5.0)
            return
        node._clock_invalid = ''
        original(msg)

    source.clock_callback = guarded
    if source._clock_sub is not None:
        source._clock_sub.callback = guarded


class TableNode(Node):
    """
    A node whose parameters are one table: declared and checked, then the node is built.

    A subclass builds itself in :meth:`_start` and takes valid runtime changes in :meth:`_apply`;
    a failed start destroys the half-built node. ``specs`` and ``validate`` as in
    :class:`ParameterTable`; ``**kwargs`` go to :class:`rclpy.node.Node`. Raises
    ``ParameterError`` when the parameters given at start are invalid.
    """

    def __init__(self, name: str, specs: Iterable[ParamSpec],
                 validate: Callable[[Mapping[str, Any]], None] | None = None, **kwargs):
        super().__init__(name, **kwargs)
        self._clock_invalid = ''
        self._clock_refused = (0, '')
        _guard_clock(self)
        with destroyed_on_failure(self):
            try:
                self.params = ParameterTable(self, specs, validate=validate,
                                             on_change=self._apply)
                self._start(self.params.values)
            except BaseException:
                self._abandon()
                raise

    def clock_fault(self) -> str:
        """Return why the latest /clock message was refused ('' when it was valid)."""
        return self._clock_invalid

    def clock_refusals(self) -> tuple[int, str]:
        """Return how many /clock messages were refused since the start, and why the last was."""
        return self._clock_refused

    def ros_time(self) -> float | None:
        """Return the node's ROS time in s, or None while /clock is invalid."""
        if self._clock_invalid:
            return None
        return self.get_clock().now().nanoseconds * 1e-9

    def _start(self, values: Mapping[str, Any]) -> None:
        """Build the node from the checked start values (publishers, subscriptions, ...)."""
        raise NotImplementedError

    def _apply(self, values: Mapping[str, Any]) -> None:
        """Take the values of a valid runtime parameter change into use."""

    def _abandon(self) -> None:
        """Stop what a failed :meth:`_start` began that destroying the node does not (threads)."""
