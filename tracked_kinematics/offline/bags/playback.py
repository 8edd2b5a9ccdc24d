"""
A rosbag2 bag as a stream of serialized messages in time order, for play_bag.

The messages stay CDR bytes, as the bag holds them and as rmw publishes them: nothing is
decoded here, any type the bag holds can be played. A ROS 1 bag is refused with the way to
convert it. Failures of the reader are one :class:`~tracked_kinematics.offline.errors.BagError`
line. Reference: docs/tools/play_bag.md.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
import math
from pathlib import Path

from tracked_kinematics.offline.errors import BagError

from .opening import guarded, open_bag, topic_list


@dataclass(frozen=True, slots=True)
class BagTopic:
    """One topic of a bag: its name, message type and number of messages in the window."""

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One message as recorded: topic, type, receive time (ns, bag clock), CDR bytes."""

    topic: str
    msgtype: str
    time_ns: int
    data: bytes


class BagPlayback:
    """
    The messages of a bag's topics between two times, as CDR bytes in time order.

    Parameters
    ----------
    path : path-like
        A rosbag2 directory (sqlite3 or mcap).
    topics : sequence of str, optional
        Topics to play (all when empty); each must be in the bag.
    start, duration : float
        The window, in s from the bag's first message: from ``start`` for ``duration``
        (``inf``: to the end).

    Raises
    ------
    BagError
        A missing, corrupt or ROS 1 bag, a topic not in it, an empty window.

    """

    def __init__(self, path, topics: Sequence[str] = (), start: float = 0.0,
                 duration: float = math.inf):
        self.path = Path(path)
        if not (math.isfinite(start) and start >= 0.0):
            raise BagError(f'--start must be a time >= 0 s from the bag start, got {start!r}')
        if not (duration > 0.0):
            raise BagError(f'--duration must be > 0 s, got {duration!r}')
        self._wanted = tuple(dict.fromkeys(topics))
        info = guarded(self.path, self._scan, start, duration)
        self.bag_start_ns, self.start_ns, self.end_ns, self.topics = info

    def _scan(self, reader, path: Path, start: float, duration: float):
        if not reader.is2:
            raise BagError(f'{path} is a ROS 1 bag: play_bag plays rosbag2 bags; convert it '
                           f'with `rosbags-convert --src {path} --dst {path.with_suffix("")}'
                           '_ros2`')
        present = {c.topic for c in reader.connections}
        missing = [topic for topic in self._wanted if topic not in present]
        if missing:
            raise BagError(f'{path}: no topic {", ".join(missing)}; topics present: '
                           f'{topic_list(reader)}')
        formats = {c.topic: c.ext.serialization_format for c in reader.connections}
        other = sorted(topic for topic, fmt in formats.items()
                       if fmt != 'cdr' and (not self._wanted or topic in self._wanted))
        if other:
            raise BagError(f'{path}: topics {", ".join(other)} are not CDR-serialized; '
                           'play_bag publishes the recorded CDR bytes')
        bag_start = reader.start_time
        start_ns = bag_start + int(round(start * 1e9))
        end_ns = math.inf if math.isinf(duration) else start_ns + int(round(duration * 1e9))
        if start_ns >= reader.end_time:
            raise BagError(f'{path}: --start {start:g} s is beyond the bag, which lasts '
                           f'{(reader.end_time - bag_start) * 1e-9:.3f} s')
        counts, types = {}, {}
        if start_ns == bag_start and math.isinf(end_ns):   # the whole bag: its index says
            for connection in self._connections(reader):
                if connection.msgcount:
                    counts[connection.topic] = counts.get(connection.topic, 0) \
                        + connection.msgcount
                    types.setdefault(connection.topic, connection.msgtype)
        else:
            for connection, _, _ in reader.messages(
                    connections=self._connections(reader), start=start_ns,
                    stop=None if math.isinf(end_ns) else end_ns):
                counts[connection.topic] = counts.get(connection.topic, 0) + 1
                types.setdefault(connection.topic, connection.msgtype)
        if not counts:
            raise BagError(f'{path}: no message of the chosen topics between {start:g} s and '
                           f'{start + duration:g} s from the bag start')
        topics = tuple(BagTopic(topic, types[topic], counts[topic]) for topic in sorted(counts))
        return bag_start, start_ns, end_ns, topics

    def _connections(self, reader):
        return [c for c in reader.connections
                if not self._wanted or c.topic in self._wanted]

    @property
    def message_count(self) -> int:
        """Return the number of messages in the window."""
        return sum(topic.count for topic in self.topics)

    def messages(self) -> Iterator[BagMessage]:
        """
        Yield the window's messages in time order (the bag is open while the loop runs).

        Raises :class:`BagError` when the bag cannot be read to the end (truncated, corrupt).
        """
        reader = open_bag(self.path)
        try:
            with reader:
                stop = None if math.isinf(self.end_ns) else self.end_ns
                for connection, time_ns, data in reader.messages(
                        connections=self._connections(reader), start=self.start_ns,
                        stop=stop):
                    yield BagMessage(connection.topic, connection.msgtype, time_ns,
                                     bytes(data))
        except BagError:
            raise
        except GeneratorExit:
            raise
        except Exception as err:  # noqa: BLE001 -- rosbags and sqlite raise many kinds
            detail = ' '.join(str(err).split()) or type(err).__name__
            raise BagError(f'cannot read bag {self.path}: {detail} (truncated or corrupt?)') \
                from None
