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
- acceleration and deceleration limits (on the twist and on each track's setpoint) move the
  setpoints along the straight segment from the last setpoints to the target, by the largest
  fraction of it that no limit forbids. Both tracks reach the target together, and a ramp
  from or to rest keeps the commanded curvature all the way. A quantity whose change moves
  it toward zero (its last value and its change have opposite signs) is held to the
  deceleration limit, any other change to the acceleration limit: the rule of
  diff_drive_controller's rate limiter (control_toolbox ``RateLimiter``, which decides on
  the sign of the last value the same way). An unset deceleration limit is the acceleration
  limit, as there.

Track limits apply to the nominal setpoints, the numbers the motor controllers receive.
Unlimited is ``math.inf``.

The vehicle envelope
--------------------
Whatever the limits, no setpoint leaves the command path faster than
:data:`TRACK_SPEED_ENVELOPE`: a user's ``max_track_speed`` can only lower it. A command is
scaled into the envelope (one factor on ``v_x`` and ``w``, so its curvature is kept) before
anything downstream sees it, and the inverse kinematics is evaluated so that it cannot
overflow (:func:`envelope_setpoints`). Every number of the ramp, its differences and its
fractions is then bounded, for every finite command: a Twist of 1.8e308 m/s becomes 30 m/s,
never the inf of an overflow nor the ``0 * inf = NaN`` of a ramp that would latch.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .kinematics import IcrParams, inverse, nominal_speeds

#: Largest nominal track speed setpoint the command path ever gives, m/s, limits or none.
#: 30 m/s (108 km/h) is beyond any tracked robot, and still a speed and not an overflow.
TRACK_SPEED_ENVELOPE = 30.0

# Deceleration limit -> the acceleration limit it defaults to.
_DECELERATION_OF = {'max_track_decel': 'max_track_accel',
                    'max_linear_deceleration': 'max_linear_acceleration',
                    'max_angular_deceleration': 'max_angular_acceleration'}


@dataclass(frozen=True, slots=True)
class CommandLimits:
    """
    Velocity, acceleration and deceleration limits of the command path; ``inf`` is no limit.

    Attributes
    ----------
    max_track_speed : float
        Largest nominal track speed setpoint, m/s.
    max_track_accel : float
        Largest rate of change of a nominal track speed setpoint away from zero, m/s^2.
    max_linear_velocity, max_linear_acceleration : float
        Largest ``|v_x|`` (m/s) and its rate of change away from zero (m/s^2).
    max_angular_velocity, max_angular_acceleration : float
        Largest ``|w|`` (rad/s) and its rate of change away from zero (rad/s^2).
    max_track_decel, max_linear_deceleration, max_angular_deceleration : float or None
        Largest rate of change toward zero of a track setpoint, ``v_x`` and ``w``; None (the
        default) is the matching acceleration limit.

    Each limit is a number > 0 (``inf`` allowed), checked where it enters
    (:func:`tracked_kinematics.params.values.limits_from_values`), not here.

    """

    max_track_speed: float = math.inf
    max_track_accel: float = math.inf
    max_linear_velocity: float = math.inf
    max_linear_acceleration: float = math.inf
    max_angular_velocity: float = math.inf
    max_angular_acceleration: float = math.inf
    max_track_decel: float | None = None
    max_linear_deceleration: float | None = None
    max_angular_deceleration: float | None = None

    def __post_init__(self):
        for decel, accel in _DECELERATION_OF.items():
            if getattr(self, decel) is None:
                object.__setattr__(self, decel, getattr(self, accel))


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


def envelope_setpoints(v_x, w, icr: IcrParams, max_speed: float = TRACK_SPEED_ENVELOPE):
    """
    Nominal setpoints of a twist, both scaled by one factor <= 1 into ``max_speed``.

    :func:`track_setpoints` then :func:`saturate_tracks`, made safe for every finite
    command: where the inverse kinematics of the command itself overflows (a Twist of
    1.8e308 m/s), it is evaluated on the command divided by ``m = max(|v_x|, |w|)``, whose
    setpoints ``s`` are finite, and the result is ``s * min(m, max_speed / max|s|)``: the
    same direction in setpoint space (the curvature is kept), at the largest magnitude
    within ``max_speed``. Where the model itself overflows even then (a scale of 5e-324,
    which no parameter range accepts), the setpoints are zero.

    Parameters
    ----------
    v_x, w : array_like
        Commanded forward velocity (m/s) and yaw rate (rad/s), finite.
    icr : IcrParams
        Kinematic model of the vehicle on its terrain.
    max_speed : float
        Largest ``|setpoint|``, m/s, finite and > 0: the envelope or a lower limit.

    Returns
    -------
    left, right : ndarray
        Nominal track speeds, m/s, finite, ``|left|, |right| <= max_speed``; exactly
        :func:`track_setpoints` where those are within ``max_speed``.

    """
    v_x = np.asarray(v_x, dtype=float)
    w = np.asarray(w, dtype=float)
    with np.errstate(all='ignore'):
        left, right = track_setpoints(v_x, w, icr)
        direct = np.isfinite(left) & np.isfinite(right)
        if not np.all(direct):
            m = np.maximum(np.abs(v_x), np.abs(w))
            m_safe = np.where(m > 0.0, m, 1.0)
            unit_left, unit_right = track_setpoints(v_x / m_safe, w / m_safe, icr)
            peak = np.maximum(np.abs(unit_left), np.abs(unit_right))
            gain = np.minimum(m, np.divide(max_speed, peak, out=np.zeros_like(peak),
                                           where=peak > 0.0))
            left = np.where(direct, left, unit_left * gain)
            right = np.where(direct, right, unit_right * gain)
        left, right = saturate_tracks(left, right, max_speed)
        finite = np.isfinite(left) & np.isfinite(right)
    return np.where(finite, left, 0.0), np.where(finite, right, 0.0)


def exceeds_envelope(v_x: float, w: float, icr: IcrParams,
                     envelope: float = TRACK_SPEED_ENVELOPE) -> bool:
    """
    Tell whether a twist asks for a nominal track speed beyond ``envelope`` (m/s).

    Eqs. (10)-(11) and (20)-(21) on Python floats; an overflow (inf, or the NaN of inf - inf)
    counts as beyond.
    """
    peak = max(abs((v_x - icr.y_left * w) / icr.scale_left),
               abs((v_x - icr.y_right * w) / icr.scale_right))
    return not peak <= envelope


def setpoint_twist(left: float, right: float, icr: IcrParams) -> tuple[float, float]:
    """
    Body twist ``(v_x, w)`` that one pair of nominal setpoints makes, on Python floats.

    The forward kinematics of :func:`~tracked_kinematics.core.kinematics.forward`
    (Martinez et al. 2005, eqs. 7-9 in the ROS frame) after the scale corrections of
    eqs. (20)-(21), written out for two floats: it runs at every publish, where numpy's
    per-call cost on scalars would be most of the work. Linear, so it also maps a change
    of the setpoints to the change of the twist.
    """
    v_left, v_right = left * icr.scale_left, right * icr.scale_right
    w = (v_right - v_left) / (icr.y_left - icr.y_right)
    return 0.5 * (v_right + v_left) + w * (0.5 * (icr.y_left + icr.y_right)), w


def setpoint_problem(left: float, right: float, icr: IcrParams, limits: CommandLimits,
                     envelope: float = TRACK_SPEED_ENVELOPE, rel: float = 1e-9) -> str | None:
    """
    Say what forbids sending a pair of nominal setpoints, or return None when nothing does.

    The check of an output guard: both finite, neither beyond ``max_track_speed`` nor the
    envelope, and the twist they make (:func:`setpoint_twist`) within the twist velocity
    limits, each up to a relative rounding margin ``rel``.

    Returns
    -------
    str or None
        What is wrong, with the numbers, for a warning.

    """
    if not (math.isfinite(left) and math.isfinite(right)):
        return f'non-finite setpoints ({left!r}, {right!r})'
    speed = max(abs(left), abs(right))
    if limits.max_track_speed < envelope:
        limit, name = limits.max_track_speed, 'max_track_speed'
    else:
        limit, name = envelope, 'the vehicle envelope'
    if speed > limit * (1.0 + rel):
        return f'track speed {speed:g} m/s beyond {name} {limit:g} m/s'
    if math.isfinite(limits.max_linear_velocity) or math.isfinite(limits.max_angular_velocity):
        v_x, w = setpoint_twist(left, right, icr)
        if abs(v_x) > limits.max_linear_velocity * (1.0 + rel):
            return f'v_x {v_x:g} m/s beyond the linear velocity limit ' \
                   f'{limits.max_linear_velocity:g} m/s'
        if abs(w) > limits.max_angular_velocity * (1.0 + rel):
            return f'w {w:g} rad/s beyond the angular velocity limit ' \
                   f'{limits.max_angular_velocity:g} rad/s'
    return None


class CommandLimiter:
    """
    Twist commands in, limited nominal track setpoints out, one update per publish period.

    The caller gives each command with its time (:meth:`command`) and asks for the
    setpoints at every publish time (:meth:`update`). A command older than ``timeout`` (or,
    when the caller gives steady times too, older than ``steady_timeout`` on the steady
    clock) is replaced by a stop, reached at the deceleration limits (at once when there are
    none). A stale command stays stale until a new one comes, whatever the clocks say later
    (a clock that goes back cannot revive it); :meth:`stop` ramps to zero on a clock of the
    caller's choice (a fault of the ROS clock).

    Parameters
    ----------
    icr : IcrParams
        Kinematic model of the vehicle on its terrain.
    limits : CommandLimits, optional
        Velocity, acceleration and deceleration limits; none by default.
    timeout : float, optional
        Age (s) beyond which a command is stale, > 0; ``inf`` disables the timeout.
    steady_timeout : float, optional
        Steady time (s) since its arrival beyond which a command is stale, > 0; ``inf`` (the
        default) judges on ``timeout`` alone.
    envelope : float, optional
        Largest nominal setpoint, m/s, whatever the limits (:data:`TRACK_SPEED_ENVELOPE`).

    Attributes
    ----------
    icr, limits, timeout, steady_timeout
        May be replaced between updates (runtime parameter changes); the ramp continues
        from the last setpoints, scaled at once into new velocity limits (a velocity limit
        is never exceeded, not even to ramp down to it).

    Notes
    -----
    The target setpoints of a command are computed once, when the command (or the model,
    or a limit) changes; an update in between costs a few microseconds.

    """

    def __init__(self, icr: IcrParams, limits: CommandLimits | None = None,
                 timeout: float = 0.5, envelope: float = TRACK_SPEED_ENVELOPE,
                 steady_timeout: float = math.inf):
        self._icr = icr
        self._limits = CommandLimits() if limits is None else limits
        self.timeout = timeout
        self.steady_timeout = steady_timeout
        self.envelope = float(envelope)
        self._setpoints = (0.0, 0.0)
        self._command = (0.0, 0.0)
        self._command_time = -math.inf
        self._command_steady: float | None = None  # steady time of its arrival, s
        self._live = False  # the command is in force (not judged stale nor dropped)
        self._target: tuple[float, float] | None = None  # of the command, computed once
        self._last_update: float | None = None

    @property
    def icr(self) -> IcrParams:
        """Kinematic model of the vehicle on its terrain."""
        return self._icr

    @icr.setter
    def icr(self, icr: IcrParams) -> None:
        self._icr, self._target = icr, None
        self._setpoints = self._within_velocity_limits(self._setpoints)

    @property
    def limits(self) -> CommandLimits:
        """Velocity, acceleration and deceleration limits."""
        return self._limits

    @limits.setter
    def limits(self, limits: CommandLimits) -> None:
        self._limits, self._target = limits, None
        self._setpoints = self._within_velocity_limits(self._setpoints)

    @property
    def max_speed(self) -> float:
        """Return the largest setpoint, m/s: ``max_track_speed`` or the envelope if lower."""
        return min(self._limits.max_track_speed, self.envelope)

    @property
    def setpoints(self) -> tuple[float, float]:
        """Return the last nominal setpoints ``(left, right)``, m/s."""
        return self._setpoints

    def command(self, v_x: float, w: float, t: float, steady: float | None = None) -> None:
        """
        Take a new twist command.

        Parameters
        ----------
        v_x, w : float
            Forward velocity (m/s) and yaw rate (rad/s), finite (any magnitude: the envelope
            scales it).
        t : float
            Time of the command (its arrival, or its stamp if older), s, on the clock of
            :meth:`update`.
        steady : float, optional
            Steady time of its arrival, s (``time.monotonic()``); None: not judged on it.

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
        self._command_steady = None if steady is None else float(steady)
        self._live = True

    def is_stale(self, t: float, steady: float | None = None) -> bool:
        """
        Tell whether the command in force is stale at ``t`` (and steady time ``steady``).

        Stale: judged stale before or dropped, older than ``timeout`` at ``t``, or (when
        both steady times are known) older than ``steady_timeout`` at ``steady``.
        """
        if not self._live or t - self._command_time > self.timeout:
            return True
        arrival = self._command_steady
        return (steady is not None and arrival is not None
                and steady - arrival > self.steady_timeout)

    def drop(self) -> None:
        """Take the command out of force: stale until a new one comes."""
        self._live = False

    def target(self, v_x: float, w: float) -> tuple[float, float]:
        """
        Nominal setpoints for a twist within the velocity limits and the envelope, unramped.

        Returns
        -------
        left, right : float
            m/s, finite for every finite twist.

        """
        limits, icr = self._limits, self._icr
        if abs(v_x) <= limits.max_linear_velocity and abs(w) <= limits.max_angular_velocity:
            # Within every limit (the usual case): eqs. (10)-(11), (20)-(21) on floats, the
            # same operations as track_setpoints, a microsecond instead of twenty.
            left = (v_x - icr.y_left * w) / icr.scale_left
            right = (v_x - icr.y_right * w) / icr.scale_right
            if max(abs(left), abs(right)) <= self.max_speed:  # False for an overflow, NaN
                return left, right
        v_x, w = limit_twist(v_x, w, limits.max_linear_velocity, limits.max_angular_velocity)
        left, right = envelope_setpoints(v_x, w, icr, self.max_speed)
        return float(left), float(right)

    def update(self, t: float, max_dt: float = math.inf,
               steady: float | None = None) -> tuple[float, float]:
        """
        Setpoints at time ``t``: toward the current command (or a stop) at the ramp limits.

        Parameters
        ----------
        t : float
            Current time, s.
        max_dt : float, optional
            Longest interval (s) one update may ramp over, so that a caller that stalled
            does not get a jump (the node passes two publish periods).
        steady : float, optional
            Steady time now, s, to judge the command on ``steady_timeout`` too.

        Returns
        -------
        left, right : float
            Nominal track speed setpoints, m/s.

        """
        t = float(t)
        dt = 0.0 if self._last_update is None else min(max(t - self._last_update, 0.0), max_dt)
        self._last_update = t
        if self.is_stale(t, steady):
            self._live = False  # latched: no later clock reading revives it
            target = (0.0, 0.0)
        else:
            if self._target is None:
                self._target = self.target(*self._command)
            target = self._target
        self._setpoints = self._ramp(target, dt)
        return self._setpoints

    def stop(self, dt: float) -> tuple[float, float]:
        """
        Drop the command and ramp toward zero over ``dt`` s at the deceleration limits.

        For a fault of the clock of :meth:`update`: ``dt`` comes from another clock (the
        steady one), and the next :meth:`update` ramps from there without a jump.
        """
        self._live = False
        self._last_update = None
        self._setpoints = self._ramp((0.0, 0.0), max(float(dt), 0.0))
        return self._setpoints

    def force_stop(self) -> None:
        """Set the setpoints to zero at once, keeping the command (an output guard's stop)."""
        self._setpoints = (0.0, 0.0)

    def reset(self) -> None:
        """Forget the command and the setpoints: stopped, as after construction."""
        self._setpoints = (0.0, 0.0)
        self._command = (0.0, 0.0)
        self._command_time = -math.inf
        self._command_steady = None
        self._live = False
        self._target = None
        self._last_update = None

    def _within_velocity_limits(self, setpoints):
        """Scale setpoints by one factor into the velocity limits (zero if not finite)."""
        left, right = setpoints
        if not (math.isfinite(left) and math.isfinite(right)):
            return 0.0, 0.0
        if left == 0.0 and right == 0.0:
            return setpoints
        v_x, w = setpoint_twist(left, right, self._icr)
        limits = self._limits
        factor = min(_ratio(self.max_speed, max(abs(left), abs(right))),
                     _ratio(limits.max_linear_velocity, abs(v_x)),
                     _ratio(limits.max_angular_velocity, abs(w)))
        return setpoints if factor >= 1.0 else (left * factor, right * factor)

    def _ramp(self, target, dt):
        """Move from the last setpoints toward ``target`` by the largest allowed fraction."""
        (left0, right0), (left1, right1) = self._setpoints, target
        d_left, d_right = left1 - left0, right1 - right0
        if d_left == 0.0 and d_right == 0.0:
            return self._setpoints
        limits, icr = self._limits, self._icr
        # The twist now, and the twist change that the setpoint change makes (linear map).
        v_x0, w0 = setpoint_twist(left0, right0, icr)
        d_v, d_w = setpoint_twist(d_left, d_right, icr)
        fraction = min(
            _fraction(left0, d_left, limits.max_track_accel, limits.max_track_decel, dt),
            _fraction(right0, d_right, limits.max_track_accel, limits.max_track_decel, dt),
            _fraction(v_x0, d_v, limits.max_linear_acceleration,
                      limits.max_linear_deceleration, dt),
            _fraction(w0, d_w, limits.max_angular_acceleration,
                      limits.max_angular_deceleration, dt))
        if fraction >= 1.0:
            return float(left1), float(right1)
        return left0 + fraction * d_left, right0 + fraction * d_right


def _ratio(limit: float, magnitude: float) -> float:
    """Largest factor <= 1 that brings ``magnitude`` (>= 0) within ``limit`` (> 0)."""
    return limit / magnitude if magnitude > limit else 1.0


def _fraction(value: float, change: float, accel: float, decel: float, dt: float) -> float:
    """
    Fraction (at most 1) of ``change`` that the rate limits allow in ``dt``.

    A change toward zero (``value`` and ``change`` of opposite signs) is held to ``decel``,
    any other to ``accel`` (both > 0, ``inf`` for none).
    """
    rate = decel if value * change < 0.0 else accel
    if math.isinf(rate):
        return 1.0
    allowed = rate * dt
    change = abs(change)
    return 1.0 if change <= allowed else allowed / change
