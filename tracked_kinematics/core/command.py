"""
From a body twist command to track speed setpoints, with limits that keep the path.

The command path of a tracked vehicle: the commanded twist ``(v_x, w)`` goes through the
inverse ICR kinematics (Martinez et al. 2005, eqs. 10-11, in the ROS frame, see
:func:`~tracked_kinematics.core.kinematics.inverse`) to true track speeds, which are divided
by the encoder scale corrections (eqs. 20-21) to give the *nominal* speeds a track speed
controller that trusts its encoders must be asked for.

Limits are applied so that the path the vehicle follows stays the commanded one:

- velocity limits (on the twist, like diff_drive_controller's ``linear.x.max_velocity`` and
  ``angular.z.max_velocity``, and on each track's setpoint) scale ``v_x`` and ``w`` by one
  common factor, which keeps the curvature ``w / v_x`` (diff_drive_controller clamps the
  two independently, which turns a commanded arc into a tighter one);
- acceleration limits (on the twist and on each track's setpoint) move the setpoints along
  the straight segment from the last setpoints to the target, by the largest fraction of it
  that no limit forbids. Both tracks reach the target together, and a ramp from or to rest
  keeps the commanded curvature all the way.

Track limits apply to the nominal setpoints, the numbers the motor controllers receive.
Unlimited is ``math.inf``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
import math

import numpy as np

from ._checks import require_numbers
from .kinematics import forward, IcrParams, inverse, nominal_speeds


@dataclass(frozen=True, slots=True)
class CommandLimits:
    """
    Velocity and acceleration limits of the command path; ``math.inf`` is no limit.

    Attributes
    ----------
    max_track_speed : float
        Largest nominal track speed setpoint, m/s.
    max_track_accel : float
        Largest rate of change of a nominal track speed setpoint, m/s^2.
    max_linear_velocity, max_linear_acceleration : float
        Largest ``|v_x|`` (m/s) and its rate of change (m/s^2).
    max_angular_velocity, max_angular_acceleration : float
        Largest ``|w|`` (rad/s) and its rate of change (rad/s^2).

    Raises
    ------
    ValueError
        On a limit that is not a number > 0 (``inf`` allowed); the message names it.

    """

    max_track_speed: float = math.inf
    max_track_accel: float = math.inf
    max_linear_velocity: float = math.inf
    max_linear_acceleration: float = math.inf
    max_angular_velocity: float = math.inf
    max_angular_acceleration: float = math.inf

    def __post_init__(self):
        names = tuple(f.name for f in fields(self))
        require_numbers(self, positive=names, unbounded=names)


def _factor(magnitude, limit):
    """Largest factor <= 1 that brings ``magnitude`` (>= 0) within ``limit`` (> 0)."""
    magnitude = np.asarray(magnitude, dtype=float)
    return np.divide(limit, magnitude, out=np.ones_like(magnitude), where=magnitude > limit)


def limit_twist(v_x, w, max_linear=math.inf, max_angular=math.inf):
    """
    Scale a twist command into the twist velocity limits, keeping its curvature.

    Parameters
    ----------
    v_x, w : array_like
        Commanded forward velocity (m/s) and yaw rate (rad/s), finite.
    max_linear, max_angular : float
        Limits on ``|v_x|`` (m/s) and ``|w|`` (rad/s), > 0; ``inf`` for none.

    Returns
    -------
    v_x, w : ndarray
        The command times one factor in (0, 1], the largest that meets both limits.

    """
    v_x = np.asarray(v_x, dtype=float)
    w = np.asarray(w, dtype=float)
    factor = np.minimum(_factor(np.abs(v_x), max_linear), _factor(np.abs(w), max_angular))
    return v_x * factor, w * factor


def track_setpoints(v_x, w, icr: IcrParams):
    """
    Nominal track speed setpoints that make the vehicle move with a commanded twist.

    Inverse kinematics, Martinez et al. (2005) eqs. (10)-(11) in the ROS frame, then the
    encoder corrections of eqs. (20)-(21) undone: ``nominal = true / scale``.

    Parameters
    ----------
    v_x, w : array_like
        Commanded forward velocity (m/s) and yaw rate (rad/s).
    icr : IcrParams
        Kinematic model of the vehicle on its terrain.

    Returns
    -------
    left, right : ndarray
        Nominal track speeds, m/s.

    """
    return nominal_speeds(*inverse(v_x, w, icr), icr)


def saturate_tracks(left, right, max_speed):
    """
    Scale both track setpoints by one factor so that neither exceeds ``max_speed``.

    Scaling both sides together scales the twist they produce, so the curvature of the
    path is kept (clipping each side alone would change it).

    Parameters
    ----------
    left, right : array_like
        Track speed setpoints, m/s.
    max_speed : float
        Largest allowed ``|setpoint|``, m/s, > 0; ``inf`` for none.

    Returns
    -------
    left, right : ndarray

    """
    left = np.asarray(left, dtype=float)
    right = np.asarray(right, dtype=float)
    factor = _factor(np.maximum(np.abs(left), np.abs(right)), max_speed)
    return left * factor, right * factor


class CommandLimiter:
    """
    Twist commands in, limited nominal track setpoints out, one update per publish period.

    The caller gives each command with its arrival time (:meth:`command`) and asks for the
    setpoints at every publish time (:meth:`update`). A command older than ``timeout`` is
    replaced by a stop, reached at the acceleration limits (at once when there are none).

    Parameters
    ----------
    icr : IcrParams
        Kinematic model of the vehicle on its terrain.
    limits : CommandLimits, optional
        Velocity and acceleration limits; none by default.
    timeout : float, optional
        Age (s) beyond which a command is stale, > 0.

    Attributes
    ----------
    icr, limits, timeout
        May be replaced between updates (runtime parameter changes); the ramp continues
        from the last setpoints.

    Notes
    -----
    The target setpoints of a command are computed once, when the command (or the model,
    or a limit) changes; an update in between costs a few microseconds.

    """

    def __init__(self, icr: IcrParams, limits: CommandLimits | None = None,
                 timeout: float = 0.5):
        self._icr = icr
        self._limits = CommandLimits() if limits is None else limits
        self.timeout = timeout
        self._setpoints = (0.0, 0.0)
        self._command = (0.0, 0.0)
        self._command_time = -math.inf
        self._target: tuple[float, float] | None = None  # of the command, computed once
        self._last_update: float | None = None

    @property
    def icr(self) -> IcrParams:
        """Kinematic model of the vehicle on its terrain."""
        return self._icr

    @icr.setter
    def icr(self, icr: IcrParams) -> None:
        self._icr, self._target = icr, None

    @property
    def limits(self) -> CommandLimits:
        """Velocity and acceleration limits."""
        return self._limits

    @limits.setter
    def limits(self, limits: CommandLimits) -> None:
        self._limits, self._target = limits, None

    @property
    def setpoints(self) -> tuple[float, float]:
        """Return the last nominal setpoints ``(left, right)``, m/s."""
        return self._setpoints

    def command(self, v_x: float, w: float, t: float) -> None:
        """
        Take a new twist command.

        Parameters
        ----------
        v_x, w : float
            Forward velocity (m/s) and yaw rate (rad/s).
        t : float
            Arrival time, s, on the clock of :meth:`update`.

        Raises
        ------
        ValueError
            When ``v_x`` or ``w`` is not finite; the last good command stays in force.

        """
        v_x, w = float(v_x), float(w)
        if not (math.isfinite(v_x) and math.isfinite(w)):
            raise ValueError(f'non-finite twist command (v_x={v_x!r}, w={w!r})')
        if (v_x, w) != self._command:
            self._command, self._target = (v_x, w), None
        self._command_time = float(t)

    def is_stale(self, t: float) -> bool:
        """Tell whether no command arrived in the ``timeout`` before ``t``."""
        return t - self._command_time > self.timeout

    def target(self, v_x: float, w: float) -> tuple[float, float]:
        """
        Nominal setpoints for a twist within the velocity limits, before any ramp.

        Returns
        -------
        left, right : float
            m/s.

        """
        limits = self._limits
        v_x, w = limit_twist(v_x, w, limits.max_linear_velocity, limits.max_angular_velocity)
        left, right = saturate_tracks(*track_setpoints(v_x, w, self._icr),
                                      limits.max_track_speed)
        return float(left), float(right)

    def update(self, t: float, max_dt: float = math.inf) -> tuple[float, float]:
        """
        Setpoints at time ``t``: toward the current command (or a stop) at the ramp limits.

        Parameters
        ----------
        t : float
            Current time, s.
        max_dt : float, optional
            Longest interval (s) one update may ramp over, so that a caller that stalled
            does not get a jump (the node passes two publish periods).

        Returns
        -------
        left, right : float
            Nominal track speed setpoints, m/s.

        """
        t = float(t)
        dt = 0.0 if self._last_update is None else min(max(t - self._last_update, 0.0), max_dt)
        self._last_update = t
        if self.is_stale(t):
            target = (0.0, 0.0)
        else:
            if self._target is None:
                self._target = self.target(*self._command)
            target = self._target
        self._setpoints = self._ramp(target, dt)
        return self._setpoints

    def reset(self) -> None:
        """Forget the command and the setpoints: stopped, as after construction."""
        self._setpoints = (0.0, 0.0)
        self._command = (0.0, 0.0)
        self._command_time = -math.inf
        self._target = None
        self._last_update = None

    def _ramp(self, target, dt):
        """Move from the last setpoints toward ``target`` by the largest allowed fraction."""
        (left0, right0), (left1, right1) = self._setpoints, target
        d_left, d_right = left1 - left0, right1 - right0
        if d_left == 0.0 and d_right == 0.0:
            return self._setpoints
        limits, icr = self._limits, self._icr
        # The twist change that the setpoint change makes (forward kinematics is linear).
        d_v, _, d_w = forward(d_left * icr.scale_left, d_right * icr.scale_right, icr)
        fraction = min(_fraction(max(abs(d_left), abs(d_right)), limits.max_track_accel, dt),
                       _fraction(abs(float(d_v)), limits.max_linear_acceleration, dt),
                       _fraction(abs(float(d_w)), limits.max_angular_acceleration, dt))
        if fraction >= 1.0:
            return float(left1), float(right1)
        return left0 + fraction * d_left, right0 + fraction * d_right


def _fraction(change: float, rate_limit: float, dt: float) -> float:
    """Fraction (at most 1) of ``change`` (>= 0) that ``rate_limit`` (> 0) allows in ``dt``."""
    if math.isinf(rate_limit):
        return 1.0
    allowed = rate_limit * dt
    return 1.0 if change <= allowed else allowed / change
