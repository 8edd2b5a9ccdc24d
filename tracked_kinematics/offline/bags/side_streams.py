"""Decode per-side encoder topics: std_msgs/Float64 track speeds or Int32/Int64 tick counters."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from tracked_kinematics.core.encoders import (
    counter_increments, travel_from_ticks, travel_from_velocities)
from tracked_kinematics.offline.errors import BagError

from .columns import _Columns
from .sources import EncoderSource, TICK_BITS


class _SideStream:
    """Per-side Float64 speeds or Int32/Int64 tick counters -> cumulative travel."""

    def __init__(self, source: EncoderSource, path: Path, ref_ns: int):
        self.source = source
        self.path = path
        self.ref_ns = ref_ns
        self.columns = {source.left_topic: _Columns(2), source.right_topic: _Columns(2)}
        self.bits = {}
        self.first = {}

    def add(self, topic, msgtype, msg, receive_ns) -> None:
        self.bits[topic] = TICK_BITS.get(msgtype, 0)
        # Counters relative to their first value, so that floats hold them exactly.
        first = self.first.setdefault(topic, msg.data if self.bits[topic] else 0)
        self.columns[topic].append((float(receive_ns - self.ref_ns), float(msg.data - first)))

    def _side(self, topic):
        data = self.columns[topic].array
        if len(data) < 2:
            raise BagError(f'{self.path}: fewer than two messages on {topic}')
        order = np.argsort(data[:, 0], kind='stable')
        t = data[order, 0]
        values = data[order, 1]
        keep = np.concatenate([[True], np.diff(t) > 0])
        t, values = t[keep], values[keep]
        if self.source.mode == 'track_speeds':
            travel = travel_from_velocities(values, t * 1e-9)
        else:
            travel = travel_from_ticks(counter_increments(values.astype(np.int64),
                                                          self.bits[topic]),
                                       self.source.ticks_per_revolution,
                                       self.source.sprocket_radius)
        return t, np.concatenate([[0.0], np.cumsum(travel)])

    def travel(self):
        """Return common times (ns) and the cumulative nominal travel of each side (m)."""
        (t_l, c_l), (t_r, c_r) = (self._side(self.source.left_topic),
                                  self._side(self.source.right_topic))
        lo, hi = max(t_l[0], t_r[0]), min(t_l[-1], t_r[-1])
        t = np.union1d(t_l, t_r)
        t = t[(t >= lo) & (t <= hi)]
        return t, np.interp(t, t_l, c_l), np.interp(t, t_r, c_r)
