"""
The ROS clock watched from the steady clock: invalid, gone back, or stalled.

Under ``use_sim_time`` every ROS-time watchdog (a deadman's age, a sensor or command timeout)
trusts /clock, and a /clock that stops while the world runs freezes them all. A node that
moves a robot feeds :class:`ClockWatch` both clocks at each tick of a steady-clock timer and
treats a fault as a reason to stop. Reference: docs/nodes/calibration_drive.md (safety).
"""

from __future__ import annotations

import math


class ClockWatch:
    """
    Faults of a ROS clock seen against the steady clock.

    Parameters
    ----------
    stall_timeout : float
        Steady time, s, the ROS clock may stand still before it counts as stalled (> 0).

    Attributes
    ----------
    fault : str
        The reason of the latest :meth:`update` ('' when healthy).

    """

    def __init__(self, stall_timeout: float):
        self.stall_timeout = float(stall_timeout)
        self.fault = ''
        self._latest: float | None = None     # latest ROS time, s
        self._advanced: float | None = None   # steady time when it last advanced, s

    def update(self, ros_s: float | None, steady_s: float) -> str:
        """
        Look at the clocks now; return '' when the ROS clock is healthy, else the reason.

        A ROS time that is None (unreadable), not finite or not positive (no /clock yet) is
        invalid; one behind the latest is a jump back (reported at this update, then the new
        time line is followed: the caller latches what it must); one that has not advanced for
        more than ``stall_timeout`` of steady time is stalled, until it advances again.
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
