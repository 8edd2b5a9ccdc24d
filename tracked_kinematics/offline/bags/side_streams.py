"""Collect per-side encoder topics (track speeds, tick counters) for their decoder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tracked_kinematics.offline.errors import BagError

from .columns import Columns
from .sources import EncoderSource


class SideStream:
    """Per-side messages -> cumulative travel, by the mode's decoder (one value a message)."""

    def __init__(self, source: EncoderSource, path: Path, ref_ns: int):
        self.source = source
        self.decoder = source.decoder()
        self.path = path
        self.ref_ns = ref_ns
        self.columns = {source.left_topic: Columns(2), source.right_topic: Columns(2)}
        self.types = {}
        self.first = {}

    def feed(self, reader, conn, receive_ns, raw) -> None:
        """Take one serialised message."""
        topic = conn.topic
        self.types[topic] = conn.msgtype
        value = self.decoder.value(reader.deserialize(raw, conn.msgtype))
        # Counters relative to their first value, so that floats hold them exactly.
        first = self.first.setdefault(topic, value if self.decoder.counter else 0)
        self.columns[topic].append((float(receive_ns - self.ref_ns), float(value - first)))

    def _side(self, topic):
        data = self.columns[topic].array
        if len(data) < 2:
            raise BagError(f'{self.path}: fewer than two messages on {topic}')
        order = np.argsort(data[:, 0], kind='stable')
        t = data[order, 0]
        values = data[order, 1]
        keep = np.concatenate([[True], np.diff(t) > 0])
        t, values = t[keep], values[keep]
        return t, self.decoder.travel(t, values, self.types[topic])

    def travel(self):
        """Return common times (ns) and the cumulative nominal travel of each side (m)."""
        (t_l, c_l), (t_r, c_r) = (self._side(self.source.left_topic),
                                  self._side(self.source.right_topic))
        lo, hi = max(t_l[0], t_r[0]), min(t_l[-1], t_r[-1])
        t = np.union1d(t_l, t_r)
        t = t[(t >= lo) & (t <= hi)]
        return t, np.interp(t, t_l, c_l), np.interp(t, t_r, c_r)

    def velocities(self):
        """Return None: the speeds of per-side topics come from their travel."""
        return None
