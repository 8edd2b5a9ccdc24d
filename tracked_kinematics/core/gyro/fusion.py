"""
Gyro-aided odometry: heading from the robot's gyro, translation from the tracks' ICR model.

One streaming state machine, fed in any order with gyro samples (:meth:`GyroOdometry.imu`)
and steps of track travel (:meth:`GyroOdometry.step`), called as :class:`..odometry.Odometry`
is (odometry_node holds either). Per encoder step ``[t0, t1]`` with scaled travel ``D_l, D_r``
(Martinez et al. 2005, eqs. 20-21) and the ICR spread ``W = y_left - y_right`` in force:

- the model's heading increment ``dpsi_e = (D_r - D_l) / W`` (eq. 7);
- the gyro's, ``dpsi_g = (Y - b (t1 - t0)) / gyro_scale``, ``Y`` the integral of the rate
  over the step on the encoders' clock (:mod:`.samples`), ``b`` the bias (:mod:`.bias`);
- their fusion, one scalar Kalman update of the heading increment, ``dpsi = dpsi_e +
  K (dpsi_g - dpsi_e)``, ``K = var_e / (var_e + var_g)``, ``var_e = F ((model_yaw_rel_std
  dpsi_e)^2 + turn |dpsi_e| + model_yaw_var_per_m d)`` (``turn`` the terrain file's,
  ``F`` the variance factor the gyro measured, :mod:`.bias`) and ``var_g = (q^2 dt +
  s_b^2 dt T) / gyro_scale^2 + (scale_std dpsi_g)^2``: ``q`` the noise density, ``s_b``
  the bias's standard deviation, whose error is common to all steps of the horizon ``T``
  (``bias_horizon``);
- the position along the exact arc of ``(dx, dy, dpsi)``, ``dx = (D_l + D_r) / 2 + c dpsi``,
  ``dy = -x dpsi`` (eqs. 8-9, ``c = (y_left + y_right) / 2``), as :mod:`..odometry`.

The gyro is used only while its samples are healthy (:mod:`.samples`), it agrees with the
tracks (:mod:`.agreement`: refused, with an error, when it turns the other way, at another
scale, or on another clock) and its bias is known well enough
(:attr:`GyroOdometry.bias_known`: to ``bias_std``, or where its error over the horizon
weighs less than the tracks' measured heading error). The pose covariance
carries the bias's error through the steps (its cross-covariance with the pose).
docs/nodes/odometry_node.md has the story and the measured figures.
"""

from __future__ import annotations

import math

from .agreement import AgreementCheck, AGREES, PENDING, REFUSED
from .bias import TurnBias
from .gyro_config import (ENCODERS, ERROR, finite_square, GYRO, GyroConfig, OK,
                          SUM_TOLERANCE, time_limit, WARN)
from .pose_bias import PoseBiasCross
from .samples import BACK, GyroSamples, STALE
from ..covariance import (arc_step, propagate, saturate, TrackNoise, travel_jacobian,
                          twist_covariance, TWIST_TIME, twist_variances)
from ..kinematics import IcrParams
from ..noise_model import NoiseModel, propagate_step, turn_slip, turn_slip_step
from ..odometry import MAX_STEP_TRAVEL, Published

#: One unit of the slip term alone (:attr:`GyroOdometry.slip_share`).
UNIT_SLIP = NoiseModel(track=0.0, floor=0.0, slip=1.0)

#: Smallest steering efficiency the adaptation goes to (the identification's bound).
MIN_CHI = 0.2

#: rad/s: a segment whose mean gyro rate is beyond this teaches nothing (gates off).
IMPLAUSIBLE_RATE = 1e3

#: s: the agreement check compares the gyro and the tracks over segments this long.
CHECK_SEGMENT = 0.25

#: Normalised innovation squared beyond which a segment teaches the filter nothing.
OUTLIER_NIS = 25.0

#: s of encoder time the gyro's stamps must stay far from the encoders' to be refused.
CLOCK_TIME = 1.0

NOT_YET = 'no gyro sample yet'
CHECKING = 'checking the gyro against the tracks (used once they have turned together)'
NOT_KNOWN = 'the gyro bias is not known yet'
RESTARTS = 'the gyro restarts (a gap, or time went back)'
RECOVERS = 'the gyro recovers'
NOT_A_FAULT = (NOT_YET, CHECKING, NOT_KNOWN, RESTARTS)
"""Reasons the gyro is not used that are no fault (the level stays OK)."""


class GyroOdometry(Published):
    """
    Dead reckoning with the heading from a gyro, the translation from the tracks.

    Parameters
    ----------
    icr : IcrParams
        The terrain's ICR model (ICRs and encoder scales).
    config : GyroConfig, optional
        How the gyro is read, trusted and checked; default ``GyroConfig()``.
    noise, terms, gyro_terms : optional
        The covariance's track noise and turn/slip terms (:meth:`set_noise`).

    Attributes
    ----------
    pose : tuple of float
        ``(x, y, theta)``, m, m, rad (theta continuous).
    twist : tuple of float
        ``(v_x, v_y, w)`` of the last step, m/s, m/s, rad/s.
    source : str
        ``'gyro'`` or ``'encoders'``: where the heading of the last step came from.
    reason : str
        Why the gyro is not used ('' when it is).
    level : str
        ``'ok'``, ``'warn'`` (the gyro is unhealthy) or ``'error'`` (refused: it disagrees
        with the tracks or is on another clock).
    switches : int
        Changes of source so far.
    covariance_upper : tuple of float
        Pose covariance ``(xx, xy, xt, yy, yt, tt)`` since the last reset.

    """

    def __init__(self, icr: IcrParams, config: GyroConfig | None = None,
                 noise: TrackNoise | None = None, terms: NoiseModel | None = None,
                 gyro_terms: NoiseModel | None = None):
        self._config = config or GyroConfig()
        self.samples = GyroSamples(self._config)
        self._bias_share = PoseBiasCross()
        self.set_noise(noise, terms, gyro_terms)
        self.filter = None
        self.set_model(icr)
        self.reset()
        self.source = ENCODERS
        self.reason = NOT_YET
        self.level = OK
        self.switches = 0
        self._healthy = False        # the samples are integrated from the cursor on
        self._cursor = math.nan      # gyro heading consumed up to this time
        self._ahead = 0.0            # extrapolated heading not yet covered by samples
        self._enc = None             # (t, left, right) of the last encoder sample
        self._still_for = 0.0
        self._covered = (0.0, 0.0)
        self._far_since = math.nan
        self._clock = ''
        self._arrived = 0            # samples received by the last step
        # turn (m), s, gyro (rad), distance (m), forward (m, signed)
        self._segment = [0.0] * 5
        self._short = [0.0] * 5                # the same for the agreement check

    # Configuration ---------------------------------------------------------------------

    @property
    def config(self) -> GyroConfig:
        """How the gyro is read: a new one applies from the next sample or step."""
        return self._config

    @config.setter
    def config(self, config: GyroConfig) -> None:
        self._config = self.samples.config = self.filter.config = config

    def set_noise(self, noise: TrackNoise | None = None, terms: NoiseModel | None = None,
                  gyro_terms: NoiseModel | None = None) -> None:
        """
        Use this track noise (default ``TrackNoise()``) and turn/slip terms (none).

        ``gyro_terms``: the slip term while the heading is the gyro's (default ``terms``; the
        terrain file's ``covariance.gyro_aided.*``, fitted on gyro-aided windows).
        """
        self.noise = noise if noise is not None else TrackNoise()
        self.terms = terms if terms is not None else NoiseModel(track=0.0, floor=0.0)
        self.gyro_terms = gyro_terms if gyro_terms is not None else self.terms

    def timing_now(self) -> NoiseModel | None:
        """Return the terms published beside the steps: the gyro-aided ones from the gyro."""
        return self.gyro_timing if self.source == GYRO else self.timing

    def _terms_for(self, source: str) -> NoiseModel:
        """Return the turn and slip terms of a step whose heading came from ``source``."""
        return self.gyro_terms if source == GYRO else self.terms

    slip_share = None
    """
    With :meth:`track_slip_share`: the pose covariance (upper triangle) one unit of
    ``gyro_terms.slip`` adds since the reset, propagated through the same steps (the covariance
    is linear in it, and nothing else depends on it): a fit of the gyro-aided constants
    replays once (:func:`..evaluate.gyro_noise.gyro_windows`). None otherwise.
    """

    def track_slip_share(self) -> None:
        """Carry :attr:`slip_share` from now on (zero now and at each reset)."""
        self.slip_share = (0.0,) * 6

    def set_model(self, icr: IcrParams) -> None:
        """Use another terrain model from the next step on; keep the bias and the noise."""
        self.model = icr
        self._offset = 0.5 * (icr.y_left + icr.y_right)
        self._spread0 = icr.y_left - icr.y_right
        width = icr.track_width
        self._spread_bounds = (width, width / MIN_CHI)
        k0 = self._config.gyro_scale / self._spread0
        old = self.filter
        self.filter = TurnBias(k0, self._config)
        if old is not None:
            self.filter.set_bias(old.b, old.bias_var)
            self.filter.adopt_noise(old)
        self.check = AgreementCheck(k0, self._spread0 * MIN_CHI / width,
                                    self._spread0 / width)
        self._set_spread(self._spread0)

    def _set_spread(self, spread: float) -> None:
        self._spread = spread
        m = self.model
        sl = m.scale_left / spread
        sr = m.scale_right / spread
        y_left = self._offset + 0.5 * spread
        y_right = self._offset - 0.5 * spread
        self._body = ((-y_right * sl, y_left * sr), (m.x * sl, -m.x * sr), (-sl, sr))

    # Results ---------------------------------------------------------------------------

    @property
    def icr(self) -> IcrParams:
        """Return the ICR model in force: the adapted spread about the model's offset."""
        m = self.model
        half = 0.5 * self._spread
        return IcrParams(m.track_width, self._offset + half, self._offset - half, m.x,
                         m.scale_left, m.scale_right)

    @property
    def bias(self) -> float:
        """Return rad/s: the gyro bias in use."""
        return self.filter.b

    @property
    def bias_std(self) -> float:
        """Return rad/s: the bias's standard deviation."""
        return self.filter.bias_std

    @property
    def bias_known(self) -> bool:
        """
        Whether the bias is known well enough to use the gyro.

        To ``bias_std``, or to where its error over the horizon ``T`` (``bias_horizon``)
        weighs less than the tracks' in the fusion at the drive's typical step:
        ``s_b^2 T <= m``, ``m`` the model's heading variance per second the gyro measured
        (:attr:`.TurnBias.model_rate_var`). Where the tracks slip far more than configured
        (ice) a bias known to a few 0.01 rad/s still makes the gyro's heading the better one.
        """
        sb2 = self.filter.bias_var
        return (sb2 <= self._config.bias_std ** 2
                or sb2 * self._config.bias_horizon <= self.filter.model_rate_var)

    @property
    def gyro_noise(self) -> float:
        """Return the rate noise density in use, rad/s/sqrt(Hz)."""
        return self.filter.noise

    @property
    def heading_variance(self) -> float:
        """Return rad^2: the heading's variance since the last reset."""
        return self.covariance_upper[5]

    @property
    def state(self) -> dict:
        """Return what a diagnostics message shows (plain numbers and strings)."""
        icr = self.icr
        return {'source': self.source, 'reason': self.reason, 'level': self.level,
                'bias': self.bias, 'bias_std': self.bias_std, 'switches': self.switches,
                'gyro_noise': self.gyro_noise, 'agreement': self.check.verdict,
                'ratio': self.check.ratio, 'y_left': icr.y_left, 'y_right': icr.y_right,
                'chi': icr.chi, 'heading_variance': self.heading_variance}

    # Inputs ----------------------------------------------------------------------------

    def imu(self, t: float, wz: float) -> bool:
        """
        Take one gyro sample: stamp ``t`` (s, the IMU's clock) and yaw rate ``wz`` (rad/s).

        Returns
        -------
        bool
            Whether the sample was taken (plausible and in time order).

        """
        fault = self.samples.add(float(t), float(wz))
        if fault == 'order':
            return False
        if fault:
            self._healthy = False
            if fault not in (STALE, BACK):
                self._fault(fault)
                return False
        return True

    def _fault(self, reason: str) -> None:
        self._healthy = False
        if self.source == GYRO:
            self.source = ENCODERS
            self.switches += 1
        self.reason = reason
        self.level = WARN

    def encoders(self, t: float, left: float, right: float):
        """
        Take one encoder sample: time ``t`` (s) and cumulative nominal travel (m) of each track.

        Returns ``(pose, twist)`` after the step; None for the first sample, a refused step,
        and a stamp not after the last one (the next step starts from it; the pose is kept).
        """
        if not (math.isfinite(t) and math.isfinite(left) and math.isfinite(right)):
            return None
        previous, self._enc = self._enc, (t, left, right)
        if previous is None or t <= previous[0]:
            return None
        t0, l0, r0 = previous
        if not self.step(t, left - l0, right - r0, t - t0):
            return None
        return self.pose, self.twist

    def step(self, t: float, d_left: float, d_right: float, dt: float) -> bool:
        """
        Integrate one step of nominal track travel ending at ``t`` (s): as :meth:`.Odometry.step`.

        A step that starts before the last one ended (time went back) restarts the gyro's
        integral there; the pose is kept. Returns False, with the state unchanged, for a
        non-finite input, ``dt <= 0`` or a travel beyond :data:`..odometry.MAX_STEP_TRAVEL`.
        """
        t, d_left, d_right, dt = float(t), float(d_left), float(d_right), float(dt)
        if not (math.isfinite(t) and math.isfinite(d_left) and math.isfinite(d_right)
                and math.isfinite(dt) and dt > 0.0 and abs(d_left) <= MAX_STEP_TRAVEL
                and abs(d_right) <= MAX_STEP_TRAVEL and math.isfinite(d_left / dt)
                and math.isfinite(d_right / dt)):
            return False
        t0 = t - dt
        if not (math.isfinite(self._cursor) and t0 >= self._cursor - 1e-6):
            # The first step, or time went back: the gyro's integral starts here.
            self._cursor = t0
            self._healthy = False
            self._ahead = 0.0
        return self._step(t0, t, d_left, d_right)

    update = step
    """The former name of :meth:`step`."""

    # The step --------------------------------------------------------------------------

    def _check_clock(self, t1: float) -> bool:
        """
        Whether the gyro's stamps are on another clock (off ``t1`` for a while).

        Off: the newest sample (after ``imu_delay``) more than ``timeout`` behind ``t1`` (as
        stale) or ahead of it, beyond what ``imu_delay`` leaves, or beyond
        :func:`.time_limit`. For a while: :data:`CLOCK_TIME` of the gyro's own time, so
        that samples taken ahead of an encoder backlog (an executor busy) while it clears
        are no clock. Judged only on steps after which samples arrived: a gyro that went
        silent is stale, not on another clock.
        """
        arrived = self.samples.arrived
        fresh, self._arrived = arrived != self._arrived, arrived
        if not fresh:
            return bool(self._clock)
        cfg = self._config
        last = self.samples.last_t
        lead = last - t1
        far = math.isfinite(last) and (
            abs(lead) > time_limit(cfg) or lead > cfg.timeout + max(-cfg.imu_delay, 0.0)
            or -lead > cfg.timeout + max(cfg.imu_delay, 0.0))
        if not far:
            self._far_since = math.nan
            self._clock = ''
            return False
        if not math.isfinite(self._far_since) or last < self._far_since:
            self._far_since = last
        if last - self._far_since >= CLOCK_TIME:
            self._clock = (f"the gyro's stamps are {last - t1:+.3g} s from the encoders' "
                           "(another clock? use_sim_time, the IMU driver's time source, "
                           'imu_delay)')
        return bool(self._clock)

    def _gyro_increment(self, t0: float, t1: float):
        """Return the gyro's raw heading over ``[t0, t1]`` (rad), or None."""
        cfg = self._config
        samples = self.samples
        if self._check_clock(t1):
            self._healthy = False
            return None
        if t1 - samples.last_t > cfg.timeout + max(cfg.imu_delay, 0.0):
            if self._healthy or (math.isfinite(samples.last_t) and self.source == GYRO):
                self._fault('the gyro is stale')
                samples.clear()
            return None
        if not self._healthy:
            since = samples.healthy_since
            if not (math.isfinite(since)
                    and samples.last_t - since >= cfg.recover_time - SUM_TOLERANCE
                    and t0 >= samples.first_t):
                return None
            self._healthy = True
            self._cursor = t0
            self._ahead = 0.0
        if self._cursor < samples.first_t:
            self._healthy = False
            return None
        covered = max(min(t1, samples.last_t), self._cursor)
        tail = samples.last_rate * (t1 - covered)
        # The extrapolated tails telescope: the sum of the increments is the gyro's
        # integral up to the last sample plus the current tail, so each covers [t0, t1].
        # The samples alone (no tail) are kept for the standstill's noise and bias.
        inside = samples.integral(self._cursor, covered)
        self._covered = (inside, covered - self._cursor)
        raw = inside + tail - self._ahead
        self._ahead = tail
        self._cursor = covered
        samples.drop_before(covered)
        if not math.isfinite(raw):
            self._fault('the gyro reads a non-finite value')
            samples.clear()
            return None
        return raw

    def _learn(self, turn, dt, raw, still, dpsi_e, big, forward):
        """Feed the bias filter and the agreement check with a step the gyro covered."""
        cfg = self._config
        flt = self.filter
        flt.predict(dt, dpsi_e, forward)
        if still:
            self._close_segment()
            if self._still_for >= cfg.still_time - SUM_TOLERANCE:
                # The samples alone: a late gyro's extrapolated tail would add one
                # sample's noise to each block (twice the density on a 0.08-s delay).
                inside, span = self._covered
                if span > 0.0:
                    flt.still(turn * span / dt, span, inside)
            return
        if self._still_for > 0.0:
            flt.moving()
        for seg in (self._segment, self._short):
            seg[0] += turn
            seg[1] += dt
            seg[2] += raw
            seg[3] += 0.5 * big
            seg[4] += forward
        if self._short[1] >= CHECK_SEGMENT - SUM_TOLERANCE:
            self._close_short()
        if self._segment[1] >= cfg.adapt_segment - SUM_TOLERANCE:
            self._close_segment()

    def _segment_noise(self, a, d, distance):
        """Return the model's heading variance over a segment and the gyro's raw one."""
        cfg = self._config
        turned = a / self._spread0
        model_var = ((cfg.model_yaw_rel_std * turned) ** 2 + self.terms.turn * abs(turned)
                     + cfg.model_yaw_var_per_m * distance)
        return model_var, cfg.gyro_scale ** 2 * model_var + self.filter.noise ** 2 * d

    def _close_short(self) -> None:
        a, d, y, distance, _ = self._short
        self._short = [0.0] * 5
        if d <= 0.0 or not abs(y) <= IMPLAUSIBLE_RATE * d:
            return
        r = self._segment_noise(a, d, distance)[1]
        self.check.add(a, d, y, r, self.filter.b, self.filter.bias_var)

    def _close_segment(self) -> None:
        self._short = [0.0] * 5
        a, d, y, distance, forward = self._segment
        self._segment = [0.0] * 5
        if d <= 0.0 or not abs(y) <= IMPLAUSIBLE_RATE * d or self.check.verdict == REFUSED:
            return
        cfg = self._config
        model_var, r = self._segment_noise(a, d, distance)
        h = (a, d, forward)
        nu, s0 = self.filter.innovation(h, y)
        if nu * nu <= OUTLIER_NIS * (s0 + r * self.filter.nis):
            self.filter.motion(h, y, model_var)
        if cfg.adapt and self.check.verdict == AGREES:
            lo, hi = self._spread_bounds
            k = self.filter.k
            spread = cfg.gyro_scale / k if k > 0.0 else hi
            self._set_spread(min(max(spread, lo), hi))

    def _usable(self, raw) -> bool:
        """Whether the gyro's increment is used; sets the reason and the level."""
        if self._clock:
            self.reason, self.level = self._clock, ERROR
            return False
        verdict = self.check.verdict
        if verdict == REFUSED:
            self.reason, self.level = self.check.reason, ERROR
            return False
        if raw is None:
            if self.level == ERROR:
                self.reason, self.level = RECOVERS, WARN    # the refusal's cause is gone
            elif not self.reason or self.reason.startswith(NOT_A_FAULT):
                never = not math.isfinite(self.samples.last_t) and self.samples.refused == 0
                self.reason, self.level = (NOT_YET if never else RESTARTS), OK
            return False
        if not self.bias_known:
            self.reason = (f'{NOT_KNOWN} (+-{self.bias_std:.2g} rad/s: stand still 2 s, or '
                           'drive on and turn)')
            self.level = OK
            return False
        # Before the check has spoken, its steps are fused only where they agree with the
        # model's (_plausible): said in the reason, no fault.
        self.reason, self.level = (CHECKING if verdict == PENDING else ''), OK
        return True

    def _step(self, t0, t1, d_left, d_right) -> bool:
        cfg = self._config
        m = self.model
        dt = t1 - t0
        big = abs(d_left) + abs(d_right)
        true_left = m.scale_left * d_left
        true_right = m.scale_right * d_right
        turn = true_right - true_left
        still = max(abs(d_left), abs(d_right)) < cfg.still_speed * dt
        if not cfg.adapt and self._spread != self._spread0:
            self._set_spread(self._spread0)     # adapt_slip off: the file's ICRs again
        dpsi_e = turn / self._spread
        raw = self._gyro_increment(t0, t1)
        if raw is None:
            self._cursor = t1
            self._ahead = 0.0
            self._close_segment()
        else:
            self._learn(turn, dt, raw, still, dpsi_e, big, 0.5 * (true_left + true_right))
        self._still_for = self._still_for + dt if still else 0.0
        use = self._usable(raw)
        source = GYRO if use else ENCODERS
        if source != self.source:
            self.switches += 1
            self.source = source
        var_e = self._model_variance(dpsi_e, big)
        bias_gain = 0.0
        if use:
            scale = cfg.gyro_scale
            q2 = self.filter.noise ** 2
            sb2 = self.filter.bias_var
            dpsi_g = (raw - self.filter.b * dt) / scale
            white = q2 * dt / (scale * scale) + finite_square(cfg.scale_std * dpsi_g)
            var_g = white + sb2 * dt * cfg.bias_horizon / (scale * scale)
            gain = var_e / (var_e + var_g) if var_e + var_g > 0.0 else 0.0
            if self.check.verdict == PENDING and not self._plausible(dpsi_g, dpsi_e):
                gain = 0.0
            dpsi = dpsi_e + gain * (dpsi_g - dpsi_e) if gain > 0.0 else dpsi_e
            var = (1.0 - gain) ** 2 * var_e + (gain * gain * white if gain > 0.0 else 0.0)
            bias_gain = -gain * dt / scale
        else:
            dpsi, var = dpsi_e, var_e
        dx = 0.5 * (true_left + true_right) + self._offset * dpsi
        dy = -m.x * dpsi
        x, y, theta = self.pose
        delta_x, delta_y, jacobian = arc_step(theta, dx, dy, dpsi)
        covariance = self._propagate(source, d_left, d_right, dx, dpsi, var, delta_x,
                                     delta_y, jacobian, bias_gain)
        pose = (x + delta_x, y + delta_y, self._wrapped(theta + dpsi))
        if not all(map(math.isfinite, pose)):
            return False
        self.covariance_upper = covariance
        self.pose = pose
        self.twist = (dx / dt, dy / dt, dpsi / dt)
        self.steps += 1
        window = self._window
        window[0] += dx
        window[1] += dy
        window[2] += dpsi
        window[3] += dt
        window[4] += abs(d_left)
        window[5] += abs(d_right)
        return True

    def _propagate(self, source, d_left, d_right, dx, dpsi, var, delta_x, delta_y, jacobian,
                   bias_gain):
        """
        One step of the pose covariance (Kelly's linearised propagation, :mod:`..odometry`).

        From the encoders: the tracks' random walk through the model in force plus the turn
        and slip terms. From the gyro: the translation ``(D_l + D_r) / 2`` from the tracks,
        the heading increment's independent variance ``var`` through ``dx = T + c dpsi`` and
        ``dy = -x dpsi``, plus the slip term on the position; and the bias's error, common to
        all steps, through its cross-covariance with the pose (``bias_gain``: the heading
        increment's error per rad/s of bias error).
        """
        var_left, var_right = self.noise.travel_variances(d_left, d_right)
        position, heading = turn_slip(self._terms_for(source), self.model.track_width, dx,
                                      dpsi)
        c, x = self._offset, self.model.x
        if self.slip_share is not None:
            self._carry_slip_share(source, dx, dpsi, delta_x, delta_y, jacobian)
        if source == GYRO:
            m = self.model
            var_t = 0.25 * (m.scale_left ** 2 * var_left + m.scale_right ** 2 * var_right)
            s = (var_t + c * c * var + position, -c * x * var, c * var,
                 x * x * var + position, -x * var, var)
            covariance = propagate_step(self.covariance_upper, delta_x, delta_y, jacobian, s)
        else:
            covariance = propagate(self.covariance_upper, delta_x, delta_y,
                                   travel_jacobian(jacobian, self._body), var_left, var_right)
            if position > 0.0 or heading > 0.0:
                covariance = turn_slip_step(covariance, position, heading, jacobian)
        return saturate(self._bias_share.step(covariance, delta_x, delta_y, jacobian,
                                              bias_gain, (c, -x, 1.0), self.filter.bias_var))

    def _carry_slip_share(self, source, dx, dpsi, delta_x, delta_y, jacobian) -> None:
        """Propagate :attr:`slip_share` over a step as :meth:`_propagate` does the covariance."""
        # The encoders' steps carry the encoders' slip: there the share only moves.
        position = (turn_slip(UNIT_SLIP, self.model.track_width, dx, dpsi)[0]
                    if source == GYRO else 0.0)
        self.slip_share = propagate_step(self.slip_share, delta_x, delta_y, jacobian,
                                         (position, 0.0, 0.0, position, 0.0, 0.0))

    @staticmethod
    def _plausible(dpsi_g, dpsi_e) -> bool:
        """
        Whether a step's gyro increment may be fused before the agreement check has spoken.

        Within half the model's increment of it, and both turning (the check decides within
        about 0.1 rad of turning): a gyro that turns the other way, at another scale or not
        at all is not fused while the check gathers its evidence.
        """
        return abs(dpsi_g - dpsi_e) <= 0.5 * abs(dpsi_e)

    def _model_variance(self, dpsi_e, big):
        """
        Return the model's heading variance over a step: its slip, and what the gyro showed.

        ``model_yaw_rel_std`` of the increment, the terrain file's turn term (rad^2 per rad,
        :func:`..noise_model.turn_slip`) and the veer per metre, times the variance factor
        the gyro measured against them in motion (:attr:`.TurnBias.variance_factor`, at
        least 1), and, once the gyro agrees with the tracks, the turn gain it measured
        against the spread in force (``k W / gyro_scale - 1``: the model's systematic error
        when the slip is not adapted).
        """
        cfg = self._config
        factor = self.filter.variance_factor
        rel2 = factor * cfg.model_yaw_rel_std ** 2
        if self.check.verdict == AGREES:
            off = self.filter.k * self._spread / cfg.gyro_scale - 1.0
            rel2 += off * off
        return (rel2 * dpsi_e * dpsi_e + factor * (self.terms.turn * abs(dpsi_e)
                                                   + cfg.model_yaw_var_per_m * 0.5 * big))

    # Outputs ---------------------------------------------------------------------------

    def take_twist(self, covariance: bool = True):
        """
        Return the mean twist ``(v_x, v_y, w)`` since the last call and its covariance.

        As :meth:`.Odometry.take_twist`: the covariance is that of the mean twist over
        :data:`..covariance.TWIST_TIME`, from the tracks' and the turn and slip terms, with
        ``w`` the gyro's (its noise, its bias's and its scale's uncertainty) when the heading
        is the gyro's (``covariance`` False: None, and :attr:`twist_covariance` is still the
        last one computed). The window then restarts.
        """
        dx, dy, dpsi, duration, abs_left, abs_right = self._window
        self._window = [0.0] * 6
        twist = (0.0, 0.0, 0.0) if duration <= 0.0 else (
            dx / duration, dy / duration, dpsi / duration)
        if not covariance:
            return twist, None
        rate = 1.0 / duration if duration > 0.0 else 1.0
        var_left, var_right = twist_variances(self.noise, abs_left * rate, abs_right * rate)
        position, heading = turn_slip(self._terms_for(self.source), self.model.track_width,
                                      twist[0] * TWIST_TIME, twist[2] * TWIST_TIME)
        scale = 1.0 / (TWIST_TIME * TWIST_TIME)
        position *= scale
        if self.source == GYRO:
            m = self.model
            c, x = self._offset, m.x
            g = self._config.gyro_scale
            var_w = ((self.gyro_noise ** 2 / TWIST_TIME + self.filter.bias_var) / (g * g)
                     + finite_square(self._config.scale_std * twist[2]))
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
        return twist, self.twist_covariance

    def reset(self) -> None:
        """Return the pose to zero, its covariance too; keep what was learnt of the gyro."""
        self.twist = (0.0, 0.0, 0.0)
        self.twist_covariance = (0.0,) * 6
        self._bias_share.reset()
        self._window = [0.0] * 6
        if self.slip_share is not None:
            self.slip_share = (0.0,) * 6
        super().reset()
