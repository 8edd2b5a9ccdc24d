"""
The calibration protocol: what a vehicle drives so that ``identify_icr`` can fit its ICRs.

What each manoeuvre pins comes from the identification's own data (docs/tools/identify_icr.md,
"Recording a calibration drive", the standard errors of the ``icr_scales`` fit on the real
Warthog and Husky logs):

- **arcs of several radii, both ways, and turns in place** determine the tread ICRs
  (``icr.*``): without the curves the ICR standard errors grow two to ten times (Warthog
  0.013 -> 0.028 m, Husky 0.022 -> 0.28 m: not identified);
- **straights forwards and backwards** determine the encoder scales (``scale.*``): without
  them the scale standard error grows three times (0.003 -> 0.009);
- **several speeds**: curves at varying speed carry some of the scales' information too, and
  the ICRs should be fitted at the speeds the robot will use;
- **about three minutes of motion**: two minutes of moving time pinned the Warthog's
  parameters and the Husky's ICRs, four the Husky's scales; 30 s pinned neither.

:func:`protocol` lays out rounds of that excitation, one round per speed level, each a
straight forward and back, arcs of three yaw rates (so of several radii) to the left and to
the right, and a turn in place each way: 60 s of motion per round by default, three rounds at
0.4, 0.7 and 1.0 of the speed cap in the default 180 s. A shorter ``duration`` drives fewer
rounds (and shorter steps below 60 s).

The protocol is planned for the geofence it is given, so that the supervisor has nothing to
correct: every straight and every arc is driven there and back (an arc ``(v, w)`` is followed
by the same arc backwards, ``(-v, -w)``, which retraces it whatever the vehicle's slip), so
the vehicle comes back to where it started after each pair, and a leg reaches at most
:data:`REACH_FRACTION` of the radius from its start even when the vehicle turns only half as
fast as commanded (:data:`SLIP_TURN`: an uncalibrated vehicle's arcs are wider than
planned). A manoeuvre longer than that is driven as several shorter pairs; a fence so small
that a straight at the speed cap would last less than :data:`MIN_STEP` lowers the speeds
(``REACH_FRACTION * radius / MIN_STEP``). The steps are commands of the ideal body twist
``(v, w)`` for ``cmd_vel``; the supervisor (:mod:`.supervisor`) still plans each one against
the geofence from the current pose before driving it (:func:`predict_step`,
:func:`fence_exit`). Measured figures: docs/nodes/calibration_drive.md.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

#: Speed levels of the rounds, as fractions of the speed cap, by number of rounds.
_LEVELS = {1: (0.7,), 2: (0.5, 1.0), 3: (0.4, 0.7, 1.0)}
#: Yaw rates of the arcs, as fractions of the yaw-rate cap: three radii per speed.
ARC_YAW_FRACTIONS = (1.0, 0.6, 0.3)
#: Motion per round, s.
ROUND_SECONDS = 60.0
#: Shortest step, s: the drive train settles in a few tenths of a second and the fit cuts
#: the data into 1-s segments.
MIN_STEP = 1.5
#: A leg of a there-and-back pair goes at most this fraction of the geofence radius from
#: where it starts.
REACH_FRACTION = 0.5
#: Slowest turn, as a fraction of the commanded yaw rate, that a leg's reach allows for (an
#: effective track width up to twice the nominal one).
SLIP_TURN = 0.5
MIN_DURATION = 15.0
MAX_DURATION = 3600.0


@dataclass(frozen=True, slots=True)
class Step:
    """
    One step of the protocol: an ideal body twist held for a while.

    Attributes
    ----------
    v : float
        Forward speed, m/s.
    w : float
        Yaw rate, rad/s (counter-clockwise positive, REP-103).
    duration : float
        s.
    kind : str
        What it is for the fit: ``straight``, ``arc``, ``turn`` (in place) or ``return``
        (towards the geofence centre, inserted by the supervisor).

    """

    v: float
    w: float
    duration: float
    kind: str

    def __post_init__(self):
        for name in ('v', 'w', 'duration'):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f'step {name} must be finite, got {value!r}')
        if self.duration <= 0.0:
            raise ValueError(f'step duration must be > 0, got {self.duration!r}')

    def describe(self) -> str:
        """Return the step in words, for the status topic and logs."""
        return f'{self.kind} v {self.v:+.2f} m/s w {self.w:+.2f} rad/s for {self.duration:.1f} s'


def _check_positive(**values) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f'{name} must be finite and > 0, got {value!r}')


def protocol(duration: float = 180.0, max_speed: float = 0.5, max_yaw_rate: float = 1.0,
             geofence_radius: float = 3.0) -> tuple[Step, ...]:
    """
    Lay out the calibration drive: rounds of straights, arcs and turns in place.

    Parameters
    ----------
    duration : float
        Motion time to plan, s, in [:data:`MIN_DURATION`, :data:`MAX_DURATION`]. Rounds of
        :data:`ROUND_SECONDS` (one per speed level; below 60 s one round of shorter steps).
    max_speed : float
        Speed cap, m/s: the fastest straight (lower in a small geofence).
    max_yaw_rate : float
        Yaw-rate cap, rad/s: the fastest turn in place and the tightest arc.
    geofence_radius : float
        m; a leg goes at most :data:`REACH_FRACTION` of it from its start.

    Returns
    -------
    tuple of Step
        In driving order; straights and arcs in there-and-back pairs. Every command is
        within the caps; the durations add up to ``duration``.

    Raises
    ------
    ValueError
        For a duration outside its range or a cap that is not a positive number.

    """
    _check_positive(max_speed=max_speed, max_yaw_rate=max_yaw_rate,
                    geofence_radius=geofence_radius)
    if not (MIN_DURATION <= duration <= MAX_DURATION):
        raise ValueError(f'duration must be in [{MIN_DURATION:g}, {MAX_DURATION:g}] s, got '
                         f'{duration!r}')
    rounds = max(1, int(round(duration / ROUND_SECONDS)))
    levels = _LEVELS.get(rounds) or tuple(_LEVELS[3][i % 3] for i in range(rounds))
    reach = REACH_FRACTION * geofence_radius
    top = min(max_speed, reach / MIN_STEP)
    steps: list[Step] = []
    for level in levels:
        steps.extend(_round(level, top, duration / rounds, max_yaw_rate, reach))
    return tuple(steps)


def _round(level, top, seconds, max_yaw_rate, reach) -> list[Step]:
    """
    One round at ``level`` of the speed ``top``: 2 + 6 + 2 shares of ``seconds``.

    Straights (two shares), arcs to both sides for each of :data:`ARC_YAW_FRACTIONS` (two
    shares each), a turn in place each way (one share each).
    """
    v = level * top
    share = seconds / (4 + 2 * len(ARC_YAW_FRACTIONS))
    out = _there_and_back(v, 0.0, 2.0 * share, 'straight', reach, _STRAIGHTS)
    for fraction in ARC_YAW_FRACTIONS:
        # Tighter arcs at the faster levels too: the yaw rate stays within its cap, the
        # radius v / w varies with both the level and the fraction.
        out += _there_and_back(v, fraction * max_yaw_rate, 2.0 * share, 'arc', reach, _ARCS)
    w_turn = max(0.4, level) * max_yaw_rate
    return out + [Step(0.0, w_turn, share, 'turn'), Step(0.0, -w_turn, share, 'turn')]


#: Legs of a straight, as signs of ``v``: there, back through the start, and back to it (the
#: drive train's lag, which leaves a pair of legs short of its start, cancels).
_STRAIGHTS = ((1.0, 0.0), (-1.0, 0.0), (-1.0, 0.0), (1.0, 0.0))
#: Legs of the arcs of one yaw rate, as signs of ``v`` and ``w``: to the left and back, to
#: the right backwards and back, to the right and back, to the left backwards and back; each
#: leg is retraced by the next, and what the lag and the vehicle's asymmetry leave over
#: cancels between the halves (0.3 m at most over the eight, at 0.5 m/s and 1 rad/s).
_ARCS = ((1.0, 1.0), (-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0),
         (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, 1.0))


def _there_and_back(v, w, seconds, kind, reach, pattern) -> list[Step]:
    """
    ``seconds`` of ``(v, w)`` in the legs of ``pattern``, repeated as ``reach`` needs.

    Each leg goes at most ``reach`` from the start of the pattern, even turning at
    :data:`SLIP_TURN` of ``w``, and lasts at least :data:`MIN_STEP` where it can: a duration
    too short for the whole pattern drives its first half; when the reach and the shortest
    leg cannot both hold, the speed is lowered, ``v`` and ``w`` together (the path is kept).
    Consecutive legs of the same command are one step.
    """
    if seconds / len(pattern) < MIN_STEP:
        pattern = pattern[:len(pattern) // 2]
    legs = len(pattern)
    limit = reach_time(v, w, reach)
    repeats = max(1, math.ceil(seconds / legs / limit - 1e-9))
    leg = seconds / (legs * repeats)
    if repeats > 1 and leg < MIN_STEP:
        repeats = max(1, int(seconds / legs / MIN_STEP))
        leg = seconds / (legs * repeats)
        factor = min(1.0, limit / leg)
        v, w = v * factor, w * factor
    out: list[Step] = []
    for sign_v, sign_w in pattern * repeats:
        command = (sign_v * v, sign_w * w + 0.0)
        if out and (out[-1].v, out[-1].w) == command:
            out[-1] = Step(*command, out[-1].duration + leg, kind)
        else:
            out.append(Step(*command, leg, kind))
    return out


def reach_time(v: float, w: float, reach: float) -> float:
    """
    How long ``(v, w)`` may be held before the vehicle may be ``reach`` from its start, s.

    The vehicle may turn at any rate between :data:`SLIP_TURN` of ``w`` and ``w``: the
    widest of those arcs (radius ``|v| / (SLIP_TURN |w|)``) gets farthest soonest.

    Returns
    -------
    float
        s; ``inf`` when the vehicle can never get that far (a turn in place, or an arc whose
        widest circle has a diameter under ``reach``).

    """
    if v == 0.0:
        return math.inf
    if w == 0.0:
        return reach / abs(v)
    rate = SLIP_TURN * abs(w)
    diameter = 2.0 * abs(v) / rate
    if diameter <= reach:
        return math.inf
    # The chord of the arc after t: diameter * sin(rate * t / 2).
    return 2.0 * math.asin(reach / diameter) / rate


def predict_step(pose, v: float, w: float, duration: float, samples: int = 50):
    """
    Poses along a step driven by the ideal (nominal) kinematics, exactly along the arc.

    Parameters
    ----------
    pose : tuple of float
        Start pose ``(x, y, yaw)``, m, m, rad.
    v, w : float
        Body twist, m/s, rad/s.
    duration : float
        s.
    samples : int
        Poses returned, evenly spaced in time, the last at ``duration``.

    Returns
    -------
    x, y, yaw : ndarray, shape (samples,)

    """
    t = np.linspace(0.0, duration, samples + 1)[1:]
    x0, y0, yaw0 = (float(p) for p in pose)
    theta = w * t
    # Chord of the arc in the start frame (sin(theta)/w and (1 - cos(theta))/w at w -> 0).
    s = t * np.sinc(theta / np.pi)
    c = 0.5 * theta * t * np.sinc(theta / (2.0 * np.pi)) ** 2
    dx, dy = v * s, v * c
    cos0, sin0 = math.cos(yaw0), math.sin(yaw0)
    return x0 + cos0 * dx - sin0 * dy, y0 + sin0 * dx + cos0 * dy, yaw0 + theta


def fence_exit(pose, step: Step, centre, radius: float, samples: int = 50) -> float | None:
    """
    When a step, driven by the ideal kinematics from ``pose``, first leaves a circle.

    Parameters
    ----------
    pose : tuple of float
        Start pose ``(x, y, yaw)``.
    step : Step
        The step.
    centre : tuple of float
        ``(x, y)`` of the circle's centre, m.
    radius : float
        m.
    samples : int
        Poses checked along the step.

    Returns
    -------
    float or None
        Time into the step of the last checked pose still inside before the first one
        outside (0.0 when the first is outside), s; None when the whole step stays inside.
        A pose that is not finite counts as outside.

    """
    x, y, _ = predict_step(pose, step.v, step.w, step.duration, samples)
    with np.errstate(invalid='ignore'):
        inside = np.hypot(x - centre[0], y - centre[1]) <= radius
    if np.all(inside):
        return None
    first = int(np.argmin(inside))
    return step.duration * first / samples


def total_duration(steps) -> float:
    """Return the summed duration of ``steps``, s."""
    return float(sum(s.duration for s in steps))


class FenceOdometry:
    """
    Dead reckoning of the geofence pose when the reference gives no position (the IMU).

    The heading is the gyro's (integrated yaw rate, less a bias measured while the vehicle
    stands still: right on any terrain, as an uncalibrated vehicle's encoder heading is not,
    since it turns less than its tracks say), the distance the encoders' mean travel times
    their scales (right to a few per cent before calibration). Good for keeping a geofence
    over minutes, not for odometry: an uncorrected gyro bias of 0.002 rad/s turns the frame
    by 0.12 rad a minute, 0.36 m at 3 m from the centre.

    Parameters
    ----------
    scale_left, scale_right : float
        Encoder scales (true travel = scale x nominal).
    settle : float
        Standing time, s, after which the bias counts as measured (:attr:`settled`).
    max_rate : float
        Largest plausible yaw rate, rad/s: a sample beyond it (a saturated or broken gyro)
        is refused.
    max_jump : float
        Largest plausible change of the yaw rate from one sample to the next, rad/s, beyond
        ``max_acceleration`` times the time between them.
    max_acceleration : float
        Largest plausible yaw acceleration, rad/s^2.

    """

    def __init__(self, scale_left: float = 1.0, scale_right: float = 1.0, settle: float = 1.0,
                 max_rate: float = math.inf, max_jump: float = math.inf,
                 max_acceleration: float = 20.0):
        self.scales = (float(scale_left), float(scale_right))
        self.x = self.y = self.yaw = 0.0
        self.settle = float(settle)
        self.max_rate = float(max_rate)
        self.max_jump = float(max_jump)
        self.max_acceleration = float(max_acceleration)
        self._gyro_t = None
        self._rate = None
        self._still_time = 0.0
        self._still_sum = 0.0

    @property
    def pose(self) -> tuple[float, float, float]:
        """Return the current ``(x, y, yaw)``."""
        return self.x, self.y, self.yaw

    @property
    def bias(self) -> float:
        """Return the gyro bias measured while standing, rad/s (0 before any)."""
        return self._still_sum / self._still_time if self._still_time > 0.0 else 0.0

    @property
    def settled(self) -> bool:
        """Return whether the vehicle stood still long enough to measure the gyro bias."""
        return self._still_time >= self.settle

    def add_gyro(self, t: float, yaw_rate: float, still: bool = False) -> str:
        """
        Integrate one gyro sample held since the last, less the bias; refuse implausible ones.

        Parameters
        ----------
        t : float
            Stamp, s.
        yaw_rate : float
            rad/s.
        still : bool
            The vehicle stands still (its encoders do not move): the sample measures the
            bias.

        Returns
        -------
        str
            '' when the sample was taken; otherwise why it was refused (not finite, beyond
            ``max_rate``, a jump beyond ``max_jump``): it is not integrated.

        """
        if not (math.isfinite(t) and math.isfinite(yaw_rate)):
            return f'gyro sample not finite ({yaw_rate!r} rad/s at {t!r} s)'
        if abs(yaw_rate) > self.max_rate:
            return (f'gyro sample of {yaw_rate:.4g} rad/s beyond the plausible '
                    f'{self.max_rate:g} rad/s (saturated?)')
        if self._rate is not None and self._gyro_t is not None:
            gap = abs(t - self._gyro_t)
            allowed = self.max_jump + self.max_acceleration * min(gap, 1.0)
            if abs(yaw_rate - self._rate) > allowed:
                return (f'gyro jumped from {self._rate:.4g} to {yaw_rate:.4g} rad/s in '
                        f'{gap:.3f} s (more than {allowed:.3g} rad/s)')
        self._rate = yaw_rate
        if self._gyro_t is not None and 0.0 < t - self._gyro_t < 1.0:
            dt = t - self._gyro_t
            if still:
                self._still_time += dt
                self._still_sum += yaw_rate * dt
            self.yaw += (yaw_rate - self.bias) * dt
        self._gyro_t = t
        return ''

    def add_travel(self, d_left: float, d_right: float) -> None:
        """Advance along the current heading by the nominal track travel of one step, m."""
        ds = 0.5 * (self.scales[0] * d_left + self.scales[1] * d_right)
        if math.isfinite(ds):
            self.x += ds * math.cos(self.yaw)
            self.y += ds * math.sin(self.yaw)
