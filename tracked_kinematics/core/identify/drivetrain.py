"""
Identify the drive train (Fink & Stump sec. III-B) from commanded and measured track speeds.

The model is :class:`~tracked_kinematics.core.drivetrain.DriveTrain`: a command delay
``tau``, an acceleration limit ``a_max`` and a closed speed loop (a first-order lag, or the
PID + DC motor loop of eqs. 6-8), the same for both tracks. Its parameters are found by least
squares on the simulated response, as Fink & Stump fit theirs (sec. IV-A: "least squares fit
of the simulated to the measured speeds"; the exact procedure is not given, this is ours):

1. Both series are resampled onto a common grid of period ``dt``, the commands as held
   setpoints and the measured speeds linearly, cut at gaps (:func:`.drive_data.resample`).
2. The delay is not a smooth parameter (the model holds it to whole samples), so it is found
   by search: the rate limiter and the loop are time-invariant, so they commute with the
   delay, and the response for every candidate delay is the zero-delay response shifted by
   whole samples. One simulation thus scores every delay in ``[0, max_delay]``.
3. With the delay fixed, ``scipy.optimize.least_squares`` fits the smooth parameters: the
   time constant ``T`` (or the PID gains), and ``u = 1 / a_max`` (``u = 0`` is no limit, a
   bound the optimiser can reach).
4. Steps 2 and 3 alternate until the delay stops changing. The delay and the loop's lag
   trade off, so the search then walks the profile cost (the least-squares optimum at each
   delay) to its minimum over neighbouring delays, a bracket search on whole samples.

What speed data can identify. The loop of eq. (8),
``K (K_d s^2 + K_p s + K_i) / (J L s^3 + (J R + b L + K K_d) s^2 + (b R + K^2 + K K_p) s
+ K K_i)``, divided through by ``J L``, has five coefficients: ``K K_p / (J L)``,
``K K_i / (J L)``, ``K K_d / (J L)``, ``R / L + b / J`` and ``(b R + K^2) / (J L)``. A
measured speed response can fix at most these five, never the eight constants
``K_p, K_i, K_d, J, b, R, L, K``: for instance ``(J, L, R, b) -> (c J, L / c, R / c, c b)``
leaves the loop unchanged for any ``c > 0``. We therefore hold the five motor constants fixed
(from a base file, else Fink & Stump Table II) and fit the three gains, which then map one
to one onto the first three coefficients. Table II's ``K_i`` puts a pole at -0.018 rad/s, a
time constant of about a minute: only long steady runs inform it, and its standard error
says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
import math
import time

import numpy as np
from scipy.optimize import least_squares

from .drive_data import resample, Segment
from ..drivetrain import DriveTrain, FirstOrderLag, LOOP_KINDS, PidMotor
from ..errors import ExcitationError, FitError
from ..recording import Recording

MIN_SECONDS = 2.0
"""Least duration of usable data (after the delay search window of each segment), s."""
MIN_COMMAND_STD = 0.02
"""Least standard deviation of the commanded speeds, m/s: below it nothing is excited."""
DELAY_BLOCK = 10.0
"""s of grid samples per jackknife block of the delay's standard error."""
MIN_DELAY_BLOCKS = 5
"""Fewest blocks for a jackknife; fewer: the delay's standard error is its grid's alone."""


@dataclass(frozen=True)
class DriveTrainFit:
    """
    Result of :func:`fit_drivetrain`.

    Attributes
    ----------
    drivetrain : DriveTrain
        The identified model (``max_accel`` is ``inf`` when the limit never binds).
    loop : str
        One of :data:`LOOP_KINDS`.
    parameters : dict
        Fitted values by name: ``delay`` (s), ``max_accel`` (m/s^2), ``time_constant`` (s)
        or ``kp``, ``ki``, ``kd``.
    standard_errors : dict
        One-sigma errors from the Jacobian (residuals taken as white, so optimistic);
        ``delay``'s is the delete-one-block jackknife of the best delay over blocks of
        :data:`DELAY_BLOCK` seconds (the smooth parameters at their fit), combined with the
        grid's own half sample (the delay is a whole number of samples):
        ``delay_uncertainty`` says which. With the smooth parameters held, it leaves out
        the trade-off of the delay with the loop's lag (``delay_profile`` shows that).
    fixed : dict
        Constants held fixed (the motor constants of ``pid_dc_motor``).
    rms : float
        RMS error of the simulated against the measured speeds, m/s.
    rms_commands : float
        The same with the commands taken as the speeds (no drive-train model), m/s.
    fit_percent : float
        ``100 (1 - |error| / |speeds - mean|)``, as system identification tools report it.
    accel_limit_binding : float
        Fraction of samples where the fitted acceleration limit shapes the demand.
    max_command_accel : float
        Largest rate of change of the commands on the grid, m/s^2.
    dt : float
        Grid period, s.
    samples : int
        Grid samples (per track) in the cost.
    seconds_of_data : float
        Duration of those samples, s.
    segments : list of Segment
        The resampled data.
    delay_profile : tuple of ndarray
        Candidate delays (s) and the RMS error of each, other parameters at their fit.
    rounds : int
        Delay / least-squares alternations.
    delays_fitted : int
        Delays at which the smooth parameters were fitted (alternation and profile walk).
    delay_uncertainty : str
        How ``standard_errors['delay']`` was obtained.
    delay_at_zero : bool
        The best delay is 0, the lower end of the search: the loop's lag may absorb the
        delay, or the measured speeds lead the setpoint stamps (setpoints stamped late).
    nfev : int
        Simulations run.
    seconds : float
        Wall time of the fit, s.

    """

    drivetrain: DriveTrain
    loop: str
    parameters: dict
    standard_errors: dict
    fixed: dict
    rms: float
    rms_commands: float
    fit_percent: float
    accel_limit_binding: float
    max_command_accel: float
    dt: float
    samples: int
    seconds_of_data: float
    segments: list = field(repr=False)
    delay_profile: tuple = field(repr=False)
    rounds: int = 0
    delays_fitted: int = 0
    delay_uncertainty: str = ''
    delay_at_zero: bool = False
    nfev: int = 0
    seconds: float = 0.0

    def simulate(self, segment: Segment) -> np.ndarray:
        """Return the model's speeds on a segment, started in steady state at its first speed."""
        return self.drivetrain.simulate(segment.commands, self.dt, initial=segment.speeds[0])


def _rate_steps(shaped: np.ndarray, step: float) -> np.ndarray:
    """Mark the samples where a rate limiter of ``step`` per sample shaped the demand."""
    return np.abs(np.diff(shaped, axis=0)) >= step * (1.0 - 1e-9)


class _Problem:
    """The resampled data and the model simulated on it, for every candidate delay."""

    def __init__(self, segments, dt, max_lag, loop, fixed_motor):
        self.segments = segments
        self.dt = dt
        self.max_lag = max_lag
        self.loop = loop
        self.fixed_motor = fixed_motor
        self.measured = [s.speeds[max_lag:] for s in segments]
        self.nfev = 0
        self._shaped = {}

    def drivetrain(self, p, delay=0.0) -> DriveTrain:
        """Model of the parameter vector ``p`` (raises ValueError when it is invalid)."""
        u = p[-1]
        accel = 1.0 / u if u > 0 else math.inf
        if self.loop == 'first_order':
            loop = FirstOrderLag(p[0])
        elif self.loop == 'pid_dc_motor':
            loop = PidMotor(kp=p[0], ki=p[1], kd=p[2], **self.fixed_motor)
        else:
            loop = None
        return DriveTrain(delay=delay, max_accel=accel, loop=loop)

    def responses(self, p):
        """Zero-delay responses of every segment, or None for an invalid (unstable) model."""
        try:
            drive = self.drivetrain(p)
        except ValueError:
            return None
        self.nfev += 1
        # The shaped demand depends on a_max only: keep it while the loop's gains vary (the
        # finite differences of the Jacobian), since the rate limiter is the costly part.
        key = float(p[-1])
        shaped = self._shaped.get(key)
        if shaped is None:
            shaped = [drive.shape(s.commands, self.dt, initial=s.speeds[0])
                      for s in self.segments]
            if len(self._shaped) >= 8:
                self._shaped.pop(next(iter(self._shaped)))
            self._shaped[key] = shaped
        return [drive.respond(d, self.dt, initial=s.speeds[0])
                for d, s in zip(shaped, self.segments)]

    def lag_sse_blocks(self, responses, block: int, lag: int) -> np.ndarray:
        """Sum of squared errors per block of ``block`` samples at one delay: shape (K,)."""
        m = self.max_lag
        rows = []
        for y, meas in zip(responses, self.measured):
            diff = y[m - lag:len(y) - lag] - meas
            first = np.arange(0, len(meas), block)
            rows.append(np.add.reduceat(np.einsum('ij,ij->i', diff, diff), first))
        return np.concatenate(rows)

    def lag_sse(self, responses) -> np.ndarray:
        """Sum of squared errors for every delay of 0..max_lag samples."""
        m = self.max_lag
        sse = np.zeros(m + 1)
        for y, meas in zip(responses, self.measured):
            n = len(y)
            for lag in range(m + 1):
                diff = y[m - lag:n - lag] - meas
                sse[lag] += np.einsum('ij,ij->', diff, diff)
        return sse

    def residuals(self, p, lag):
        """Stacked errors of the model with a delay of ``lag`` samples."""
        responses = self.responses(p)
        m = self.max_lag
        if responses is None:
            # An unstable loop: a large, constant penalty steers the optimiser back.
            return np.concatenate([(np.abs(meas) + 1.0).ravel() for meas in self.measured])
        return np.concatenate([(y[m - lag:len(y) - lag] - meas).ravel()
                               for y, meas in zip(responses, self.measured)])


def _peak_accel(segments, dt: float) -> float:
    """Largest measured acceleration (99.9th percentile, 5-sample smoothing), m/s^2."""
    peaks = [np.percentile(np.abs(np.diff(np.convolve(s.speeds[:, j], np.ones(5) / 5,
                                                      mode='valid'))), 99.9) / dt
             for s in segments for j in range(2) if len(s.t) > 6]
    return float(max(peaks)) if peaks else 1.0


def _defaults_motor(base: DriveTrain | None) -> PidMotor:
    if base is not None and isinstance(base.loop, PidMotor):
        return base.loop
    return DriveTrain.fink_stump_packbot().loop


def _delay_std(blocks, lag: int, dt: float):
    """
    Return the best delay's standard error: a delete-one-block jackknife and the grid.

    ``blocks`` (K, 3) holds each block's squared errors at the delays ``lag - 1``, ``lag``
    and ``lag + 1``, each with the smooth parameters fitted at it (the profile); each
    jackknife estimate is the minimum of the parabola through the three, within one sample.
    None (the best delay at an end of the search, a loop that goes unstable): the grid's
    half sample alone. The half sample stays in any case: the model holds the delay to whole
    samples, and its discrete simulation is off the continuous truth by up to about one
    (on simulated data the best delay lands one sample from the true one).
    """
    grid = 0.5 * dt
    if blocks is None or len(blocks) < MIN_DELAY_BLOCKS:
        why = (f'fewer than {MIN_DELAY_BLOCKS} blocks of {DELAY_BLOCK:.0f} s' if blocks is not None
               else 'the best delay at an end of the search')
        return grid, f'the {1000 * dt:.0f} ms grid alone ({why})'
    k = len(blocks)
    total = blocks.sum(axis=0)
    loo = []
    for j in range(k):
        a, b, c = total - blocks[j]
        curvature = a - 2.0 * b + c
        offset = float(np.clip(0.5 * (a - c) / curvature, -1.0, 1.0)) if curvature > 0 else 0.0
        loo.append((lag + offset) * dt)
    loo = np.array(loo)
    jackknife = math.sqrt((k - 1) / k * float(np.sum((loo - loo.mean()) ** 2)))
    return (math.sqrt(jackknife ** 2 + grid ** 2),
            f'a jackknife over {k} blocks of {DELAY_BLOCK:.0f} s of the profile, and the '
            f'{1000 * dt:.0f} ms grid')


def fit_drivetrain(data: Recording | Sequence[Recording], loop: str = 'first_order',
                   dt: float | None = None, max_delay: float = 0.5, max_gap: float = 0.5,
                   base: DriveTrain | None = None, max_rounds: int = 6) -> DriveTrainFit:
    """
    Fit delay, acceleration limit and speed loop to commanded and measured track speeds.

    Parameters
    ----------
    data : Recording or sequence of Recording
        Recordings with track setpoints (``commands``); both tracks of all of them share one model.
    loop : {'first_order', 'pid_dc_motor', 'ideal'}
        Speed loop to fit: a lag ``1 / (T s + 1)``; the PID gains of eq. (8) with the motor
        constants of ``base`` (else Table II) fixed; or none.
    dt : float, optional
        Grid period, s; default the median period of the measured speeds, within
        [0.002, 0.02] s. It is also the resolution of the delay.
    max_delay : float
        Largest delay searched, s.
    max_gap : float
        Longest gap bridged in either stream, s.
    base : DriveTrain, optional
        Starting point and fixed motor constants (``pid_dc_motor``).
    max_rounds : int
        Most delay / least-squares alternations before the profile walk.

    Returns
    -------
    DriveTrainFit

    Raises
    ------
    ValueError
        Malformed inputs or options (shapes, lengths).
    TrackedKinematicsError
        Commands and measured speeds that do not overlap in time.
    ExcitationError
        Too little data, or commands that hardly change.
    FitError
        A best delay at the search bound, or a failed optimisation.

    """
    started = time.perf_counter()
    if loop not in LOOP_KINDS:
        raise ValueError(f'loop must be one of {", ".join(LOOP_KINDS)}, got {loop!r}')
    for name, value in (('max_delay', max_delay), ('max_gap', max_gap)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise ValueError(f'{name} must be a finite number >= 0 s, got {value!r}')
    recordings = [data] if isinstance(data, Recording) else list(data)
    if not recordings:
        raise ValueError('no recordings given')
    if dt is None:
        times = [np.unique(np.asarray(r.track_speeds()[0], float)) for r in recordings]
        periods = [np.median(np.diff(t)) for t in times if len(t) > 1]
        # Rounded to the microsecond: stamps jitter, and the delay is a multiple of dt.
        dt = round(float(np.clip(min(periods), 0.002, 0.02)), 6) if periods else 0.01
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f'dt must be a finite number > 0 s, got {dt!r}')
    max_lag = int(math.ceil(max_delay / dt - 1e-9))
    segments = [s for r in recordings for s in resample(r, dt, max(max_gap, dt))
                if len(s.t) > max_lag + 1]
    usable = sum(len(s.t) - max_lag for s in segments)
    if usable * dt < MIN_SECONDS:
        raise ExcitationError(
            f'too little data: {usable * dt:.1f} s of commanded and measured speeds without '
            f'gaps > {max_gap} s, after {max_delay} s per segment for the delay search '
            f'(need {MIN_SECONDS:.0f} s)')
    cmd = np.concatenate([s.commands[max_lag:] for s in segments])
    meas = np.concatenate([s.speeds[max_lag:] for s in segments])
    cmd_std, meas_std = float(np.std(cmd)), float(np.std(meas))
    if cmd_std < MIN_COMMAND_STD:
        raise ExcitationError(
            f'the commanded speeds hardly change (std {cmd_std:.4f} m/s < {MIN_COMMAND_STD} '
            'm/s): record starts, stops and speed changes')
    if meas_std < 0.1 * cmd_std:
        raise ExcitationError(
            f'the measured speeds do not follow the commands (std {meas_std:.4f} m/s against '
            f'{cmd_std:.4f} m/s commanded): wrong encoder topic, joints or sprocket radius?')

    fixed_motor = {}
    if loop == 'pid_dc_motor':
        motor = _defaults_motor(base)
        fixed_motor = {'inertia': motor.inertia, 'damping': motor.damping,
                       'resistance': motor.resistance, 'inductance': motor.inductance,
                       'motor_constant': motor.motor_constant}
    problem = _Problem(segments, dt, max_lag, loop, fixed_motor)

    u_guess = 1.0 / max(_peak_accel(segments, dt), 1e-3)
    if loop == 'first_order':
        start_t = base.loop.time_constant if (
            base is not None and isinstance(base.loop, FirstOrderLag)) else None
        candidates = [np.array([tc, u]) for tc in ([start_t] if start_t else [])
                      + [0.02, 0.05, 0.1, 0.2, 0.5, 1.0] for u in (0.0, u_guess)]
        lower, upper = [1e-3, 0.0], [30.0, 100.0]
    elif loop == 'pid_dc_motor':
        gains = _defaults_motor(base)
        candidates = [np.array([gains.kp, gains.ki, gains.kd, u]) for u in (0.0, u_guess)]
        lower, upper = [0.0, 0.0, 0.0, 0.0], [np.inf, np.inf, np.inf, 100.0]
    else:
        candidates = [np.array([u]) for u in (0.0, u_guess, 0.3 * u_guess, 3.0 * u_guess)]
        lower, upper = [0.0], [100.0]

    # Starting point: the best candidate with its best delay.
    best = None
    for p in candidates:
        responses = problem.responses(p)
        if responses is None:
            continue
        sse = problem.lag_sse(responses)
        lag = int(np.argmin(sse))
        if best is None or sse[lag] < best[0]:
            best = (sse[lag], p, lag)
    if best is None:
        raise FitError('every starting point gives an unstable speed loop; check the motor '
                       'constants of the base file')
    _, p, lag = best
    fits = {}   # delay in samples -> least-squares solution at that delay

    def fit_at(lag, x0):
        if lag not in fits:
            try:
                fits[lag] = least_squares(problem.residuals, np.clip(x0, lower, upper),
                                          bounds=(lower, upper), args=(lag,), x_scale='jac',
                                          diff_step=1e-4)
            except ValueError as err:
                raise FitError(f'the least-squares fit failed: {err}') from None
        return fits[lag]

    # Alternate: fit the smooth parameters at a delay, then take the delay that scores best
    # with them, until a delay comes back.
    rounds = 0
    while rounds < max_rounds:
        rounds += 1
        p = fit_at(lag, p).x
        responses = problem.responses(p)
        if responses is None:
            raise FitError('the fit ended on an unstable speed loop')
        lag_next = int(np.argmin(problem.lag_sse(responses)))
        if lag_next in fits:
            break
        lag = lag_next
    # Delay and loop lag trade off, so alternation can stall one or two samples off: walk the
    # profile cost (the best fit at each delay) downhill from the best delay so far.
    lag = min(fits, key=lambda k: fits[k].cost)
    for step in (-1, 1):
        while 0 <= lag + step <= max_lag and \
                fit_at(lag + step, fits[lag].x).cost < fits[lag].cost:
            lag += step
    solution = fits[lag]
    p = solution.x
    if not (solution.success and np.all(np.isfinite(p))):
        raise FitError(f'the least-squares fit did not converge: {solution.message}')
    responses = problem.responses(p)
    if responses is None:
        raise FitError('the fit ended on an unstable speed loop')
    sse = problem.lag_sse(responses)
    if lag == max_lag and max_lag > 0:
        raise FitError(f'the best delay is at the search bound ({max_lag * dt:.3f} s): raise '
                       '--max-delay, or check that commands and speeds share a clock')

    residual = problem.residuals(p, lag)
    n = residual.size
    sse_total = float(residual @ residual)
    rms = math.sqrt(sse_total / n)
    centred = meas - meas.mean(axis=0)
    fit_percent = 100.0 * (1.0 - math.sqrt(sse_total / float(np.sum(centred ** 2))))
    rms_commands = float(np.sqrt(np.mean((cmd - meas) ** 2)))

    # Standard errors from the Jacobian of the final least-squares round.
    names = {'first_order': ['time_constant'], 'pid_dc_motor': ['kp', 'ki', 'kd'],
             'ideal': []}[loop]
    jac = solution.jac
    sigma2 = sse_total / max(n - len(p), 1)
    try:
        cov = sigma2 * np.linalg.pinv(jac.T @ jac)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(len(p), np.nan)

    drive = problem.drivetrain(p, delay=lag * dt)
    u = float(p[-1])
    shaped = [replace(drive, delay=0.0, loop=None).simulate(s.commands, dt,
                                                            initial=s.speeds[0])
              for s in segments]
    binding = 0.0
    if math.isfinite(drive.max_accel):
        step = drive.max_accel * dt
        hits = sum(int(np.count_nonzero(_rate_steps(y, step))) for y in shaped)
        binding = hits / sum(2 * (len(y) - 1) for y in shaped)
        if hits == 0:
            drive = replace(drive, max_accel=math.inf)
    max_command_accel = max(float(np.max(np.abs(np.diff(s.commands, axis=0)))) for s in
                            segments) / dt
    parameters = {'delay': lag * dt, 'max_accel': drive.max_accel}
    # The profile around the best delay, each neighbour with its own smooth parameters (the
    # walk fitted them), block by block: the jackknife then sees the trade-off with the lag.
    block = max(1, int(round(DELAY_BLOCK / dt)))
    blocks = None
    if 0 < lag < max_lag:
        columns = []
        for near in (lag - 1, lag, lag + 1):
            near_responses = problem.responses(fit_at(near, p).x)
            if near_responses is None:
                break
            columns.append(problem.lag_sse_blocks(near_responses, block, near))
        if len(columns) == 3:
            blocks = np.column_stack(columns)
    delay_std, how = _delay_std(blocks, lag, dt)
    errors = {'delay': delay_std,
              'max_accel': (float(std[-1]) / u ** 2 if u > 0 and math.isfinite(drive.max_accel)
                            else math.nan)}
    for i, name in enumerate(names):
        parameters[name] = float(p[i])
        errors[name] = float(std[i])
    profile = (np.arange(max_lag + 1) * dt, np.sqrt(sse / n))
    return DriveTrainFit(
        drivetrain=drive, loop=loop, parameters=parameters, standard_errors=errors,
        fixed=fixed_motor, rms=rms, rms_commands=rms_commands, fit_percent=fit_percent,
        accel_limit_binding=binding, max_command_accel=max_command_accel, dt=dt,
        samples=n // 2, seconds_of_data=n // 2 * dt, segments=segments, delay_profile=profile,
        rounds=rounds, delays_fitted=len(fits), delay_uncertainty=how,
        delay_at_zero=lag == 0 and max_lag > 0, nfev=problem.nfev,
        seconds=time.perf_counter() - started)
