"""
From a body twist command to track speed setpoints, with limits that keep the path.

Inverse ICR kinematics (Martinez et al. 2005, eqs. 10-11) and the encoder scales (eqs. 20-21) give
nominal setpoints; velocity limits scale ``v_x`` and ``w`` by one factor, ramps move both tracks
along one segment. See docs/nodes/cmd_vel_translator.md, "Limits and the vehicle envelope".
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
    Velocity (m/s, rad/s) and rate (m/s^2, rad/s^2) limits of the command path; ``inf`` is none.

    Track limits apply to the nominal setpoints. ``*_decel*`` limits hold changes toward zero; None
    (the default) is the matching acceleration limit. Raises ValueError on a limit that is not > 0.
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
    """Scale ``v_x`` (m/s), ``w`` (rad/s) by one factor <= 1 into the limits (keeps curvature)."""
    v_x = np.asarray(v_x, dtype=float)
    w = np.asarray(w, dtype=float)
    factor = np.minimum(_factor(np.abs(v_x), max_linear), _factor(np.abs(w), max_angular))
    return v_x * factor, w * factor


def track_setpoints(v_x, w, icr: IcrParams):
    """
    Nominal track speed setpoints (m/s) that make the vehicle move with twist ``(v_x, w)``.

    Martinez et al. (2005) eqs. (10)-(11) in the ROS frame, then eqs. (20)-(21) undone: ``nominal =
    true / scale``.
    """
    return nominal_speeds(*inverse(v_x, w, icr), icr)


def saturate_tracks(left, right, max_speed):
    """Scale both setpoints by one factor so neither exceeds ``max_speed`` (keeps curvature)."""
    left = np.asarray(left, dtype=float)
    right = np.asarray(right, dtype=float)
    factor = _factor(np.maximum(np.abs(left), np.abs(right)), max_speed)
    return left * factor, right * factor


def envelope_setpoints(v_x, w, icr: IcrParams, max_speed: float = TRACK_SPEED_ENVELOPE):
    """
    Nominal setpoints of a twist, both scaled by one factor <= 1 into ``max_speed`` (m/s).

    :func:`track_setpoints` then :func:`saturate_tracks`, finite for every finite command: where
    the inverse kinematics overflows, it is evaluated on the command divided by ``max(|v_x|, |w|)``
    and rescaled; where the model itself overflows, the setpoints are zero.
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
    Tell whether a twist asks for a nominal track speed beyond ``envelope`` (or overflows).

    Martinez eqs. (10)-(11) and (20)-(21) on Python floats.
    """
    peak = max(abs((v_x - icr.y_left * w) / icr.scale_left),
               abs((v_x - icr.y_right * w) / icr.scale_right))
    return not peak <= envelope


def setpoint_twist(left: float, right: float, icr: IcrParams) -> tuple[float, float]:
    """
    Body twist ``(v_x, w)`` of a pair of nominal setpoints, on Python floats (fast per publish).

    Martinez et al. (2005) eqs. (7)-(9) in the ROS frame after the scales of eqs. (20)-(21).
    """
    v_left, v_right = left * icr.scale_left, right * icr.scale_right
    w = (v_right - v_left) / (icr.y_left - icr.y_right)
    return 0.5 * (v_right + v_left) + w * (0.5 * (icr.y_left + icr.y_right)), w


def setpoint_problem(left: float, right: float, icr: IcrParams, limits: CommandLimits,
                     envelope: float = TRACK_SPEED_ENVELOPE, rel: float = 1e-9) -> str | None:
    """Say what forbids sending a pair of nominal setpoints (output guard), or return None."""
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

    A command older than ``timeout`` (s; or ``steady_timeout`` on the steady clock) is replaced by
    a stop at the deceleration limits and stays stale until a new one comes. ``icr``, ``limits``
    and the timeouts may be replaced between updates; the ramp continues. See
    docs/nodes/cmd_vel_translator.md.
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
        Take a twist command ``(v_x, w)`` at time ``t`` (s; ``steady``: steady time of arrival).

        Raises ValueError when ``v_x`` or ``w`` is not finite; the last good command stays.
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
        """Tell whether the command in force is stale at ``t`` (and steady time ``steady``)."""
        if not self._live or t - self._command_time > self.timeout:
            return True
        arrival = self._command_steady
        return (steady is not None and arrival is not None
                and steady - arrival > self.steady_timeout)

    def drop(self) -> None:
        """Take the command out of force: stale until a new one comes."""
        self._live = False

    def target(self, v_x: float, w: float) -> tuple[float, float]:
        """Nominal setpoints (m/s) of a twist within the velocity limits and envelope, unramped."""
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
        Nominal setpoints (m/s) at time ``t``, ramped toward the command (or a stop).

        ``max_dt`` bounds the interval one update ramps over (no jump after a stall); ``steady``
        judges the command on ``steady_timeout`` too.
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
        """Drop the command; ramp toward zero over ``dt`` s (another clock's) at decel limits."""
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
    """Fraction (<= 1) of ``change`` the rate limits allow in ``dt`` (``decel`` toward zero)."""
    rate = decel if value * change < 0.0 else accel
    if math.isinf(rate):
        return 1.0
    allowed = rate * dt
    change = abs(change)
    return 1.0 if change <= allowed else allowed / change
