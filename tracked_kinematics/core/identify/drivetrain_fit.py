"""
Identify the drive train (Fink & Stump sec. III-B) from commanded and measured track speeds.

Least squares on the simulated response (the paper's words; the procedure is ours): the delay by a
search over whole samples, the smooth parameters by ``least_squares``, alternated. Only three PID
gains are identifiable with the motor constants fixed. See docs/tools/identify_drivetrain.md, "How
it fits" and "What is identifiable".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
import math
import time

import numpy as np

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
    parameters, standard_errors : dict
        Fitted values by name (``delay`` s, ``max_accel`` m/s^2, ``time_constant`` s or
        ``kp, ki, kd``) and one-sigma errors (Jacobian, optimistic; the delay's as
        ``delay_uncertainty`` says).
    rms, rms_commands : float
        RMS error of the simulated speeds, and of the commands taken as speeds, m/s.
    fit_percent : float
        ``100 (1 - |error| / |speeds - mean|)``, as system identification tools report it.
    delay_profile : tuple of ndarray
        Candidate delays (s) and the RMS error of each, other parameters at their fit.
    delay_at_zero : bool
        The best delay is 0: the lag may absorb it, or the setpoints are stamped late.

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
    Return the best delay's standard error: a block jackknife plus the grid's half sample.

    ``blocks`` (K, 3) are each block's squared errors at ``lag - 1, lag, lag + 1``; each estimate
    is the parabola's minimum. None (delay at an end, unstable loop): the grid alone.
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
        A lag ``1 / (T s + 1)``; the PID gains of eq. (8) with ``base``'s (else Table II's)
        motor constants fixed; or none.
    dt : float, optional
        Grid period and delay resolution, s; default the median measured period in [2, 20] ms.
    max_delay, max_gap : float
        Largest delay searched and longest gap bridged, s.
    base : DriveTrain, optional
        Starting point and fixed motor constants.
    max_rounds : int
        Most delay / least-squares alternations before the profile walk.

    Raises
    ------
    ValueError
        Malformed inputs or options.
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
        dt = _grid_period(recordings)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f'dt must be a finite number > 0 s, got {dt!r}')
    max_lag = int(math.ceil(max_delay / dt - 1e-9))
    segments, cmd, meas = _excited_segments(recordings, dt, max_lag, max_delay, max_gap)
    fixed_motor = {}
    if loop == 'pid_dc_motor':
        motor = _defaults_motor(base)
        fixed_motor = {'inertia': motor.inertia, 'damping': motor.damping,
                       'resistance': motor.resistance, 'inductance': motor.inductance,
                       'motor_constant': motor.motor_constant}
    problem = _Problem(segments, dt, max_lag, loop, fixed_motor)
    candidates, lower, upper = _starting_points(loop, base, segments, dt)
    search = _DelaySearch(problem, lower, upper)
    lag, rounds = search.run(candidates, max_rounds)
    solution = search.fits[lag]
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
    centred = meas - meas.mean(axis=0)
    drive, binding = _acceleration_limit(problem.drivetrain(p, delay=lag * dt), segments, dt)
    parameters, errors, how = _estimates(problem, search, p, lag, drive, sse_total)
    return DriveTrainFit(
        drivetrain=drive, loop=loop, parameters=parameters, standard_errors=errors,
        fixed=fixed_motor, rms=math.sqrt(sse_total / n),
        rms_commands=float(np.sqrt(np.mean((cmd - meas) ** 2))),
        fit_percent=100.0 * (1.0 - math.sqrt(sse_total / float(np.sum(centred ** 2)))),
        accel_limit_binding=binding,
        max_command_accel=max(float(np.max(np.abs(np.diff(s.commands, axis=0))))
                              for s in segments) / dt,
        dt=dt, samples=n // 2, seconds_of_data=n // 2 * dt, segments=segments,
        delay_profile=(np.arange(max_lag + 1) * dt, np.sqrt(sse / n)),
        rounds=rounds, delays_fitted=len(search.fits), delay_uncertainty=how,
        delay_at_zero=lag == 0 and max_lag > 0, nfev=problem.nfev,
        seconds=time.perf_counter() - started)


def _grid_period(recordings) -> float:
    """Return the default grid: the median measured period, in [2, 20] ms, s."""
    times = [np.unique(np.asarray(r.track_speeds()[0], float)) for r in recordings]
    periods = [np.median(np.diff(t)) for t in times if len(t) > 1]
    # Rounded to the microsecond: stamps jitter, and the delay is a multiple of dt.
    return round(float(np.clip(min(periods), 0.002, 0.02)), 6) if periods else 0.01


def _excited_segments(recordings, dt, max_lag, max_delay, max_gap):
    """
    Return the resampled segments and their commands and speeds after the delay window.

    Raises ExcitationError for too little data, commands that hardly change, or speeds that
    do not follow them.
    """
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
    return segments, cmd, meas


def _starting_points(loop, base, segments, dt):
    """Return the candidate parameter vectors of ``loop`` and the bounds of the fit."""
    u_guess = 1.0 / max(_peak_accel(segments, dt), 1e-3)
    if loop == 'first_order':
        start_t = base.loop.time_constant if (
            base is not None and isinstance(base.loop, FirstOrderLag)) else None
        candidates = [np.array([tc, u]) for tc in ([start_t] if start_t else [])
                      + [0.02, 0.05, 0.1, 0.2, 0.5, 1.0] for u in (0.0, u_guess)]
        return candidates, [1e-3, 0.0], [30.0, 100.0]
    if loop == 'pid_dc_motor':
        gains = _defaults_motor(base)
        candidates = [np.array([gains.kp, gains.ki, gains.kd, u]) for u in (0.0, u_guess)]
        return candidates, [0.0, 0.0, 0.0, 0.0], [np.inf, np.inf, np.inf, 100.0]
    candidates = [np.array([u]) for u in (0.0, u_guess, 0.3 * u_guess, 3.0 * u_guess)]
    return candidates, [0.0], [100.0]


class _DelaySearch:
    """The least-squares fits at whole-sample delays, each done once (``fits``: lag -> fit)."""

    def __init__(self, problem, lower, upper):
        self.problem = problem
        self.lower, self.upper = lower, upper
        self.fits = {}

    def fit_at(self, lag, x0):
        """Return the least-squares fit of the smooth parameters at a delay of ``lag``."""
        if lag not in self.fits:
            from scipy.optimize import least_squares   # lazily, as every scipy of core
            try:
                self.fits[lag] = least_squares(
                    self.problem.residuals, np.clip(x0, self.lower, self.upper),
                    bounds=(self.lower, self.upper), args=(lag,), x_scale='jac',
                    diff_step=1e-4)
            except ValueError as err:
                raise FitError(f'the least-squares fit failed: {err}') from None
        return self.fits[lag]

    def run(self, candidates, max_rounds):
        """Return the best delay (samples) and the rounds of alternation it took."""
        problem = self.problem
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
        # Alternate: fit the smooth parameters at a delay, then take the delay that scores
        # best with them, until a delay comes back.
        rounds = 0
        while rounds < max_rounds:
            rounds += 1
            p = self.fit_at(lag, p).x
            responses = problem.responses(p)
            if responses is None:
                raise FitError('the fit ended on an unstable speed loop')
            lag_next = int(np.argmin(problem.lag_sse(responses)))
            if lag_next in self.fits:
                break
            lag = lag_next
        # Delay and loop lag trade off, so alternation can stall one or two samples off: walk
        # the profile cost (the best fit at each delay) downhill from the best delay so far.
        fits = self.fits
        lag = min(fits, key=lambda k: fits[k].cost)
        for step in (-1, 1):
            while 0 <= lag + step <= problem.max_lag and \
                    self.fit_at(lag + step, fits[lag].x).cost < fits[lag].cost:
                lag += step
        return lag, rounds


def _acceleration_limit(drive: DriveTrain, segments, dt: float):
    """Return the model without a limit that never binds, and the share of steps it shapes."""
    if not math.isfinite(drive.max_accel):
        return drive, 0.0
    shaped = [replace(drive, delay=0.0, loop=None).simulate(s.commands, dt,
                                                            initial=s.speeds[0])
              for s in segments]
    step = drive.max_accel * dt
    hits = sum(int(np.count_nonzero(_rate_steps(y, step))) for y in shaped)
    binding = hits / sum(2 * (len(y) - 1) for y in shaped)
    return (replace(drive, max_accel=math.inf) if hits == 0 else drive), binding


def _estimates(problem, search, p, lag, drive, sse_total):
    """Return the fitted parameters, their standard errors, and how the delay's was found."""
    solution = search.fits[lag]
    dt, max_lag = problem.dt, problem.max_lag
    # Standard errors from the Jacobian of the final least-squares round.
    names = {'first_order': ['time_constant'], 'pid_dc_motor': ['kp', 'ki', 'kd'],
             'ideal': []}[problem.loop]
    jac = solution.jac
    sigma2 = sse_total / max(jac.shape[0] - len(p), 1)
    try:
        cov = sigma2 * np.linalg.pinv(jac.T @ jac)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(len(p), np.nan)
    u = float(p[-1])
    parameters = {'delay': lag * dt, 'max_accel': drive.max_accel}
    # The profile around the best delay, each neighbour with its own smooth parameters (the
    # walk fitted them), block by block: the jackknife then sees the trade-off with the lag.
    block = max(1, int(round(DELAY_BLOCK / dt)))
    blocks = None
    if 0 < lag < max_lag:
        columns = []
        for near in (lag - 1, lag, lag + 1):
            near_responses = problem.responses(search.fit_at(near, p).x)
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
    return parameters, errors, how
