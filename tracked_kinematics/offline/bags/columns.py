"""
Growing numeric columns and the small conversions every message decoder of a bag uses.

Each message is reduced to a few numbers appended to a :class:`Columns`, so that memory grows
with the number of samples (tens of bytes each), never with the size of the bag.
"""

from __future__ import annotations

import numpy as np
from tracked_kinematics.core.integration import stamp_ns, yaw_from_quaternion


class Columns:
    """Growing float64 columns, doubled in place: appends are amortised O(1)."""

    def __init__(self, width: int, capacity: int = 1024):
        self._data = np.empty((capacity, width))
        self.n = 0

    def append(self, row) -> None:
        if self.n == len(self._data):
            self._data = np.concatenate([self._data, np.empty_like(self._data)])
        self._data[self.n] = row
        self.n += 1

    def extend(self, rows) -> None:
        while self.n + len(rows) > len(self._data):
            self._data = np.concatenate([self._data, np.empty_like(self._data)])
        self._data[self.n:self.n + len(rows)] = rows
        self.n += len(rows)

    @property
    def array(self) -> np.ndarray:
        return self._data[:self.n]


def header_stamp(header, receive_ns: int, ref_ns: int) -> float:
    """Header stamp in ns after ``ref_ns`` (receive time when the stamp was never filled)."""
    ns = stamp_ns(header.stamp.sec, header.stamp.nanosec)
    return float((ns if ns > 0 else receive_ns) - ref_ns)


def quaternion_yaw(q) -> float:
    """Return the yaw, rad, of a quaternion message."""
    return yaw_from_quaternion(q.x, q.y, q.z, q.w)


def sort_unique(columns: np.ndarray) -> np.ndarray:
    """Rows sorted by their first column (time), the first of equal times kept."""
    if len(columns) == 0:
        return columns
    columns = columns[np.argsort(columns[:, 0], kind='stable')]
    keep = np.concatenate([[True], np.diff(columns[:, 0]) > 0])
    return columns[keep]


def strip_frame(frame: str) -> str:
    """Return a frame id without its leading slashes."""
    return frame.lstrip('/')
