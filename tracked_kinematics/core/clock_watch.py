"""
The ROS clock watched from the steady clock: invalid, gone back, or stalled.

A /clock that stops freezes every ROS-time watchdog; a node that moves a robot stops on a fault.
See docs/nodes/calibration_drive.md, "Safety".
"""

from __future__ import annotations

import math


class ClockWatch:
    """Faults of a ROS clock against the steady clock (``stall_timeout`` in s)."""

    def __init__(self, stall_timeout: float):
        self.stall_timeout = float(stall_timeout)
        self.fault = ''
        self._latest: float | None = None     # latest ROS time, s
        self._advanced: float | None = None   # steady time when it last advanced, s

    def update(self, ros_s: float | None, steady_s: float) -> str:
        """
        Look at the clocks now; return '' when the ROS clock is healthy, else the reason.

        Invalid: None, not finite or not positive. A jump back is reported once, then the new time
        line followed. Stalled: not advanced for ``stall_timeout`` steady s, until it advances.
        """
        if ros_s is None or not math.isfinite(ros_s) or ros_s <= 0.0:
            self.fault = 'the ROS clock is invalid (no valid /clock?)'
        elif self._latest is None or ros_s > self._latest:
            self._latest, self._advanced = ros_s, steady_s
            self.fault = ''
        elif ros_s < self._latest:
            self.fault = f'the ROS clock went back {self._latest - ros_s:.3g} s'
            self._latest, self._advanced = ros_s, steady_s
        elif steady_s - self._advanced > self.stall_timeout:
            self.fault = (f'the ROS clock has not advanced for {steady_s - self._advanced:.3g} '
                          's of steady time')
        else:
            self.fault = ''
        return self.fault
