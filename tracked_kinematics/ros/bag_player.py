"""
play_bag's publishing side: recorded messages onto live topics, at their pace.

Each message is published as the CDR bytes the bag holds (rmw's own serialized form, so any
type whose Python class rclpy can import plays, untouched); its first message is decoded once
to check that the installed type matches the recorded one. Paced on the steady clock from the
messages' receive times; ``/clock`` (if asked) carries the bag's time. The bag side is
:mod:`tracked_kinematics.offline.bags.playback`. Reference: docs/tools/play_bag.md.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
import importlib
import time

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock

#: Topics whose subscribers expect the messages published before they started (latched).
LATCHED = ('/tf_static', '/robot_description')
#: Longest wait between two looks at the stop request, s.
STOP_POLL = 0.05


def message_class(msgtype: str):
    """Return the Python class of ``pkg/msg/Name`` (or ``pkg/Name``), or None if not installed."""
    parts = msgtype.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts):
        return None
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError):
        return None


def _stamp(msg, time_ns: int) -> None:
    msg.sec, msg.nanosec = divmod(int(time_ns), 1_000_000_000)


@dataclass
class PlayStats:
    """What a run of :func:`play` published."""

    messages: int = 0
    loops: int = 0
    stopped: bool = False


class BagPlayer:
    """
    Publishers of a bag's topics (and ``/clock``) on one node.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that owns the publishers.
    topics : iterable of (str, str)
        Topic name and message type (``sensor_msgs/msg/Imu``) of each topic to play.
    clock : bool
        Publish the bag's time on ``/clock`` (the nodes then run with ``use_sim_time``).
    warn : callable
        ``warn(text)`` for each topic left out (type not installed, or not the recorded one).

    """

    def __init__(self, node, topics: Iterable[tuple[str, str]], clock: bool,
                 warn: Callable[[str], None]):
        self._node, self._warn = node, warn
        self._publishers = {}
        self._checked = set()
        self.skipped: dict[str, str] = {}
        for name, msgtype in topics:
            cls = message_class(msgtype)
            if cls is None:
                self._skip(name, f'its type {msgtype} is not installed (no Python module)')
                continue
            qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
            if name in LATCHED:
                qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
            self._publishers[name] = (node.create_publisher(cls, name, qos), cls, msgtype)
        self._clock = node.create_publisher(Clock, '/clock', QoSProfile(
            depth=10, reliability=ReliabilityPolicy.RELIABLE)) if clock else None

    @property
    def topics(self) -> list[str]:
        """Return the topics that are played (the others are in :attr:`skipped`)."""
        return list(self._publishers)

    def published_as(self, topic: str) -> str:
        """Return the name ``topic`` is published on (after remapping), '' when not played."""
        entry = self._publishers.get(topic)
        return '' if entry is None else entry[0].topic_name

    def subscribers(self, topic: str) -> int:
        """Return how many subscriptions the publisher of ``topic`` has matched."""
        return self._publishers[topic][0].get_subscription_count()

    def _skip(self, topic: str, why: str) -> None:
        self.skipped[topic] = why
        self._warn(f'{topic} is not played: {why}')

    def publish(self, topic: str, data: bytes) -> bool:
        """Publish one recorded message; return False when its topic is not played."""
        entry = self._publishers.get(topic)
        if entry is None:
            return False
        publisher, cls, msgtype = entry
        if topic not in self._checked:
            self._checked.add(topic)
            try:
                deserialize_message(data, cls)
            except Exception as err:  # noqa: BLE001 -- rclpy raises several kinds
                del self._publishers[topic]
                self._node.destroy_publisher(publisher)
                self._skip(topic, f'its recorded {msgtype} does not decode as the installed '
                           f'one ({" ".join(str(err).split()) or type(err).__name__})')
                return False
        publisher.publish(data)
        return True

    def publish_clock(self, time_ns: int) -> None:
        """Publish ``time_ns`` (bag time) on /clock, if asked for."""
        if self._clock is not None:
            msg = Clock()
            _stamp(msg.clock, time_ns)
            self._clock.publish(msg)


def play(player: BagPlayer, messages: Callable[[], Iterable], start_ns: int, rate: float,
         stop: Callable[[], bool], loop: bool = False, delay: float = 0.0,
         clock_period: float = 0.01, now: Callable[[], float] = time.monotonic) -> PlayStats:
    """
    Publish ``messages()`` (objects with ``topic``, ``time_ns``, ``data``) at their pace.

    Parameters
    ----------
    player : BagPlayer
        Where the messages go.
    messages : callable
        Returns an iterable of the messages in time order (called once per pass).
    start_ns : int
        Bag time of the window's start: it is played ``delay`` s of steady time after the call.
    rate : float
        Bag seconds per steady second (> 0; 2: twice as fast).
    stop : callable
        Polled at least every :data:`STOP_POLL` s; True ends the play at once.
    loop : bool
        Start over at the end (``messages()`` is called again), until stopped.
    delay : float
        Steady s before the first message (for discovery).
    clock_period : float
        Steady s between two /clock messages while no message is due.
    now : callable
        The steady clock, s.

    """
    stats = PlayStats()
    origin = now() + max(0.0, delay)
    while True:
        last_ns = start_ns
        for msg in messages():
            if not _wait_until(player, origin, start_ns, msg.time_ns, rate, stop,
                               clock_period, now):
                stats.stopped = True
                return stats
            player.publish_clock(msg.time_ns)
            if player.publish(msg.topic, msg.data):
                stats.messages += 1
            last_ns = msg.time_ns
        stats.loops += 1
        if not loop or stop():
            stats.stopped = stop()
            return stats
        # The next pass starts where this one's last message was, on the steady clock.
        origin += (last_ns - start_ns) * 1e-9 / rate


def _wait_until(player, origin, start_ns, time_ns, rate, stop, clock_period, now) -> bool:
    """Wait for bag time ``time_ns``; /clock runs meanwhile. Return False when stopped."""
    due = origin + (time_ns - start_ns) * 1e-9 / rate
    while True:
        if stop():
            return False
        left = due - now()
        if left <= 0.0:
            return True
        time.sleep(min(left, clock_period, STOP_POLL))
        elapsed = now() - origin
        if elapsed > 0.0:
            player.publish_clock(min(time_ns, start_ns + int(elapsed * rate * 1e9)))
