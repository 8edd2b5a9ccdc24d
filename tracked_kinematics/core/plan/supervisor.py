"""
The safety supervisor of a calibration drive: a pure state machine from inputs to a command.

A node calls :meth:`Supervisor.update` with :class:`Inputs` and publishes the :class:`Output`; the
rules (deadman, geofence, caps, stale or lying sensors, latch, late loop, returns) are in
docs/nodes/calibration_drive.md, "Safety", and tested one by one in
test/core/plan/test_supervisor.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math

from .calibration_protocol import fence_exit, Step
from .._checks import require_numbers
from ..integration import wrap_angle

STATES = ('idle', 'running', 'paused', 'returning', 'finished', 'stopped')
#: Smallest commanded or measured motion in a window that the cross-checks judge, m (the
#: simulated Auriga-alpha's tracks stood still under a return's 0.04 m/s).
MIN_CHECKED = 0.15
#: Longest delay of the encoders' samples the command check allows for, s (older ones are
#: the staleness rule's).
MAX_ENCODER_LAG = 2.0
#: Smallest encoder motion in a window against which the reference is judged, m (a slow
#: vehicle that sticks a moment in a tight arc moved 0.09 m by its encoders and 0.01 m).
MIN_REFERENCE = 0.15
#: Noise of a pose step that :func:`pose_jump` allows, m.
POSE_NOISE = 0.05
#: A return must come this much closer to the centre to count as progress, m.
RETURN_PROGRESS = 0.05


@dataclass(frozen=True, slots=True)
class SupervisorConfig:
    """
    Limits (m, m/s, rad/s), timeouts (s) and fractions of the geofence radius of the supervisor.

    The names follow docs/nodes/calibration_drive.md, "Parameters". ``reference`` is ``'pose'`` or
    ``'imu'`` (heading only). ``follow_fraction`` is 0.1 because honest encoders fell short of the
    command by up to 72 % in a reversal (drive-train lag, encoder latency).
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
    track_width: float = 0.5
    reference: str = 'pose'
    check_window: float = 1.0
    settle_time: float = 0.6
    start_grace: float = 3.0
    follow_fraction: float = 0.1
    reference_fraction: float = 0.05
    rearm_time: float = 0.1
    reaction_time: float = 0.15
    return_progress_time: float = 10.0
    outside_fraction: float = 1.15

    def __post_init__(self):
        # geofence_radius, max_speed, max_yaw_rate, the three timeouts and track_width are
        # checked where they enter (calibration_drive's parameters); the settings no
        # parameter sets are checked here.
        require_numbers(self, positive=('return_timeout', 'heading_tolerance', 'check_window',
                                        'follow_fraction', 'reference_fraction',
                                        'return_progress_time', 'outside_fraction'),
                        non_negative=('settle_time', 'start_grace', 'rearm_time', 'reaction_time'))
        if self.reference not in ('pose', 'imu'):
            raise ValueError(f"reference must be 'pose' or 'imu', got {self.reference!r}")
        if self.outside_fraction < 1.0:
            raise ValueError(f'outside_fraction must be >= 1, got {self.outside_fraction!r}')
        if not (0.0 < self.inner_fraction < self.plan_fraction <= self.guard_fraction <= 1.0):
            raise ValueError(
                'need 0 < inner_fraction < plan_fraction <= guard_fraction <= 1, got '
                f'{self.inner_fraction!r}, {self.plan_fraction!r}, {self.guard_fraction!r}')


@dataclass(frozen=True, slots=True)
class Inputs:
    """
    What the node knows at one instant; times in s on the node's clock (``*_steady``: steady).

    ``None`` times mean never; ``pose`` is ``(x, y, yaw)`` in the geofence frame or None;
    ``travel`` the cumulative nominal track travel (m) as of ``travel_t``; ``lateness`` how late
    the loop runs (s); ``not_ready`` and ``fault`` say why not to drive ('' when nothing).
    """

    t: float
    deadman: bool = False
    deadman_t: float | None = None
    encoder_t: float | None = None
    reference_t: float | None = None
    pose: tuple | None = None
    not_ready: str = ''
    steady: float | None = None
    deadman_steady: float | None = None
    encoder_steady: float | None = None
    reference_steady: float | None = None
    travel: tuple | None = None
    travel_t: float | None = None
    lateness: float = 0.0
    fault: str = ''


@dataclass(frozen=True, slots=True)
class Output:
    """
    The command ``(v, w)`` (m/s, rad/s; finite, capped) with the state and the reason for it.

    ``distance`` is from the geofence centre, m (None before start or without a pose).
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
    deadman: str = 'new'              # new -> held -> latched -> rearm -> held
    released_at: float | None = None  # when the deadman was last seen released
    history: list = field(default_factory=list)  # (t, travel, pose, v, w, travel_t) moving
    best: tuple | None = None         # (t, distance, |heading error|) of a return's best
    start_travel: tuple | None = None  # the encoders' travel at start (None: not known)
    moved: bool = False               # the tracks have moved since the start
    start_steady: float | None = None  # the steady clock at start (None: not given)


class Supervisor:
    """The calibration drive's state machine over protocol ``steps`` with ``config``."""

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
        """Start the protocol (from ``idle``) or resume it; return ``(ok, message)``."""
        d = self._d
        if d.terminal or d.state == 'finished':
            return False, (f'cannot start: the drive is {d.state} ({d.reason}); start the '
                           'node again')
        if d.state == 'idle':
            problem = inputs.not_ready or inputs.fault or self._stale(inputs)
            if problem:
                return False, f'cannot start: {problem}'
            pose = inputs.pose
            d.centre = (float(pose[0]), float(pose[1]))
            d.index, d.step, d.step_t0 = 0, None, None
            d.history.clear()
            d.start_travel, d.moved = inputs.travel, False
            d.start_steady = inputs.steady
            self._set(inputs.t, 'running', '')
            return True, (f'started: {len(self.steps)} steps, geofence of '
                          f'{self.config.geofence_radius:g} m around ({d.centre[0]:.2f}, '
                          f'{d.centre[1]:.2f})')
        if d.state == 'stopped':
            problem = inputs.fault or self._stale(inputs)
            if problem:
                return False, f'cannot resume: {problem}'
            d.step_t0 = d.return_t0 = d.best = None
            d.history.clear()
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
        self._record(inputs, out)
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
            self._deadman_fresh(inputs)   # the latch follows the deadman all the same
            return self._output(inputs, 0.0, 0.0)
        if inputs.fault:
            # Rule 6: a fault the node found stops, paused or not.
            self._stop_for(t, inputs.fault)
            return self._output(inputs, 0.0, 0.0)
        fresh = self._deadman_fresh(inputs)
        if d.paused_by_user:
            return self._output(inputs, 0.0, 0.0)
        if not fresh:
            # Rules 1 and 7: zero at once; the step restarts on resume.
            d.step_t0 = d.return_t0 = d.best = None
            self._set(t, 'paused', self._deadman_reason(inputs))
            return self._output(inputs, 0.0, 0.0)
        problem = self._stale(inputs) or self._outside(inputs) or self._cross_check(inputs)
        if problem:
            self._stop_for(t, problem)
            return self._output(inputs, 0.0, 0.0)
        if d.state == 'paused':
            self._set(t, 'returning' if d.return_phase else 'running', 'resumed')
        if d.return_phase:
            return self._returning(inputs)
        return self._running(inputs)

    def _deadman_when(self, inputs: Inputs):
        """Return (now, when) of the deadman: on the steady clock when the node gives it."""
        if inputs.steady is not None:
            return inputs.steady, inputs.deadman_steady
        return inputs.t, inputs.deadman_t

    def _deadman_fresh(self, inputs: Inputs) -> bool:
        """Rules 1 and 7: held, fresh, and pressed again after a release or a stale one."""
        d, cfg = self._d, self.config
        now, when = self._deadman_when(inputs)
        if when is None or not math.isfinite(when):
            if d.deadman == 'held':
                d.deadman = 'latched'
            return False
        if not inputs.deadman:
            # A release (from anyone): the next press must come rearm_time after its last.
            d.deadman = 'rearm'
            d.released_at = when if d.released_at is None else max(d.released_at, when)
            return False
        age = now - when
        if not (-cfg.deadman_timeout <= age <= cfg.deadman_timeout):
            if d.deadman == 'held':
                d.deadman = 'latched'
            return False
        if d.deadman == 'rearm' and when - d.released_at >= cfg.rearm_time:
            d.deadman = 'held'
        elif d.deadman == 'new':
            d.deadman = 'held'
        return d.deadman == 'held'

    def _deadman_reason(self, inputs: Inputs) -> str:
        d, cfg = self._d, self.config
        now, when = self._deadman_when(inputs)
        if when is not None and not inputs.deadman:
            return 'deadman released'
        if d.deadman == 'latched' and when is not None and \
                -cfg.deadman_timeout <= now - when <= cfg.deadman_timeout:
            return 'deadman was stale: let go and press it again'
        if d.deadman == 'rearm':
            return 'deadman released'
        return f'deadman not held within {cfg.deadman_timeout:g} s'

    def _stale(self, inputs: Inputs) -> str:
        """Rule 4: with a steady time, stale only when old on both clocks."""
        cfg = self.config
        for what, when, when_steady, timeout in (
                ('encoders', inputs.encoder_t, inputs.encoder_steady, cfg.encoder_timeout),
                ('reference', inputs.reference_t, inputs.reference_steady,
                 cfg.reference_timeout)):
            if when is None:
                return f'no {what} data'
            age = inputs.t - when
            if inputs.steady is not None:
                age_steady = math.inf if when_steady is None else inputs.steady - when_steady
                if -timeout <= age_steady <= timeout:
                    continue
                age = min(age, age_steady) if math.isfinite(age) else age_steady
            if not (-timeout <= age <= timeout):
                return f'{what} stale ({age:.2f} s old, timeout {timeout:g} s)'
        pose = inputs.pose
        if pose is None or not all(map(math.isfinite, pose)):
            return 'reference stale (no finite pose)'
        return ''

    def _outside(self, inputs: Inputs) -> str:
        """Rule 9: a pose far beyond the fence means the fence failed: stop."""
        d, cfg = self._d, self.config
        pose = inputs.pose
        distance = math.hypot(pose[0] - d.centre[0], pose[1] - d.centre[1])
        if distance > cfg.outside_fraction * cfg.geofence_radius:
            return (f'outside the geofence: {distance:.2f} m from the centre (radius '
                    f'{cfg.geofence_radius:g} m)')
        return ''

    def _cross_check(self, inputs: Inputs) -> str:
        """Rule 6: the command, the encoders and the reference must tell the same story."""
        d, cfg = self._d, self.config
        h, t, travel = d.history, inputs.t, inputs.travel
        if len(h) < 2 or travel is None or not all(map(math.isfinite, travel)):
            return ''
        # The encoders' travel is as of their latest sample: the command is compared over
        # the window that ends there, so a pipeline that delivers late (a loaded machine)
        # is not a frozen sensor. Frozen data with fresh stamps still travels nothing.
        travel_t = inputs.travel_t if inputs.travel_t is not None and \
            math.isfinite(inputs.travel_t) else t
        end = t - min(max(t - travel_t, 0.0), MAX_ENCODER_LAG)
        if not d.moved and d.start_travel is not None:
            d.moved = 0.5 * (abs(travel[0] - d.start_travel[0])
                             + abs(travel[1] - d.start_travel[1])) >= MIN_CHECKED
        # Until the tracks first move, the command path may still be coming up (a node
        # discovered late, a clock not yet received): it has start_grace to show life.
        settle = cfg.settle_time if d.moved else max(cfg.settle_time, cfg.start_grace)
        if end - h[0][0] < cfg.check_window + settle:
            return ''
        # A path coming up is processes discovering each other: wall time. In simulated time
        # faster than real, start_grace of it alone is too short (1 s of wall time at 3x).
        if not d.moved and inputs.steady is not None and d.start_steady is not None \
                and inputs.steady - d.start_steady < cfg.check_window + settle:
            return ''
        row = self._history_row
        rows = h[row(t - cfg.check_window):] + [(t, tuple(travel), tuple(inputs.pose), 0.0,
                                                 0.0, travel_t)]
        half = 0.5 * cfg.track_width
        # Commanded track travel over [end - window, end]; encoder travel over the samples
        # stamped in it.
        cmd = 0.0
        lagged = h[row(end - cfg.check_window):] + [rows[-1]]
        for a, b in zip(lagged, lagged[1:]):
            lo, hi = max(a[0], end - cfg.check_window), min(b[0], end)
            if hi > lo:
                cmd += 0.5 * (abs(a[3] - a[4] * half) + abs(a[3] + a[4] * half)) * (hi - lo)
        since = next((i for i in range(len(h) - 1, -1, -1)
                      if h[i][5] <= end - cfg.check_window), 0)
        samples = [r[1] for r in h[since:]] + [tuple(travel)]
        enc = sum(0.5 * (abs(b[0] - a[0]) + abs(b[1] - a[1]))
                  for a, b in zip(samples, samples[1:]))
        turned = 0.0
        enc_d = enc_r = ref_d = ref_r = 0.0
        first = rows[0]
        for a, b in zip(rows, rows[1:]):
            turned += float(wrap_angle(b[2][2] - a[2][2]))
            # The farthest each sensor got from where the window began: a sum of absolute
            # steps would add up sensor noise, the net motion is ~0 across a reversal (and
            # two sensors of different latency reverse at different instants).
            dl, dr = b[1][0] - first[1][0], b[1][1] - first[1][1]
            enc_d = max(enc_d, 0.5 * abs(dl + dr))
            enc_r = max(enc_r, abs(dr - dl) / cfg.track_width)
            ref_d = max(ref_d, math.hypot(b[2][0] - first[2][0], b[2][1] - first[2][1]))
            ref_r = max(ref_r, abs(turned))
        span = cfg.check_window
        if cmd >= MIN_CHECKED and enc < cfg.follow_fraction * cmd:
            return (f'encoders do not follow the command: {enc:.3f} m of track travel in '
                    f'{span:.2f} s against {cmd:.3f} m commanded ' + (
                        '(frozen encoders?)' if d.moved else '(the tracks have not moved '
                        'since the start: is the command path up, cmd_vel_translator and '
                        'the motor drivers? frozen encoders?)'))
        # Only motion along the path is judged: a turn in place moves no vehicle out of its
        # fence, and a skid-steer vehicle may barely turn in place on a grippy floor.
        if cfg.reference == 'pose':
            expected, observed = enc_d, ref_d + half * ref_r
            what = (f'pose reference does not follow the encoders: it moved {ref_d:.3f} m and '
                    f'{ref_r:.2f} rad in {span:.2f} s, the encoders {enc_d:.3f} m and '
                    f'{enc_r:.2f} rad (frozen pose?)')
        else:
            expected = half * enc_r if enc_d >= MIN_CHECKED else 0.0
            observed = half * ref_r
            what = (f'gyro does not follow the encoders: it turned {ref_r:.2f} rad in '
                    f'{span:.2f} s, the encoders {enc_r:.2f} rad (stuck gyro?)')
        if expected >= MIN_REFERENCE and observed < cfg.reference_fraction * expected:
            return what
        return ''

    def _history_row(self, t: float) -> int:
        """Index of the last history row at or before ``t`` (0 when none is)."""
        return max((i for i, row in enumerate(self._d.history) if row[0] <= t), default=0)

    def _record(self, inputs: Inputs, out: Output) -> None:
        """Keep the moving commands with the travel and pose they were sent at (rule 6)."""
        d, cfg = self._d, self.config
        travel, pose = inputs.travel, inputs.pose
        if not out.moving or travel is None or pose is None \
                or not all(map(math.isfinite, (*travel, *pose, inputs.t))):
            d.history.clear()
            return
        if d.history and inputs.t <= d.history[-1][0]:
            if inputs.t < d.history[-1][0]:
                d.history.clear()   # time went back
            else:
                d.history.pop()     # a second update at the same instant: keep the latest
        travel_t = inputs.t if inputs.travel_t is None else inputs.travel_t
        d.history.append((inputs.t, tuple(travel), tuple(pose), out.v, out.w, travel_t))
        # What the checks can still look at (rows before it only say how long it moved).
        keep = inputs.t - (cfg.check_window + max(cfg.settle_time, cfg.start_grace)
                           + MAX_ENCODER_LAG + 0.5)
        while len(d.history) > 2 and d.history[1][0] < keep:
            d.history.pop(0)

    def _delay(self, inputs: Inputs) -> float:
        """Rule 8: how long from a pose to stopped tracks, s."""
        lateness = inputs.lateness
        if not math.isfinite(lateness):
            return math.inf
        return self.config.reaction_time + max(0.0, lateness)

    def _speed_limit(self, inputs: Inputs) -> float:
        """Rule 8: the speed whose reaction distance is half the guard's margin, m/s."""
        cfg = self.config
        delay = self._delay(inputs)
        margin = 0.5 * (1.0 - cfg.guard_fraction) * cfg.geofence_radius
        return math.inf if delay <= 0.0 else margin / delay

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
        if self._leaving(pose, inputs):
            d.index += 1
            d.step_t0 = None
            return self._begin_return(inputs, 'at the geofence, moving outwards')
        return self._output(inputs, d.step.v, d.step.w)

    def _near_centre(self, pose) -> bool:
        c = self._d.centre
        return math.hypot(pose[0] - c[0], pose[1] - c[1]) \
            <= self.config.inner_fraction * self.config.geofence_radius

    def _leaving(self, pose, inputs: Inputs) -> bool:
        d, cfg = self._d, self.config
        dx, dy = pose[0] - d.centre[0], pose[1] - d.centre[1]
        v = min(abs(d.step.v), self._speed_limit(inputs))
        guard = cfg.guard_fraction * cfg.geofence_radius - v * self._delay(inputs)
        if math.hypot(dx, dy) < guard:
            return False
        # Moving outwards: the body's velocity direction (by the sign of v) points away.
        v = d.step.v
        heading = pose[2] if v >= 0.0 else pose[2] + math.pi
        return v != 0.0 and dx * math.cos(heading) + dy * math.sin(heading) > 0.0

    def _begin_return(self, inputs: Inputs, why: str) -> Output:
        d = self._d
        d.return_phase, d.return_t0, d.best = 'turn', inputs.t, None
        self._set(inputs.t, 'returning', why)
        return self._returning(inputs)

    def _returning(self, inputs: Inputs) -> Output:
        d, cfg = self._d, self.config
        t, pose = inputs.t, inputs.pose
        if d.return_t0 is None or t < d.return_t0:
            d.return_t0, d.best = t, None
        if t - d.return_t0 > cfg.return_timeout:
            d.return_phase = ''
            self._stop_for(t, f'the return to the geofence centre took more than '
                           f'{cfg.return_timeout:g} s')
            return self._output(inputs, 0.0, 0.0)
        dx, dy = d.centre[0] - pose[0], d.centre[1] - pose[1]
        distance = math.hypot(dx, dy)
        error = float(wrap_angle(math.atan2(dy, dx) - pose[2]))
        # Progress: closer to the centre, or (turning in place) facing it better.
        if d.best is None or distance < d.best[1] - RETURN_PROGRESS \
                or abs(error) < d.best[2] - 2.0 * RETURN_PROGRESS:
            d.best = (t, min(distance, d.best[1]) if d.best else distance,
                      min(abs(error), d.best[2]) if d.best else abs(error))
        elif t - d.best[0] > cfg.return_progress_time:
            d.return_phase = ''
            self._stop_for(t, f'the return to the geofence centre came no closer in '
                           f'{cfg.return_progress_time:g} s ({distance:.2f} m from it)')
            return self._output(inputs, 0.0, 0.0)
        if distance <= cfg.inner_fraction * cfg.geofence_radius:
            d.return_phase, d.step_t0, d.best = '', None, None
            self._set(t, 'running', 'back near the centre')
            return self._running(inputs)
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
        limit = self._speed_limit(inputs)
        if abs(v) > limit:
            # Rule 8: slower when late (both components: the curvature is kept).
            v, w = cap(v, w, limit, cfg.max_yaw_rate) if limit > 0.0 else (0.0, 0.0)
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
    """Scale ``(v, w)`` down together into the caps, keeping the curvature; non-finite -> zero."""
    v, w = float(v), float(w)
    if not (math.isfinite(v) and math.isfinite(w)):
        return 0.0, 0.0
    factor = min(1.0, max_speed / abs(v) if v else 1.0, max_yaw_rate / abs(w) if w else 1.0)
    return v * factor, w * factor


def pose_jump(previous, pose, dt: float, max_speed: float, max_yaw_rate: float,
              margin: float = POSE_NOISE) -> str:
    """
    Say why a step of the reference pose is implausible ('' when it is not).

    Allowed: twice the caps over ``dt`` s (slip, a push), plus ``margin`` m (ten times it in rad);
    a longer step is a second publisher or a tracker that jumped. ``dt < 0`` counts as 0.
    """
    dt = max(0.0, dt) if math.isfinite(dt) else 0.0
    step = math.hypot(pose[0] - previous[0], pose[1] - previous[1])
    turn = abs(float(wrap_angle(pose[2] - previous[2])))
    allowed = 2.0 * max_speed * dt + margin
    allowed_turn = 2.0 * max_yaw_rate * dt + 10.0 * margin
    if step > allowed or turn > allowed_turn:
        return (f'pose jumped {step:.3f} m and {turn:.3f} rad in {dt:.3f} s (at most '
                f'{allowed:.3f} m and {allowed_turn:.3f} rad are plausible): a second pose '
                'publisher or a tracker that lost the body?')
    return ''
