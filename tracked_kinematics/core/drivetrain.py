"""
Drive-train response: commanded track speeds -> track speeds, Fink & Stump sec. III-B.

Per track: a command delay, speed and acceleration limits, then a speed loop (PID around a DC
motor, eqs. 6-8, or a first-order lag), simulated exactly by a first-order hold in
``scipy.signal.lfilter``. See docs/simulator.md, "Drive train".
"""

from __future__ import annotations

from dataclasses import dataclass
import functools
import math

import numpy as np


LOOP_KINDS = ('first_order', 'pid_dc_motor', 'ideal')
"""Names of the speed loops in parameter files: FirstOrderLag, PidMotor, none."""


@dataclass(frozen=True, slots=True)
class PidMotor:
    """
    PID speed loop around a DC motor, Fink & Stump eqs. (6)-(8).

    ``C(s) = K_p + K_d s + K_i / s`` (eq. 6), ``M(s) = K / ((b + J s)(L s + R) + K^2)`` (eq. 7),
    closed loop ``C M / (1 + C M)`` (eq. 8), from desired to actual track speed (gearing in the
    gains). Attributes: gains ``kp, ki, kd`` (>= 0); ``inertia`` J (kg m^2), ``damping`` b (N m s),
    ``resistance`` R (Ohm), ``inductance`` L (H), ``motor_constant`` K (N m / A).
    """

    kp: float
    ki: float
    kd: float
    inertia: float
    damping: float
    resistance: float
    inductance: float
    motor_constant: float

    def __post_init__(self):
        # Each value's range is checked where it enters (DRIVETRAIN_PARAMS); what no single
        # range says, a loop with no gain or an unstable one, is checked here.
        if self.kp == self.ki == self.kd == 0.0:
            raise ValueError('at least one of kp, ki, kd must be > 0')
        poles = np.roots(self.transfer_function()[1])
        if np.any(poles.real >= 0.0):
            raise ValueError(f'the closed speed loop is unstable (poles {np.round(poles, 4)})')

    def transfer_function(self):
        """
        Closed-loop transfer function, eq. (8): ``num, den`` in ``s``, highest power first.

        ``K (K_d s^2 + K_p s + K_i) / (J L s^3 + (J R + b L + K K_d) s^2 + (b R + K^2 + K K_p) s +
        K K_i)``, one order less when ``K_i = 0``.
        """
        k, j, b = self.motor_constant, self.inertia, self.damping
        r, ell = self.resistance, self.inductance
        num = k * np.array([self.kd, self.kp, self.ki])
        den = np.array([j * ell, j * r + b * ell + k * self.kd,
                        b * r + k * k + k * self.kp, k * self.ki])
        if self.ki == 0.0:
            # No integrator: C(s) = K_p + K_d s, the common factor s cancels.
            return num[:-1], den[:-1]
        return num, den


@dataclass(frozen=True, slots=True)
class FirstOrderLag:
    """First-order lag ``1 / (T s + 1)``, ``time_constant`` T (s): users without motor data."""

    time_constant: float

    def transfer_function(self):
        """Return ``num, den`` of ``1 / (T s + 1)``, highest power first."""
        return np.array([1.0]), np.array([self.time_constant, 1.0])


@dataclass(frozen=True, slots=True)
class DriveTrain:
    """
    Command delay, speed and acceleration limits, and speed loop of one track (or each column).

    Attributes
    ----------
    delay : float
        Command delay ``tau``, s (>= 0).
    max_accel, max_speed : float
        Limits of the input shaping, m/s^2 and m/s (> 0; ``inf`` for none).
    loop : PidMotor, FirstOrderLag or None
        Speed loop; None passes the shaped command through (an ideal drive).

    Examples
    --------
    >>> drive = DriveTrain(delay=0.05, max_accel=2.0, loop=FirstOrderLag(0.1))
    >>> speeds = drive.simulate(np.ones(300), dt=0.01)   # 3 s step to 1 m/s

    """

    delay: float = 0.0
    max_accel: float = math.inf
    max_speed: float = math.inf
    loop: PidMotor | FirstOrderLag | None = None

    def __post_init__(self):
        if self.loop is not None and not isinstance(self.loop, (PidMotor, FirstOrderLag)):
            raise ValueError(f'loop must be a PidMotor, a FirstOrderLag or None, got '
                             f'{self.loop!r}')

    @classmethod
    def fink_stump_packbot(cls, max_speed: float = 2.0) -> DriveTrain:
        """
        Drive train identified on the Packbot, Fink & Stump Table II.

        The table prints the delay as "0.049 ms"; the text (sec. IV-A) measures 0.049 s, which we
        use.
        """
        return cls(delay=0.049, max_accel=5.5, max_speed=max_speed,
                   loop=PidMotor(kp=56.49, ki=1.11, kd=2.77, inertia=0.059, damping=0.456,
                                 resistance=0.254, inductance=0.253, motor_constant=0.0294))

    def transfer_function(self):
        """Continuous transfer function of the speed loop (``[1], [1]`` without one)."""
        if self.loop is None:
            return np.array([1.0]), np.array([1.0])
        return self.loop.transfer_function()

    @property
    def dc_gain(self) -> float:
        """Steady-state gain of the speed loop (1 with integral action or a lag)."""
        num, den = self.transfer_function()
        return float(num[-1] / den[-1])

    def discretise(self, dt: float):
        """Return ``b, a`` for ``lfilter``: the speed loop at period ``dt`` by first-order hold."""
        num, den = self.transfer_function()
        return _foh(tuple(num), tuple(den), float(dt))

    def shape(self, commands, dt: float, initial=0.0) -> np.ndarray:
        """
        Input shaping of held commands (m/s, every ``dt`` s): delay, speed and acceleration limits.

        ``initial`` is the speed before the first sample; the result is the demand at the samples
        (linear in between).
        """
        commands = np.asarray(commands, dtype=float)
        dt = _check_dt(dt)
        initial = np.broadcast_to(np.asarray(initial, float), commands.shape[1:])
        lag = int(math.ceil(self.delay / dt - 1e-9))
        if lag > 0:
            head = np.broadcast_to(initial, (min(lag, len(commands)),) + commands.shape[1:])
            commands = np.concatenate([head, commands[:len(commands) - lag]])
        shaped = np.clip(commands, -self.max_speed, self.max_speed)
        if math.isfinite(self.max_accel) and len(shaped):
            start = np.clip(initial, -self.max_speed, self.max_speed)
            columns = shaped.reshape(len(shaped), -1)
            starts = np.broadcast_to(start, shaped.shape[1:]).reshape(-1)
            limited = [_rate_limit(columns[:, j].tolist(), float(starts[j]), self.max_accel * dt)
                       for j in range(columns.shape[1])]
            shaped = np.stack(limited, axis=-1).reshape(shaped.shape)
        return shaped

    def respond(self, shaped, dt: float, initial=0.0) -> np.ndarray:
        """Speed loop response (m/s) to a shaped demand, from steady state at ``initial``."""
        shaped = np.asarray(shaped, dtype=float)
        if self.loop is None or not len(shaped):
            return shaped.copy()
        from scipy import signal   # 0.7 s to import: only where a loop is simulated
        b, a = self.discretise(_check_dt(dt))
        zi_unit = signal.lfilter_zi(b, a)
        initial = np.broadcast_to(np.asarray(initial, float), shaped.shape[1:])
        zi = zi_unit.reshape((-1,) + (1,) * (shaped.ndim - 1)) * initial
        out, _ = signal.lfilter(b, a, shaped, axis=0, zi=zi)
        return out

    def simulate(self, commands, dt: float, initial=0.0) -> np.ndarray:
        """Track speeds (m/s) from held commanded speeds: :meth:`shape`, then :meth:`respond`."""
        shaped = self.shape(commands, dt, initial)
        start = np.clip(initial, -self.max_speed, self.max_speed)
        return self.respond(shaped, dt, start)


@functools.lru_cache(maxsize=64)
def _foh(num: tuple, den: tuple, dt: float):
    """Discretise by first-order hold, cached (the matrix exponential costs more than a run)."""
    from scipy import signal
    numd, dend, _ = signal.cont2discrete((np.array(num), np.array(den)), dt, method='foh')
    numd, dend = np.atleast_1d(np.squeeze(numd)), np.atleast_1d(dend)
    numd.flags.writeable = False
    dend.flags.writeable = False
    return numd, dend


def _rate_limit(targets: list, value: float, step: float) -> list:
    """
    Sequential rate limiter on plain floats (a numpy loop would be 30 times slower).

    ``value += clip(target - value, -step, step)`` per target, branched rather than through
    ``min`` and ``max`` (twice as fast: identify_drivetrain runs it millions of times).
    """
    out = []
    append = out.append
    low = -step
    for target in targets:
        change = target - value
        if change > step:
            value += step
        elif change < low:
            value += low
        else:
            value += change
        append(value)
    return out


def _check_dt(dt) -> float:
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f'dt must be a finite number > 0 s, got {dt!r}')
    return dt
