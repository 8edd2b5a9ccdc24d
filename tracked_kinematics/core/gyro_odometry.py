"""
Gyro-aided odometry: heading from the robot's gyro, translation from the tracks' ICR model.

One streaming state machine, fed in time order with gyro samples (:meth:`GyroOdometry.imu`)
and cumulative track travel (:meth:`GyroOdometry.encoders`); odometry_node calls it per
message and evaluate_model replays a bag through the same calls (:func:`replay`).

Per encoder step ``[t0, t1]`` with scaled travel ``D_l, D_r`` (Martinez et al. 2005,
eqs. 20-21) and the ICR spread ``W = y_left - y_right`` in force:

- the model's heading increment ``dpsi_e = (D_r - D_l) / W`` (eq. 7);
- the gyro's, ``dpsi_g = (H(t1) - H(t0) - b (t1 - t0)) / gyro_scale``, with ``H`` the
  trapezoidal integral of the raw rates on the encoders' clock (stamps minus ``imu_delay``,
  identify_icr's convention: > 0 when the gyro is stamped late) and ``b`` the bias;
- their fusion, one scalar Kalman update of the heading increment:
  ``dpsi = dpsi_e + K (dpsi_g - dpsi_e)``, ``K = var_e / (var_e + var_g)`` with
  ``var_e = (model_yaw_rel_std dpsi_e)^2 + model_yaw_var_per_m d`` (``d`` the mean track
  distance of the step) and ``var_g = gyro_noise^2 dt + (scale_std dpsi_g)^2``: at
  standstill the model's variance is zero and the heading holds; in motion the gyro wins
  as far as its noise allows;
- the position along the exact arc of ``(dx, dy, dpsi)``, ``dx = (D_l + D_r) / 2 + c dpsi``,
  ``dy = -x dpsi`` (eqs. 8-9, ``c = (y_left + y_right) / 2``), as :mod:`.odometry`.

Trust comes from measured noise: the gyro's noise density is measured while the tracks
stand still (blocks of :data:`NOISE_BLOCK` s; ``gyro_noise`` until then), and so is its
bias, the mean raw rate (a running mean over the first ``bias_time`` s of standstill, then
exponential forgetting with that time constant). Per ``adapt_segment`` s of motion, a
recursive least squares with forgetting (``adapt_time``) regresses the gyro's heading on
the turn, ``dpsi_g = u (D_r - D_l) + b dt``: the turn gain ``u = 1 / W`` (the online
estimation of the EKF paper, docs/papers.md, driven by the gyro's yaw rate instead of
low-rate poses; bounded to ``0.2 <= chi <= 1``, applied to the model with ``adapt``) and,
while no standstill has measured the bias (:data:`STILL_KNOWN` s), a residual bias ``b``.
Until the bias is known (that standstill, or ``b`` to ``bias_std``) the heading is the
encoders': a gyro whose bias is unknown makes a good model worse (issue 29's Husky). The
ICR offset ``c`` and ``x``, which a gyro does not see, stay the model's.

Fallback: a sample that is not finite, saturated (``|w| >= saturation``) or jumps
(``|w - w_prev| > max_jump``), or no sample for ``timeout`` s, switches the heading to the
encoders at once (the heading continues from where it is: only increments are
integrated); the gyro is used again after ``recover_time`` s of healthy samples.
docs/nodes/odometry_node.md has the story and the measured figures.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
import math

import numpy as np

from ._checks import require_numbers
from .covariance import (arc_step, propagate, saturate, TrackNoise, travel_jacobian,
                         twist_covariance, TWIST_TIME, twist_variances)
from .kinematics import IcrParams
from .noise_model import NoiseModel, propagate_step, turn_slip, turn_slip_step

GYRO = 'gyro'
ENCODERS = 'encoders'

#: s, blocks of standstill over which the gyro's noise is measured.
NOISE_BLOCK = 0.5

#: s of standstill after which the bias counts as measured: the adaptation then looks for
#: no bias in motion.
STILL_KNOWN = 2.0

#: Smallest steering efficiency the adaptation goes to (the identification's bound).
MIN_CHI = 0.2

#: s: sums of step durations are compared with their thresholds this much early, so that
#: regular steps whose durations differ in the last bit (a node's ``ns * 1e-9`` against a
#: replay's ``t1 - t0``) cross them at the same step.
SUM_TOLERANCE = 1e-9


@dataclass(frozen=True, slots=True)
class GyroConfig:
    """
    How the gyro is read, trusted and checked.

    Attributes
    ----------
    imu_delay : float
        s, the gyro's stamps behind the encoders' (identify_icr's ``imu_delay``; about
        -0.17 s on the Warthog logs: the encoders trail the gyro).
    gyro_scale : float
        Measured rate over true rate (the simulator's ``GyroModel.scale``).
    gyro_bias : float
        rad/s, the bias before any standstill has been seen.
    gyro_noise : float
        rad/s/sqrt(Hz): white rate noise; heading variance ``gyro_noise^2`` per second.
        Used until 2 s of standstill have measured it (``measure_noise``).
    measure_noise : bool
        Measure the noise density at standstill and use it instead of ``gyro_noise``.
    scale_std : float
        Relative uncertainty of the gyro's scale (1 sigma).
    model_yaw_rel_std : float
        Relative error of the model's heading increments in turns (slip), 1 sigma.
    model_yaw_var_per_m : float
        rad^2 per metre travelled: the model's heading error on straights (veer).
    bias_time : float
        s, time constant of the standstill bias estimate.
    still_speed : float
        m/s, track speeds below which the tracks stand still.
    still_time : float
        s of standstill before the bias is learnt (the robot settles).
    timeout : float
        s without a gyro sample (beyond a positive ``imu_delay``) after which it is stale.
    saturation : float
        rad/s, readings at or beyond are saturated (inf: none).
    max_jump : float
        rad/s, largest change between consecutive samples that is plausible (inf: any).
    recover_time : float
        s of healthy samples before the gyro is used again.
    adapt : bool
        Adapt the ICR spread online.
    adapt_time : float
        s of turning over which the adaptation forgets (its memory).
    adapt_segment : float
        s, the gyro and the tracks are compared over segments this long.
    adapt_prior : float
        rad^2: weight of the model's spread at the start, as ``(D_r - D_l)^2`` summed.
    bias_prior : float
        s^2: weight of "no bias beyond the standstill's" in the adaptation, as ``dt^2``
        summed over segments.
    bias_std : float
        rad/s: a bias fitted in motion (no standstill yet) is known, and the gyro used,
        when its standard error is below this.

    """

    imu_delay: float = 0.0
    gyro_scale: float = 1.0
    gyro_bias: float = 0.0
    gyro_noise: float = 0.01
    measure_noise: bool = True
    scale_std: float = 0.01
    model_yaw_rel_std: float = 0.1
    model_yaw_var_per_m: float = 1e-4
    bias_time: float = 10.0
    still_speed: float = 0.005
    still_time: float = 0.3
    timeout: float = 0.5
    saturation: float = math.inf
    max_jump: float = math.inf
    recover_time: float = 0.5
    adapt: bool = False
    adapt_time: float = 60.0
    adapt_segment: float = 1.0
    adapt_prior: float = 1.0
    bias_prior: float = 0.1
    bias_std: float = 0.001

    def __post_init__(self):
        require_numbers(self, finite=('imu_delay', 'gyro_bias'),
                        positive=('gyro_scale', 'bias_time', 'bias_std', 'timeout', 'adapt_time',
                                  'adapt_segment', 'saturation', 'max_jump'),
                        non_negative=('gyro_noise', 'scale_std', 'model_yaw_rel_std',
                                      'model_yaw_var_per_m', 'still_speed', 'still_time',
                                      'recover_time', 'adapt_prior', 'bias_prior'),
                        unbounded=('saturation', 'max_jump'))
        for name in ('adapt', 'measure_noise'):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f'{name} must be a bool, got {getattr(self, name)!r}')


class GyroOdometry:
    """
    Dead reckoning with the heading from a gyro, the translation from the tracks.

    Parameters
    ----------
    icr : IcrParams
        The terrain's ICR model (ICRs and encoder scales).
    config : GyroConfig, optional
        How the gyro is read, trusted and checked; default ``GyroConfig()``.

    Attributes
    ----------
    pose : tuple of float
        ``(x, y, theta)``, m, m, rad (theta continuous).
    twist : tuple of float
        ``(v_x, v_y, w)`` of the last step, m/s, m/s, rad/s.
    source : str
        ``'gyro'`` or ``'encoders'``: where the heading of the last step came from.
    bias : float
        rad/s, the gyro bias in use.
    heading_variance : float
        rad^2, grown by each step's fused heading variance.
    reason : str
        Why the gyro is not used ('' when it is).
    switches : int
        Changes of source so far.
    covariance_upper : tuple of float
        Pose covariance ``(xx, xy, xt, yy, yt, tt)``, propagated per step (:meth:`set_noise`).
    twist_covariance : tuple of float
        Covariance of the twist the last :meth:`take_twist` returned, same layout.

    """

    def __init__(self, icr: IcrParams, config: GyroConfig | None = None,
                 noise: TrackNoise | None = None, terms: NoiseModel | None = None):
        self.config = config or GyroConfig()
        self.set_noise(noise, terms)
        self.set_model(icr)
        self.reset()
        self.source = ENCODERS
        self.reason = 'no gyro sample yet'
        self.switches = 0
        self._healthy = False        # the gyro's samples are in use (not the bias: source)
        self.bias = self.config.gyro_bias
        self._still_seen = 0.0       # s of standstill learnt from
        self._noise2 = 0.0           # measured rate noise density squared, rad^2/s
        self._block = [0.0, 0.0]     # standstill block: integral of the rate, duration
        self._blocks = 0
        self._still_for = 0.0        # s the tracks have stood still
        # Gyro integral on the encoders' clock: (t, raw heading) of healthy samples.
        self._buffer: deque = deque()
        self._last_rate = math.nan   # previous finite reading (jump check)
        self._last_t = -math.inf     # shifted time of the last healthy sample
        self._healthy_since = math.nan
        self._cursor = math.nan      # gyro heading consumed up to this time
        self._ahead = 0.0            # extrapolated heading not yet covered by samples
        self._enc = None             # (t, left, right) of the last encoder sample
        self.residual_bias = 0.0          # rad/s, the bias found in motion (no standstill)
        self._residual2 = 0.0             # mean squared residual of a segment, rad^2
        self._segments = 0
        self._bias_std = math.inf

    # Results ---------------------------------------------------------------------------

    @property
    def icr(self) -> IcrParams:
        """Return the ICR model in force: the adapted spread about the model's offset."""
        m = self.model
        half = 0.5 * self._spread
        return IcrParams(m.track_width, self._offset + half, self._offset - half, m.x,
                         m.scale_left, m.scale_right)

    @property
    def state(self) -> dict:
        """Return what a diagnostics message shows (plain numbers and strings)."""
        icr = self.icr
        return {'source': self.source, 'reason': self.reason, 'bias': self.bias,
                'switches': self.switches, 'gyro_noise': self.gyro_noise,
                'y_left': icr.y_left, 'y_right': icr.y_right,
                'chi': icr.chi, 'heading_variance': self.heading_variance}

    # Inputs ----------------------------------------------------------------------------

    def imu(self, t: float, wz: float) -> bool:
        """
        Take one gyro sample: stamp ``t`` (s, the IMU's clock) and z rate ``wz`` (rad/s).

        Returns
        -------
        bool
            Whether the sample was healthy (finite, unsaturated, no jump, in time order).

        """
        cfg = self.config
        ts = t - cfg.imu_delay
        previous = self._last_rate
        if math.isfinite(wz):
            self._last_rate = wz
        if not math.isfinite(ts) or not math.isfinite(wz):
            return self._unhealthy('the gyro reads a non-finite value')
        if abs(wz) >= cfg.saturation:
            return self._unhealthy('the gyro is saturated')
        if math.isfinite(previous) and abs(wz - previous) > cfg.max_jump:
            return self._unhealthy('the gyro jumps')
        buffer = self._buffer
        if buffer and ts <= buffer[-1][0]:
            return False  # out of order or repeated: ignored, not a fault
        if not buffer:
            buffer.append((ts, 0.0, wz))
        else:
            t0, h0, w0 = buffer[-1]
            if ts - t0 > cfg.timeout:
                # A gap: the integral across it is unknown; start again.
                self._unhealthy('the gyro was stale')
                buffer.append((ts, 0.0, wz))
            else:
                buffer.append((ts, h0 + 0.5 * (w0 + wz) * (ts - t0), wz))
        if not math.isfinite(self._healthy_since):
            self._healthy_since = ts
        self._last_t = ts
        return True

    def _unhealthy(self, reason: str) -> bool:
        self._healthy = False
        self._buffer.clear()
        self._healthy_since = math.nan
        self._last_t = -math.inf
        if self.source == GYRO:
            self.source = ENCODERS
            self.switches += 1
        self.reason = reason
        return False

    def encoders(self, t: float, left: float, right: float):
        """
        Take one encoder sample: time ``t`` (s) and cumulative nominal travel (m) of each track.

        Returns
        -------
        tuple or None
            ``(pose, twist)`` after the step; None for the first sample and a step refused
            (non-finite, or ``t`` not after the last sample).

        """
        if not (math.isfinite(t) and math.isfinite(left) and math.isfinite(right)):
            return None
        if self._enc is None:
            self._enc = (t, left, right)
            return None
        t0, l0, r0 = self._enc
        if t <= t0:
            return None
        self._enc = (t, left, right)
        if not self.update(t, left - l0, right - r0, t - t0):
            return None
        return self.pose, self.twist

    def update(self, t: float, d_left: float, d_right: float, dt: float) -> bool:
        """
        Integrate one step of nominal track travel ending at ``t``, as :meth:`.Odometry.update`.

        Parameters
        ----------
        t : float
            End of the step, s (the encoder message's stamp).
        d_left, d_right : float
            Nominal travel of each track over the step, m.
        dt : float
            Duration of the step, s (> 0).

        Returns
        -------
        bool
            False, with the state unchanged, for a non-finite input or ``dt <= 0``.

        """
        if not (math.isfinite(t) and math.isfinite(d_left) and math.isfinite(d_right)
                and math.isfinite(dt) and dt > 0.0):
            return False
        t0 = t - dt
        if not math.isfinite(self._cursor):
            self._cursor = t0
        return self._step(t0, t, d_left, d_right) is not None

    def take_twist(self):
        """
        Return the mean twist ``(v_x, v_y, w)`` since the last call; restart the window.

        Its covariance is then :attr:`twist_covariance`: that of the mean twist over
        :data:`.covariance.TWIST_TIME`, as :meth:`.Odometry.take_twist`, from the tracks' and
        the turn and slip terms, with ``w`` the gyro's (``gyro_noise^2 / TWIST_TIME`` plus the
        scale's uncertainty) when the heading is the gyro's.
        """
        dx, dy, dpsi, duration, abs_left, abs_right = self._window
        self._window = [0.0] * 6
        twist = (0.0, 0.0, 0.0) if duration <= 0.0 else (
            dx / duration, dy / duration, dpsi / duration)
        rate = 1.0 / duration if duration > 0.0 else 1.0
        var_left, var_right = twist_variances(self.noise, abs_left * rate, abs_right * rate)
        position, heading = turn_slip(self.terms, self.model.track_width,
                                      twist[0] * TWIST_TIME, twist[2] * TWIST_TIME)
        scale = 1.0 / (TWIST_TIME * TWIST_TIME)
        position *= scale
        if self.source == GYRO:
            m = self.model
            c, x = self._offset, m.x
            var_w = (self.gyro_noise ** 2 / TWIST_TIME
                     + (self.config.scale_std * twist[2]) ** 2)
            var_t = 0.25 * (m.scale_left ** 2 * var_left
                            + m.scale_right ** 2 * var_right) * scale
            covariance = (var_t + c * c * var_w + position, -c * x * var_w, c * var_w,
                          x * x * var_w + position, -x * var_w, var_w)
        else:
            xx, xy, xt, yy, yt, tt = twist_covariance(self._body, var_left, var_right,
                                                      TWIST_TIME)
            covariance = (xx + position, xy, xt, yy + position, yt, tt + heading * scale)
        # v_y is known to the floor's precision, never exactly (as Odometry's).
        xx, xy, xt, yy, yt, tt = covariance
        self.twist_covariance = (xx, xy, xt, yy + self.noise.floor * scale, yt, tt)
        return twist

    def reset(self) -> None:
        """Return the pose to zero, its covariance too; keep what was learnt of the gyro."""
        self.pose = (0.0, 0.0, 0.0)
        self.twist = (0.0, 0.0, 0.0)
        self.heading_variance = 0.0
        self.covariance_upper = (0.0,) * 6
        self.twist_covariance = (0.0,) * 6
        self._window = [0.0] * 6

    def set_noise(self, noise: TrackNoise | None = None,
                  terms: NoiseModel | None = None) -> None:
        """
        Use this noise for the covariances from the next step on.

        ``noise``: the tracks' random walk (default ``TrackNoise()``); ``terms``: the turn and
        slip terms of a :class:`.noise_model.NoiseModel` (default none), as :class:`.Odometry`.
        With the gyro in use the heading increments' variance is the fused one (the gyro's
        ``gyro_noise^2 dt`` plus its scale's, bounded by the model's), not the tracks'.
        """
        self.noise = noise if noise is not None else TrackNoise()
        self.terms = terms if terms is not None else NoiseModel(track=0.0, floor=0.0)

    def set_model(self, icr: IcrParams) -> None:
        """Use another terrain model from the next step on: the adaptation starts from it."""
        self.model = icr
        self._offset = 0.5 * (icr.y_left + icr.y_right)
        self._spread = icr.y_left - icr.y_right
        width = icr.track_width
        self._u_bounds = (1.0 / (width / MIN_CHI), 1.0 / width)
        self._u0 = 1.0 / self._spread
        self._update_body()
        self._info = [0.0, 0.0, 0.0]      # decaying information (uu, ub, bb)
        self._moment = [0.0, 0.0]         # decaying moments (u, b)
        self._segment = [0.0, 0.0, 0.0]   # turn (m), gyro heading (rad), duration (s)

    # The step --------------------------------------------------------------------------

    def _raw(self, tq: float):
        """Return the raw gyro integral at ``tq`` (linear between samples) or None."""
        buffer = self._buffer
        if not buffer or tq < buffer[0][0]:
            return None
        if tq >= buffer[-1][0]:
            tl, hl, wl = buffer[-1]
            return hl + wl * (tq - tl)
        lo, hi = 0, len(buffer) - 1
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if buffer[mid][0] <= tq:
                lo = mid
            else:
                hi = mid
        ta, ha, _ = buffer[lo]
        tb, hb, _ = buffer[hi]
        return ha + (hb - ha) * (tq - ta) / (tb - ta)

    def _gyro_increment(self, t0: float, t1: float):
        """Return the de-biased, scaled gyro heading over ``[t0, t1]`` (or None)."""
        cfg = self.config
        # Stale: the last sample is too old for this step.
        if t1 - self._last_t > cfg.timeout + max(cfg.imu_delay, 0.0):
            if self._healthy:
                self._unhealthy('the gyro is stale')
            return None
        if not self._healthy:
            if not (math.isfinite(self._healthy_since)
                    and self._last_t - self._healthy_since >= cfg.recover_time):
                return None
            start = self._raw(t0)
            if start is None:
                return None
            self._healthy = True
            self._cursor = t0
            self._ahead = 0.0
        a = self._raw(self._cursor)
        if a is None:
            return None
        covered = min(t1, self._last_t)
        b = self._raw(covered)
        tail = self._buffer[-1][2] * (t1 - covered)
        # The extrapolated tails telescope: the sum of the increments is the gyro's
        # integral up to the last sample plus the current tail, so each covers [t0, t1].
        raw = (b - a) + tail - self._ahead
        span = t1 - t0
        self._ahead = tail
        self._cursor = covered
        # Keep one sample before the cursor for the next interpolation.
        buffer = self._buffer
        while len(buffer) > 2 and buffer[1][0] <= covered:
            buffer.popleft()
        mean_raw = raw / span if span > 0 else 0.0
        return (raw - self.bias * span) / cfg.gyro_scale, mean_raw, span

    def _step(self, t0, t1, d_left, d_right):
        cfg = self.config
        m = self.model
        dt = t1 - t0
        big = abs(d_left) + abs(d_right)
        if not math.isfinite(big / dt):
            return None
        true_left = m.scale_left * d_left
        true_right = m.scale_right * d_right
        turn = true_right - true_left
        still = max(abs(d_left), abs(d_right)) < cfg.still_speed * dt
        self._still_for = self._still_for + dt if still else 0.0
        dpsi_e = turn / self._spread
        gyro = self._gyro_increment(t0, t1) if math.isfinite(self._cursor) else None
        if gyro is None:
            self._cursor = t1
            self._ahead = 0.0
        else:
            dpsi_g, mean_raw, span = gyro
            if still and self._still_for >= cfg.still_time - SUM_TOLERANCE:
                self._learn_bias(mean_raw, span)
            self._learn_slip(turn, dpsi_g, dt, still)
            dpsi_g -= self.residual_bias * dt
        source = GYRO if gyro is not None and self.bias_known else ENCODERS
        if source != self.source:
            self.switches += 1
            self.source = source
        if source == GYRO:
            self.reason = ''
            var_e = self._model_variance(dpsi_e, big)
            var_g = self.gyro_noise ** 2 * dt + (cfg.scale_std * dpsi_g) ** 2
            gain = var_e / (var_e + var_g) if var_e + var_g > 0.0 else 0.0
            dpsi = dpsi_e + gain * (dpsi_g - dpsi_e)
            var = (1.0 - gain) * var_e
        else:
            if gyro is not None:
                self.reason = 'the gyro bias is not known yet (stand still 2 s, or drive on)'
            dpsi, var = dpsi_e, self._model_variance(dpsi_e, big)
        dx = 0.5 * (true_left + true_right) + self._offset * dpsi
        dy = -m.x * dpsi
        x, y, theta = self.pose
        delta_x, delta_y, jacobian = arc_step(theta, dx, dy, dpsi)
        self.covariance_upper = self._propagate(source, d_left, d_right, dx, dpsi, var,
                                                delta_x, delta_y, jacobian)
        self.pose = (x + delta_x, y + delta_y, theta + dpsi)
        self.twist = (dx / dt, dy / dt, dpsi / dt)
        self.heading_variance += var
        window = self._window
        window[0] += dx
        window[1] += dy
        window[2] += dpsi
        window[3] += dt
        window[4] += abs(d_left)
        window[5] += abs(d_right)
        return self.pose, self.twist

    def _propagate(self, source, d_left, d_right, dx, dpsi, var, delta_x, delta_y, jacobian):
        """
        One step of the pose covariance (Kelly's linearised propagation, :mod:`.odometry`).

        From the encoders: the tracks' random walk through the model in force plus the turn
        and slip terms. From the gyro: the translation ``(D_l + D_r) / 2`` from the tracks,
        the heading increment's variance ``var`` (fused), through ``dx = T + c dpsi`` and
        ``dy = -x dpsi``, plus the slip term on the position.
        """
        var_left, var_right = self.noise.travel_variances(d_left, d_right)
        position, heading = turn_slip(self.terms, self.model.track_width, dx, dpsi)
        if source == GYRO:
            m = self.model
            c, x = self._offset, m.x
            var_t = 0.25 * (m.scale_left ** 2 * var_left + m.scale_right ** 2 * var_right)
            s = (var_t + c * c * var + position, -c * x * var, c * var,
                 x * x * var + position, -x * var, var)
            covariance = propagate_step(self.covariance_upper, delta_x, delta_y, jacobian, s)
        else:
            covariance = propagate(self.covariance_upper, delta_x, delta_y,
                                   travel_jacobian(jacobian, self._body), var_left, var_right)
            if position > 0.0 or heading > 0.0:
                covariance = turn_slip_step(covariance, position, heading, jacobian)
        return saturate(covariance)

    def _model_variance(self, dpsi_e, big):
        cfg = self.config
        return (cfg.model_yaw_rel_std * dpsi_e) ** 2 + cfg.model_yaw_var_per_m * 0.5 * big

    @property
    def gyro_noise(self) -> float:
        """Return the rate noise density in use, rad/s/sqrt(Hz): measured after 2 s still."""
        if (self.config.measure_noise and self._still_seen >= STILL_KNOWN - SUM_TOLERANCE
                and self._blocks):
            return math.sqrt(self._noise2)
        return self.config.gyro_noise

    def _learn_bias(self, mean_raw, span):
        self._still_seen += span
        weight = min(span / min(self._still_seen, self.config.bias_time), 1.0)
        self.bias += weight * (mean_raw - self.bias)
        self._restart_residual_bias()
        # The noise from blocks of NOISE_BLOCK s (a step's mean is not independent of the
        # next: the tail of a late gyro is extrapolated, then corrected): the mean of white
        # noise of density q over s seconds has the variance q^2 / s.
        block = self._block
        block[0] += mean_raw * span
        block[1] += span
        if block[1] >= NOISE_BLOCK - SUM_TOLERANCE:
            d = block[0] / block[1] - self.bias
            self._blocks += 1
            w = max(1.0 / self._blocks, block[1] / self.config.bias_time)
            self._noise2 += w * (d * d * block[1] - self._noise2)
            self._block = [0.0, 0.0]

    @property
    def bias_known(self) -> bool:
        """Whether the bias is known: from 2 s of standstill, or to ``bias_std`` in motion."""
        if self._still_seen >= STILL_KNOWN - SUM_TOLERANCE:
            return True
        return self._bias_std <= self.config.bias_std

    def _learn_slip(self, turn, dpsi_g, dt, still):
        """
        Regress the gyro's heading on the turn per segment: the turn gain, and the bias.

        ``dpsi_g = u (D_r - D_l) + b dt`` over segments of ``adapt_segment`` s in motion,
        recursive least squares with forgetting (``adapt_time``) and priors that do not
        decay (the model's ``u``, no residual bias). The bias is fitted only while no
        standstill has measured it.
        """
        cfg = self.config
        seg = self._segment
        if not still:
            seg[0] += turn
            seg[1] += dpsi_g
            seg[2] += dt
        if seg[2] < cfg.adapt_segment - SUM_TOLERANCE:
            return
        a, yv, duration = seg
        self._segment = [0.0, 0.0, 0.0]
        forget = math.exp(-duration / cfg.adapt_time)
        info, moment = self._info, self._moment
        info[0] = forget * info[0] + a * a
        info[1] = forget * info[1] + a * duration
        info[2] = forget * info[2] + duration * duration
        moment[0] = forget * moment[0] + a * yv
        moment[1] = forget * moment[1] + duration * yv
        i00 = info[0] + cfg.adapt_prior
        i01 = info[1]
        i11 = info[2] + cfg.bias_prior
        m0 = moment[0] + cfg.adapt_prior * self._u0
        m1 = moment[1]
        lo, hi = self._u_bounds
        if self._still_seen >= STILL_KNOWN - SUM_TOLERANCE:
            # The standstill measured the bias: the disagreement is slip alone.
            u = min(max(m0 / i00, lo), hi)
            b = 0.0
        else:
            det = i00 * i11 - i01 * i01
            u = min(max((i11 * m0 - i01 * m1) / det, lo), hi)
            b = (m1 - i01 * u) / i11
            residual = yv - u * a - b * duration
            self._segments += 1
            self._residual2 += (residual * residual - self._residual2) / min(self._segments,
                                                                             20)
            if self._segments >= 5:
                self._bias_std = math.sqrt(self._residual2 * i00 / det)
            self.residual_bias = b
        if cfg.adapt:
            self._spread = 1.0 / u
            self._update_body()

    def _update_body(self) -> None:
        """Body Jacobian of the model in force (the adapted spread), for the covariance."""
        m = self.model
        sl = m.scale_left / self._spread
        sr = m.scale_right / self._spread
        y_left = self._offset + 0.5 * self._spread
        y_right = self._offset - 0.5 * self._spread
        self._body = ((-y_right * sl, y_left * sr), (m.x * sl, -m.x * sr), (-sl, sr))

    def _restart_residual_bias(self):
        """Forget what the adaptation knew of the bias: a standstill measured it anew."""
        info, moment = self._info, self._moment
        info[1] = info[2] = 0.0
        moment[1] = 0.0
        self.residual_bias = 0.0
        self._bias_std = math.inf


def replay(enc_t, left, right, gyro_t, gyro_rate, icr: IcrParams,
           config: GyroConfig | None = None):
    """
    Replay a recording through :class:`GyroOdometry` as a node would receive it.

    Messages are taken in the order of their stamps (a gyro sample before an encoder sample
    of the same stamp).

    Parameters
    ----------
    enc_t, left, right : array_like, shape (N,)
        Encoder times, s, and cumulative nominal travel of each track, m.
    gyro_t, gyro_rate : array_like, shape (G,)
        Gyro stamps, s, and z rates, rad/s (may be empty: encoders only).
    icr : IcrParams
        The terrain's ICR model.
    config : GyroConfig, optional
        How the gyro is read; default ``GyroConfig()``.

    Returns
    -------
    poses : ndarray, shape (N, 3)
        Pose after each encoder sample (the first: zero).
    sources : ndarray of str, shape (N,)
        The source of each step's heading.
    odometry : GyroOdometry
        The state at the end.

    """
    enc_t = np.asarray(enc_t, float)
    gyro_t = np.asarray(gyro_t, float)
    events = np.concatenate([gyro_t, enc_t])
    order = np.argsort(events, kind='stable').tolist()
    n_gyro = len(gyro_t)
    odo = GyroOdometry(icr, config)
    poses = np.zeros((len(enc_t), 3))
    sources = np.full(len(enc_t), ENCODERS, dtype=object)
    gt, gr = gyro_t.tolist(), np.asarray(gyro_rate, float).tolist()
    et, el, er = enc_t.tolist(), np.asarray(left, float).tolist(), \
        np.asarray(right, float).tolist()
    for e in order:
        if e < n_gyro:
            odo.imu(gt[e], gr[e])
        else:
            k = e - n_gyro
            odo.encoders(et[k], el[k], er[k])
            poses[k] = odo.pose
            sources[k] = odo.source
    return poses, sources, odo


def fit_gyro_scale(gyro_t, gyro_rate, pose_t, pose_yaw, imu_delay: float = 0.0,
                   segment: float = 1.0) -> tuple[float, float]:
    """
    Fit the gyro's scale (measured over true rate) against a pose reference's heading.

    Over segments of ``segment`` s, the integrated raw rate is regressed on the reference's
    heading change with one bias per recording, ``dH = scale dpsi + b_r dt``; segments
    across a gap of either stream are left out, and those whose residual exceeds three
    robust standard deviations (pose glitches) dropped, twice.

    Parameters
    ----------
    gyro_t, gyro_rate : sequence of array_like
        Per recording: gyro stamps (s) and z rates (rad/s).
    pose_t, pose_yaw : sequence of array_like
        Per recording: reference stamps on the encoders' clock (its delay taken off), s,
        and yaw, rad.
    imu_delay : float
        s, the gyro's stamps behind the encoders.
    segment : float
        s.

    Returns
    -------
    scale, std : float
        The scale and its standard error; ``(1.0, inf)`` when the data cannot tell (fewer
        than ten segments). On the Warthog runs of ../shared/realdata the three runs give
        0.986-1.001 with standard errors of a few 0.001: a scale is worth applying only
        when it differs from 1 by several standard errors and more than the runs disagree.

    """
    rows, targets = [], []
    n = len(gyro_t)
    for r, (tg, wg, tp, yaw) in enumerate(zip(gyro_t, gyro_rate, pose_t, pose_yaw)):
        tg = np.asarray(tg, float) - imu_delay
        wg = np.asarray(wg, float)
        tp = np.asarray(tp, float)
        heading = np.unwrap(np.asarray(yaw, float))
        h = np.r_[0.0, np.cumsum(0.5 * (wg[1:] + wg[:-1]) * np.diff(tg))]
        lo, hi = max(tg[0], tp[0]), min(tg[-1], tp[-1])
        if hi - lo < 2 * segment:
            continue
        edges = lo + segment * np.arange(int((hi - lo) // segment) + 1)
        bad = np.zeros(len(edges) - 1, dtype=bool)
        for t in (tg, tp):
            steps = np.diff(t)
            gap = np.flatnonzero(steps > max(0.5, 5 * np.median(steps)))
            for g in gap:
                bad |= (edges[1:] > t[g]) & (edges[:-1] < t[g + 1])
        d_h = np.diff(np.interp(edges, tg, h))[~bad]
        d_psi = np.diff(np.interp(edges, tp, heading))[~bad]
        a = np.zeros((len(d_h), 1 + n))
        a[:, 0] = d_psi
        a[:, 1 + r] = segment
        rows.append(a)
        targets.append(d_h)
    if not rows or sum(len(t) for t in targets) < 10:
        return 1.0, math.inf
    a, y = np.vstack(rows), np.concatenate(targets)
    keep = np.ones(len(y), dtype=bool)
    for _ in range(3):
        p = np.linalg.lstsq(a[keep], y[keep], rcond=None)[0]
        residual = y - a @ p
        sigma = 1.4826 * np.median(np.abs(residual[keep] - np.median(residual[keep])))
        keep = np.abs(residual) <= 3.0 * max(sigma, 1e-9)
    if not (np.isfinite(p[0]) and p[0] > 0):
        return 1.0, math.inf
    a, residual = a[keep], residual[keep]
    dof = max(len(residual) - a.shape[1], 1)
    cov = np.linalg.pinv(a.T @ a) * float(residual @ residual) / dof
    return float(p[0]), float(np.sqrt(cov[0, 0]))
