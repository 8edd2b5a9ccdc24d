"""Decode the commands: setpoints per side, or cmd_vel through the ideal inverse."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from tracked_kinematics.offline.errors import BagError

from .columns import Columns, header_stamp, sort_unique
from .opening import topic_connections, topic_list
from .sources import CMD_VEL_TYPES, CommandSource


class Commands:
    """
    Setpoints per side, or cmd_vel through the ideal inverse -> track commands held until next.

    Which stream is chosen when the bag is opened (:class:`CommandSource` ``kind``); a bag
    without the stream asked for is an error, one without either of ``auto`` only when
    ``required``, else it simply has no commands.
    """

    def __init__(self, source: CommandSource, path: Path, ref_ns: int):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.required = source.required or source.kind != 'auto'
        self.kind = None      # 'setpoints' or 'cmd_vel' once chosen
        self.sides = {topic: Columns(2) for topic in source.setpoint_topics}
        self.twists = Columns(3)

    def _choose(self, reader: AnyReader) -> str | None:
        src = self.source
        if src.kind != 'auto':
            return None if src.kind == 'none' else src.kind
        present = {c.topic for c in reader.connections}
        if all(topic in present for topic in src.setpoint_topics):
            return 'setpoints'
        if src.cmd_vel_topic in present:
            return 'cmd_vel'
        if self.required:
            missing = next(t for t in src.setpoint_topics if t not in present)
            raise BagError(f'{self.path}: no topic {missing} for the setpoints (nor '
                           f'{src.cmd_vel_topic} for cmd_vel); topics present: '
                           f'{topic_list(reader)}')
        return None

    def connections(self, reader: AnyReader):
        """Return the bag connections of the command topics (checked)."""
        self.kind = self._choose(reader)
        if self.kind == 'setpoints':
            return [c for topic in self.source.setpoint_topics
                    for c in topic_connections(reader, self.path, topic,
                                               ('std_msgs/msg/Float64',), 'setpoints')]
        if self.kind == 'cmd_vel':
            if not math.isfinite(self.source.track_width) or self.source.track_width <= 0:
                raise BagError(f'{self.path}: the commands on {self.source.cmd_vel_topic} are '
                               'body twists; turning them into track speeds needs the track '
                               'width (--track-width or --params)')
            return topic_connections(reader, self.path, self.source.cmd_vel_topic,
                                     CMD_VEL_TYPES, 'commands')
        return []

    def add(self, conn, msg, receive_ns) -> None:
        if self.kind == 'setpoints':
            self.sides[conn.topic].append((float(receive_ns - self.ref_ns), float(msg.data)))
            return
        twist = msg
        t = float(receive_ns - self.ref_ns)
        if conn.msgtype == 'geometry_msgs/msg/TwistStamped':
            twist = msg.twist
            t = header_stamp(msg.header, receive_ns, self.ref_ns)
        self.twists.append((t, float(twist.linear.x), float(twist.angular.z)))

    def commands(self):
        """
        Return the times (ns) and the commanded track speeds (m/s), each held until the next.

        None when the bag has no commands (and none were required).
        """
        if self.kind == 'cmd_vel':
            data = self.body_twists()
            # The ideal inverse: V_l = v - w B / 2, V_r = v + w B / 2 (nominal track speeds).
            half = 0.5 * self.source.track_width
            return data[:, 0], np.column_stack([data[:, 1] - half * data[:, 2],
                                                data[:, 1] + half * data[:, 2]])
        if self.kind != 'setpoints':
            return None
        # Setpoints of both sides on the union of their stamps.
        topics = self.source.setpoint_topics
        data = [sort_unique(self.sides[topic].array) for topic in topics]
        for topic, side in zip(topics, data):
            if len(side) < 2:
                raise BagError(f'{self.path}: fewer than two messages on {topic}')
        command_t = np.union1d(data[0][:, 0], data[1][:, 0])
        command_t = command_t[command_t >= max(data[0][0, 0], data[1][0, 0])]
        held = [side[np.searchsorted(side[:, 0], command_t, side='right') - 1, 1]
                for side in data]
        return command_t, np.column_stack(held)

    def body_twists(self):
        """Return the rows ``(t (ns), v, w)`` of the cmd_vel messages (kind ``cmd_vel``)."""
        data = self.twists.array
        data = sort_unique(data[np.all(np.isfinite(data), axis=1)])
        if len(data) < 2:
            raise BagError(f'{self.path}: fewer than two finite messages on '
                           f'{self.source.cmd_vel_topic}')
        return data
