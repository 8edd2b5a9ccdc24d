"""
Node health: its inputs on ``/diagnostics``, and a throttled warning naming a missing one.

A small equivalent of diagnostic_updater's ``Updater`` (not on PyPI): one status per node,
``"<node name>: health"``, once a second. See docs/diagnostics.md.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType

DIAGNOSTICS_TOPIC = '/diagnostics'  # absolute, as diagnostic_updater's
PERIOD = 1.0  # s between two updates: diagnostic_updater's default period
TASK = 'health'  # the status is named '<node name>: health'
SILENCE = 3.0  # s without a message before a needed input is reported
WARN_PERIOD = 5.0  # s between two warnings about the same input
RATE_UPDATES = 5  # the rate is counted over the last this many updates

OK, WARN, ERROR, STALE = (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR,
                          DiagnosticStatus.STALE)
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}


class MessageCount:
    """Messages of one input: how many, and the steady time of the last one (ns); O(1) per tick."""

    __slots__ = ('count', 'last_ns')

    def __init__(self):
        self.count = 0
        self.last_ns: int | None = None

    def tick(self) -> None:
        """Count one message, received now."""
        self.count += 1
        self.last_ns = time.monotonic_ns()

    def counted(self, callback: Callable) -> Callable:
        """Return ``callback`` that counts each message first."""
        def counting(msg):
            self.count += 1
            self.last_ns = time.monotonic_ns()
            callback(msg)
        return counting


class Report:
    """What a node adds: the worst ``level`` so far, its ``messages``, key/``values``."""

    def __init__(self):
        self.level = OK
        self.messages: list[str] = []
        self.values: list[KeyValue] = []

    def add(self, key: str, value) -> None:
        """Add a key/value (``value`` is turned into text)."""
        self.values.append(KeyValue(key=str(key), value=str(value)))

    def merge(self, level: bytes, message: str) -> None:
        """Merge a level and its message: the worst level wins, equal ones join messages."""
        if level > self.level:
            self.level, self.messages = level, []
        if level == self.level and message:
            self.messages.append(message)

    @property
    def message(self) -> str:
        """Return the messages of the worst level, joined ('OK' when there are none)."""
        return '; '.join(self.messages) or LEVEL_NAMES[self.level]


def _plural(count: int, word: str) -> str:
    return f'{count} {word}' + ('' if count == 1 else 's')


class _Input:
    """One watched input topic and what the last updates saw of it."""

    def __init__(self, topic: str, type_names, count: MessageCount, needed, silence: float,
                 now_ns: int):
        self.topic = topic
        self.type_names = type_names
        self.count = count
        self.needed = needed if callable(needed) else (lambda: needed)
        self.silence_ns = round(silence * 1e9)
        self.samples = deque([(now_ns, count.count)], maxlen=RATE_UPDATES + 1)
        self.needed_since: int | None = None
        self.warned_ns: int | None = None


class Health:
    """
    Publish a node's health on ``/diagnostics``; warn about missing inputs it needs.

    Parameters
    ----------
    hardware_id : str
        ``hardware_id`` of the status ('' as diagnostic_updater's default).
    timer : bool
        Update every :data:`PERIOD` s on a steady timer of its own; False when the node calls
        :meth:`update` from a timer it has anyway.

    """

    def __init__(self, node, hardware_id: str = '', timer: bool = True):
        self._node = node
        self.name = f'{node.get_name()}: {TASK}'
        self.hardware_id = hardware_id
        self._inputs: list[_Input] = []
        self._reporters: list[Callable[[Report], None]] = []
        self._publisher = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, 1)
        self._timer = node.create_timer(
            PERIOD, self.update, clock=Clock(clock_type=ClockType.STEADY_TIME)) \
            if timer else None

    def watch(self, *inputs, needed=True, silence: float = SILENCE) -> None:
        """
        Watch input topics (:class:`~tracked_kinematics.ros.input_topic.InputTopic`).

        ``needed`` (a bool, or a callable asked at every update): a missing input is then an ERROR
        and a warning; ``silence``: seconds without a message or publisher before it is missing.
        """
        for topic in inputs:
            self._inputs.append(_Input(topic.topic_name, (topic.type_name,), topic.count,
                                       needed, silence, time.monotonic_ns()))

    def watch_topic(self, topic: str, type_names: Iterable[str] | None = None, needed=False,
                    silence: float = SILENCE) -> MessageCount:
        """
        Watch a plain subscription's topic; return the count its callback must tick.

        Only publishers of ``type_names`` (``'std_msgs/msg/Float64'``) count; None: every one.
        """
        count = MessageCount()
        self._inputs.append(_Input(
            self._node.resolve_topic_name(topic),
            None if type_names is None else tuple(type_names), count, needed, silence,
            time.monotonic_ns()))
        return count

    def add(self, reporter: Callable[[Report], None]) -> None:
        """Call ``reporter(report)`` at every update: the node's own key/values and level."""
        self._reporters.append(reporter)

    def _publishers(self, watched: _Input) -> int:
        try:
            infos = self._node.get_publishers_info_by_topic(watched.topic)
        except Exception:  # noqa: BLE001 -- the graph is gone during shutdown
            return 0
        if watched.type_names is None:
            return len(infos)
        return sum(1 for info in infos if info.topic_type in watched.type_names)

    def report(self) -> Report:
        """Look at every input (warning about missing ones) and the node's own reporters."""
        report = Report()
        now_ns = time.monotonic_ns()
        for watched in self._inputs:
            self._report_input(report, watched, now_ns)
        for reporter in self._reporters:
            reporter(report)
        return report

    def _report_input(self, report: Report, watched: _Input, now_ns: int) -> None:
        count = watched.count
        total, last_ns = count.count, count.last_ns
        first_ns, first_total = watched.samples[0]
        watched.samples.append((now_ns, total))
        rate = (total - first_total) * 1e9 / (now_ns - first_ns) if now_ns > first_ns else 0.0
        publishers = self._publishers(watched)
        topic = watched.topic
        needed = bool(watched.needed())
        report.add(f'{topic} publishers', publishers)
        report.add(f'{topic} rate (Hz)', f'{rate:.3g}')
        report.add(f'{topic} age (s)',
                   'never' if last_ns is None else f'{(now_ns - last_ns) * 1e-9:.3g}')
        report.add(f'{topic} messages', total)
        report.add(f'{topic} needed', 'yes' if needed else 'no')
        if not needed:
            watched.needed_since = None
            return
        if watched.needed_since is None:
            watched.needed_since = now_ns
        since = max(watched.needed_since, last_ns or 0)
        if now_ns - since < watched.silence_ns:
            if watched.warned_ns is not None:
                watched.warned_ns = None
                self._node.get_logger().info(f'{topic}: receiving again')
            return
        text = (f'{topic}: no publisher' if publishers == 0 else
                f'{topic}: no message for {(now_ns - since) * 1e-9:.0f} s '
                f'({_plural(publishers, "publisher")})')
        report.merge(ERROR, text)
        if watched.warned_ns is None or now_ns - watched.warned_ns >= WARN_PERIOD * 1e9:
            watched.warned_ns = now_ns
            self._node.get_logger().warning(
                f'{text}: this node needs it (is its publisher running, is the topic '
                'remapped right?)')

    def status(self, report: Report) -> DiagnosticStatus:
        """Return the node's DiagnosticStatus for a report."""
        return DiagnosticStatus(level=report.level, name=self.name, message=report.message,
                                hardware_id=self.hardware_id, values=report.values)

    def update(self) -> None:
        """Report, then publish the status on ``/diagnostics``."""
        status = self.status(self.report())
        array = DiagnosticArray(status=[status])
        array.header.stamp = self._node.get_clock().now().to_msg()
        try:
            self._publisher.publish(array)
        except Exception:  # noqa: BLE001 -- shutting down: the publisher is gone
            pass
