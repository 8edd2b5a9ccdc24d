"""
The safety supervisor of a calibration drive: a pure state machine from inputs to a command.

A node calls :meth:`Supervisor.update` at a fixed rate (and whenever the deadman changes)
with what it knows (:class:`Inputs`: the time, the deadman's value and when it came, when the
encoders and the reference last delivered, the pose in the geofence frame) and publishes the
``(v, w)`` of the :class:`Output`; the services call :meth:`Supervisor.start`,
:meth:`Supervisor.pause` and :meth:`Supervisor.stop`. The rules, each one tested on its own
(test/core/plan/test_supervisor.py):

1. **Deadman.** The vehicle moves only while the deadman is held and its last message is at
   most ``deadman_timeout`` old. Released or stale, the command is zero at once and the
   state ``paused``; the current step restarts (planned again from the pose then) when the
   deadman is held again. A return towards the centre resumes where it was.
2. **Geofence.** A circle of ``geofence_radius`` around the pose at start. Before a step is
   driven it is predicted with the ideal kinematics from the current pose
   (:func:`.calibration.fence_exit`) and must stay within ``plan_fraction`` of the radius;
   otherwise a return towards the centre is driven first (state ``returning``), and a step
   that still does not fit from there is cut where it would leave. While driving, a vehicle
   whose real path (it slips: an uncalibrated vehicle turns less than commanded) is past
   ``guard_fraction`` of the radius and moving outwards ends its step and returns. The
   return is closed-loop on the measured pose: turn in place towards the centre, then drive
   to within ``inner_fraction`` of the radius; one that takes longer than ``return_timeout``
   stops the drive.
3. **Caps.** ``|v| <= max_speed`` and ``|w| <= max_yaw_rate``; a command beyond either is
   scaled down, both components together (the path's curvature is kept).
4. **Stale sensors.** Encoders or the reference that have not delivered for
   ``encoder_timeout`` / ``reference_timeout`` while the vehicle should move stop the drive
   (state ``stopped``, the reason names the sensor); ``start`` resumes it once they are
   fresh again.
5. **Finite.** The command is always finite: a pose that is not finite counts as a stale
   reference, and any non-finite command is replaced by zero and stops the drive.

States: ``idle`` (before start), ``running``, ``paused``, ``returning``, ``finished`` (the
protocol is done), ``stopped`` (by ``stop``, terminal; or by a sensor, resumable).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math

from .calibration import fence_exit, Step
from .._checks import require_numbers
from ..integration import wrap_angle

STATES = ('idle', 'running', 'paused', 'returning', 'finished', 'stopped')


@dataclass(frozen=True, slots=True)
class SupervisorConfig:
    """
    Limits and timeouts of the supervisor.

    Attributes
    ----------
    geofence_radius : float
        m, around the pose at start.
    max_speed, max_yaw_rate : float
        Caps of the command, m/s and rad/s.
    deadman_timeout, encoder_timeout, reference_timeout : float
        Oldest acceptable deadman message, encoder step and reference message, s.
    auto_start : bool
        Start when the deadman is first held, without ``start``.
    plan_fraction : float
        A planned step must stay within this fraction of the radius.
    guard_fraction : float
        Past this fraction of the radius, moving outwards ends the step.
    inner_fraction : float
        A return ends within this fraction of the radius from the centre.
    return_timeout : float
        Longest return, s.
    heading_tolerance : float
        A return turns in place until it faces the centre this well, rad.

    """

    geofence_radius: float = 3.0
    max_speed: float = 0.5
    max_yaw_rate: float = 1.0
    deadman_timeout: float = 0.3
    encoder_timeout: float = 0.5
    reference_timeout: float = 0.5
    auto_start: bool = False
    plan_fraction: float = 0.85
    guard_fraction: float = 0.93
    inner_fraction: float = 0.25
    return_timeout: float = 60.0
    heading_tolerance: float = 0.2

    def __post_init__(self):
        require_numbers(self, positive=('geofence_radius', 'max_speed', 'max_yaw_rate',
                                        'deadman_timeout', 'encoder_timeout',
                                        'reference_timeout', 'return_timeout',
                                        'heading_tolerance'))
        if not (0.0 < self.inner_fraction < self.plan_fraction <= self.guard_fraction <= 1.0):
            raise ValueError(
                'need 0 < inner_fraction < plan_fraction <= guard_fraction <= 1, got '
                f'{self.inner_fraction!r}, {self.plan_fraction!r}, {self.guard_fraction!r}')


@dataclass(frozen=True, slots=True)
class Inputs:
    """
    What the node knows at one instant; times on one clock (the node's), s.

    Attributes
    ----------
    t : float
        Now.
    deadman : bool
        Last deadman value (False before any).
    deadman_t : float or None
        When the last deadman message arrived (None: never).
    encoder_t, reference_t : float or None
        When the encoders and the reference last delivered (None: never).
    pose : tuple of float or None
        Current pose ``(x, y, yaw)`` in the frame the geofence is kept in (the reference's,
        or dead reckoning); None when unknown.
    not_ready : str
        Why the drive may not start yet (the gyro bias is not measured), or ''.

    """

    t: float
    deadman: bool = False
    deadman_t: float | None = None
    encoder_t: float | None = None
    reference_t: float | None = None
    pose: tuple | None = None
    not_ready: str = ''


@dataclass(frozen=True, slots=True)
class Output:
    """
    The command to publish and the state, with the reason for it.

    Attributes
    ----------
    v, w : float
        Command, m/s and rad/s; always finite, within the caps, zero unless moving.
    state : str
        One of :data:`STATES`.
    reason : str
        Why (``''`` when running normally).
    step : int
        Index of the current protocol step (``len(steps)`` when done).
    steps : int
        Number of protocol steps.
    step_elapsed : float
        Time into the current step, s.
    distance : float or None
        Distance from the geofence centre, m (None before start or without a pose).

    """

    v: float
    w: float
    state: str
    reason: str
    step: int
    steps: int
    step_elapsed: float = 0.0
    distance: float | None = None

    @property
    def moving(self) -> bool:
        """Return whether the command is not zero."""
        return self.v != 0.0 or self.w != 0.0


@dataclass
class _Drive:
    """The mutable part of the supervisor (kept apart, so the rules read as functions)."""

    state: str = 'idle'
    reason: str = ''
    index: int = 0
    step: Step | None = None          # the current step as planned (maybe cut)
    step_t0: float | None = None      # when it started; None: plan it at the next update
    centre: tuple | None = None
    paused_by_user: bool = False
    return_t0: float | None = None
    return_phase: str = ''
    terminal: bool = False
    returned_for: int = -1            # the step a return was already driven for
    log: list = field(default_factory=list)


class Supervisor:
    """
    The calibration drive's state machine (see the module docstring for the rules).

    Parameters
    ----------
    steps : sequence of Step
        The protocol (:func:`.calibration.protocol`).
    config : SupervisorConfig
        Limits and timeouts.

    """

    def __init__(self, steps, config: SupervisorConfig = SupervisorConfig()):
        self.steps = tuple(steps)
        if not self.steps:
            raise ValueError('the protocol has no steps')
        self.config = config
        self._d = _Drive()
        self._last = Output(0.0, 0.0, 'idle', 'waiting for start', 0, len(self.steps))

    # --- services --------------------------------------------------------------------

    @property
    def state(self) -> str:
        """Return the current state."""
        return self._d.state

    @property
    def centre(self) -> tuple | None:
        """Return ``(x, y)`` of the geofence centre, or None before start."""
        return self._d.centre

    @property
    def events(self) -> list:
        """Return ``(t, state, reason)`` of every state change, oldest first."""
        return list(self._d.log)

    def start(self, inputs: Inputs) -> tuple[bool, str]:
        """
        Start the protocol (from ``idle``), or resume it (after ``pause`` or a sensor stop).

        Returns
        -------
        ok : bool
        message : str

        """
        d = self._d
        if d.terminal or d.state == 'finished':
            return False, (f'cannot start: the drive is {d.state} ({d.reason}); start the '
                           'node again')
        if d.state == 'idle':
            problem = inputs.not_ready or self._stale(inputs)
            if problem:
                return False, f'cannot start: {problem}'
            pose = inputs.pose
            d.centre = (float(pose[0]), float(pose[1]))
            d.index, d.step, d.step_t0 = 0, None, None
            self._set(inputs.t, 'running', '')
            return True, (f'started: {len(self.steps)} steps, geofence of '
                          f'{self.config.geofence_radius:g} m around ({d.centre[0]:.2f}, '
                          f'{d.centre[1]:.2f})')
        if d.state == 'stopped':
            problem = self._stale(inputs)
            if problem:
                return False, f'cannot resume: {problem}'
            d.step_t0 = None
            self._set(inputs.t, 'returning' if d.return_phase else 'running', 'resumed')
            return True, f'resumed at step {d.index + 1} of {len(self.steps)}'
        if d.paused_by_user:
            d.paused_by_user = False
            d.step_t0 = None
            return True, f'resumed at step {d.index + 1} of {len(self.steps)}'
        return True, f'already {d.state}'

    def pause(self, inputs: Inputs) -> tuple[bool, str]:
        """Pause: zero command at once; ``start`` resumes (the current step restarts)."""
        d = self._d
        if d.state in ('idle', 'finished') or d.terminal:
            return False, f'cannot pause: the drive is {d.state}'
        d.paused_by_user = True
        d.step_t0 = None
        self._set(inputs.t, 'paused', 'paused by ~/pause')
        return True, 'paused; call ~/start to resume'

    def stop(self, inputs: Inputs) -> tuple[bool, str]:
        """Stop for good: zero command at once; the drive cannot be resumed."""
        d = self._d
        if d.state == 'finished':
            return False, 'the drive is already finished'
        d.terminal = True
        self._set(inputs.t, 'stopped', 'stopped by ~/stop')
        return True, 'stopped: the command is zero; nothing more is driven'

    # --- the rules --------------------------------------------------------------------

    def update(self, inputs: Inputs) -> Output:
        """Apply the rules at ``inputs.t``; return the command to publish and the state."""
        out = self._update(inputs)
        v, w = out.v, out.w
        if not (math.isfinite(v) and math.isfinite(w)):
            self._stop_for(inputs.t, f'non-finite command ({v!r}, {w!r}) refused')
            out = self._output(inputs, 0.0, 0.0)
        self._last = out
        return out

    @property
    def last(self) -> Output:
        """Return the output of the latest update."""
        return self._last

    def _update(self, inputs: Inputs) -> Output:
        d, cfg = self._d, self.config
        t = inputs.t
        if not math.isfinite(t):
            return self._output(inputs, 0.0, 0.0)
        if d.state == 'idle':
            if not (cfg.auto_start and self._deadman_fresh(inputs)):
                return self._output(inputs, 0.0, 0.0)
            ok, message = self.start(inputs)
            if not ok:   # waits for the sensors
                return self._output(inputs, 0.0, 0.0, reason=message)
        if d.state in ('finished', 'stopped'):
            return self._output(inputs, 0.0, 0.0)
        if d.paused_by_user:
            return self._output(inputs, 0.0, 0.0)
        if not self._deadman_fresh(inputs):
            # Rule 1: zero at once; the step restarts on resume.
            d.step_t0 = d.return_t0 = None
            why = 'deadman released' if (inputs.deadman_t is not None and not inputs.deadman) \
                else f'deadman not held within {cfg.deadman_timeout:g} s'
            self._set(t, 'paused', why)
            return self._output(inputs, 0.0, 0.0)
        problem = self._stale(inputs)
        if problem:
            self._stop_for(t, problem)
            return self._output(inputs, 0.0, 0.0)
        if d.state == 'paused':
            self._set(t, 'returning' if d.return_phase else 'running', 'resumed')
        if d.return_phase:
            return self._returning(inputs)
        return self._running(inputs)

    def _deadman_fresh(self, inputs: Inputs) -> bool:
        age = None if inputs.deadman_t is None else inputs.t - inputs.deadman_t
        return bool(inputs.deadman) and age is not None and \
            -self.config.deadman_timeout <= age <= self.config.deadman_timeout

    def _stale(self, inputs: Inputs) -> str:
        cfg = self.config
        for what, when, timeout in (('encoders', inputs.encoder_t, cfg.encoder_timeout),
                                    ('reference', inputs.reference_t, cfg.reference_timeout)):
            if when is None:
                return f'no {what} data'
            age = inputs.t - when
            if not (-timeout <= age <= timeout):
                return f'{what} stale ({age:.2f} s old, timeout {timeout:g} s)'
        pose = inputs.pose
        if pose is None or not all(map(math.isfinite, pose)):
            return 'reference stale (no finite pose)'
        return ''

    def _running(self, inputs: Inputs) -> Output:
        d, cfg = self._d, self.config
        t, pose = inputs.t, inputs.pose
        radius = cfg.geofence_radius
        if d.step_t0 is not None and t < d.step_t0:
            d.step_t0 = None  # time went backwards (sim time reset): restart the step
        if d.step_t0 is not None and t - d.step_t0 >= d.step.duration:
            d.index += 1
            d.step_t0 = None
        if d.index >= len(self.steps):
            self._set(t, 'finished', f'all {len(self.steps)} steps driven')
            return self._output(inputs, 0.0, 0.0)
        if d.step_t0 is None:
            step = self.steps[d.index]
            cut = fence_exit(pose, step, d.centre, cfg.plan_fraction * radius)
            if cut is not None:
                if d.returned_for != d.index and not self._near_centre(pose):
                    d.returned_for = d.index
                    return self._begin_return(inputs, 'the next step would leave the geofence')
                if cut < 0.5:
                    # Even from the centre it leaves at once: drive the next one instead.
                    d.index += 1
                    return self._running(inputs)
                step = replace(step, duration=cut)
            d.step, d.step_t0 = step, t
            self._set(t, 'running', '')
        if self._leaving(pose):
            d.index += 1
            d.step_t0 = None
            return self._begin_return(inputs, 'at the geofence, moving outwards')
        return self._output(inputs, d.step.v, d.step.w)

    def _near_centre(self, pose) -> bool:
        c = self._d.centre
        return math.hypot(pose[0] - c[0], pose[1] - c[1]) \
            <= self.config.inner_fraction * self.config.geofence_radius

    def _leaving(self, pose) -> bool:
        d, cfg = self._d, self.config
        dx, dy = pose[0] - d.centre[0], pose[1] - d.centre[1]
        if math.hypot(dx, dy) < cfg.guard_fraction * cfg.geofence_radius:
            return False
        # Moving outwards: the body's velocity direction (by the sign of v) points away.
        v = d.step.v
        heading = pose[2] if v >= 0.0 else pose[2] + math.pi
        return v != 0.0 and dx * math.cos(heading) + dy * math.sin(heading) > 0.0

    def _begin_return(self, inputs: Inputs, why: str) -> Output:
        d = self._d
        d.return_phase, d.return_t0 = 'turn', inputs.t
        self._set(inputs.t, 'returning', why)
        return self._returning(inputs)

    def _returning(self, inputs: Inputs) -> Output:
        d, cfg = self._d, self.config
        t, pose = inputs.t, inputs.pose
        if d.return_t0 is None or t < d.return_t0:
            d.return_t0 = t
        if t - d.return_t0 > cfg.return_timeout:
            d.return_phase = ''
            self._stop_for(t, f'the return to the geofence centre took more than '
                           f'{cfg.return_timeout:g} s')
            return self._output(inputs, 0.0, 0.0)
        dx, dy = d.centre[0] - pose[0], d.centre[1] - pose[1]
        distance = math.hypot(dx, dy)
        if distance <= cfg.inner_fraction * cfg.geofence_radius:
            d.return_phase, d.step_t0 = '', None
            self._set(t, 'running', 'back near the centre')
            return self._running(inputs)
        error = float(wrap_angle(math.atan2(dy, dx) - pose[2]))
        w = max(-cfg.max_yaw_rate, min(cfg.max_yaw_rate, 2.0 * error))
        if d.return_phase == 'turn':
            if abs(error) > cfg.heading_tolerance:
                return self._output(inputs, 0.0, w)
            d.return_phase = 'drive'
        if abs(error) > 4.0 * cfg.heading_tolerance:
            d.return_phase = 'turn'
            return self._output(inputs, 0.0, w)
        v = 0.6 * cfg.max_speed * min(1.0, distance / (0.5 * cfg.geofence_radius) + 0.3)
        return self._output(inputs, v * math.cos(error), w)

    # --- helpers ----------------------------------------------------------------------

    def _stop_for(self, t: float, reason: str) -> None:
        d = self._d
        d.step_t0 = None
        self._set(t, 'stopped', reason)

    def _set(self, t: float, state: str, reason: str) -> None:
        d = self._d
        if (state, reason) != (d.state, d.reason):
            d.log.append((t, state, reason))
        d.state, d.reason = state, reason

    def _output(self, inputs: Inputs, v: float, w: float, reason: str | None = None) -> Output:
        d, cfg = self._d, self.config
        v, w = cap(v, w, cfg.max_speed, cfg.max_yaw_rate)
        if d.state not in ('running', 'returning'):
            v = w = 0.0
        elapsed = 0.0 if d.step_t0 is None else max(0.0, inputs.t - d.step_t0)
        distance = None
        pose = inputs.pose
        if d.centre is not None and pose is not None and all(map(math.isfinite, pose[:2])):
            distance = math.hypot(pose[0] - d.centre[0], pose[1] - d.centre[1])
        return Output(v, w, d.state, d.reason if reason is None else reason,
                      min(d.index, len(self.steps)), len(self.steps), elapsed, distance)


def cap(v: float, w: float, max_speed: float, max_yaw_rate: float) -> tuple[float, float]:
    """
    Scale ``(v, w)`` down, both together, until ``|v| <= max_speed`` and ``|w| <= max_yaw_rate``.

    Scaling both keeps the curvature ``w / v`` of the commanded path. A non-finite input
    gives ``(0.0, 0.0)``.
    """
    v, w = float(v), float(w)
    if not (math.isfinite(v) and math.isfinite(w)):
        return 0.0, 0.0
    factor = min(1.0, max_speed / abs(v) if v else 1.0, max_yaw_rate / abs(w) if w else 1.0)
    return v * factor, w * factor
