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

The bias is the mean raw rate while the tracks stand still (a running mean over the first
``bias_time`` s of standstill, then exponential forgetting with that time constant). The
spread adapts online (``adapt``): recursive least squares with forgetting, per
``adapt_segment`` s of turning, of the turn gain ``u = 1 / W`` in
``dpsi_g = u (D_r - D_l)``: the online estimation of the EKF paper (Pentzer et al. 2014)
with the gyro's yaw rate as the measurement instead of poses, bounded to ``0.2 <= chi <= 1``;
the ICR offset ``c`` and ``x``, which a gyro does not see, stay the model's.

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
from .covariance import arc_step
from .kinematics import IcrParams

GYRO = 'gyro'
ENCODERS = 'encoders'

#: Smallest steering efficiency the adaptation goes to (the identification's bound).
MIN_CHI = 0.2


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
    min_turn : float
        m, smallest ``|D_r - D_l|`` of a segment the adaptation learns from.

    """

    imu_delay: float = 0.0
    gyro_scale: float = 1.0
    gyro_bias: float = 0.0
    gyro_noise: float = 0.01
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
    min_turn: float = 0.05

    def __post_init__(self):
        require_numbers(self, finite=('imu_delay', 'gyro_bias'),
                        positive=('gyro_scale', 'bias_time', 'timeout', 'adapt_time',
                                  'adapt_segment', 'saturation', 'max_jump'),
                        non_negative=('gyro_noise', 'scale_std', 'model_yaw_rel_std',
                                      'model_yaw_var_per_m', 'still_speed', 'still_time',
                                      'recover_time', 'adapt_prior', 'min_turn'),
                        unbounded=('saturation', 'max_jump'))
        if not isinstance(self.adapt, bool):
            raise ValueError(f'adapt must be a bool, got {self.adapt!r}')


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

    """

    def __init__(self, icr: IcrParams, config: GyroConfig | None = None):
        self.config = config or GyroConfig()
        self.model = icr
        self._offset = 0.5 * (icr.y_left + icr.y_right)
        self._spread = icr.y_left - icr.y_right
        self.pose = (0.0, 0.0, 0.0)
        self.twist = (0.0, 0.0, 0.0)
        self.heading_variance = 0.0
        self.source = ENCODERS
        self.reason = 'no gyro sample yet'
        self.switches = 0
        self.bias = self.config.gyro_bias
        self._still_seen = 0.0       # s of standstill learnt from
        self._still_for = 0.0        # s the tracks have stood still
        # Gyro integral on the encoders' clock: (t, raw heading) of healthy samples.
        self._buffer: deque = deque()
        self._last_rate = math.nan   # previous finite reading (jump check)
        self._last_t = -math.inf     # shifted time of the last healthy sample
        self._healthy_since = math.nan
        self._cursor = math.nan      # gyro heading consumed up to this time
        self._ahead = 0.0            # extrapolated heading not yet covered by samples
        self._enc = None             # (t, left, right) of the last encoder sample
        # Adaptation: information-form RLS of u = 1 / W.
        width = icr.track_width
        self._u_bounds = (1.0 / (width / MIN_CHI), 1.0 / width)
        self._info = self.config.adapt_prior
        self._moment = self.config.adapt_prior / self._spread
        self._segment = [0.0, 0.0, 0.0]  # turn (m), gyro heading (rad), duration (s)

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
                'switches': self.switches, 'y_left': icr.y_left, 'y_right': icr.y_right,
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
            self._cursor = t
            return None
        t0, l0, r0 = self._enc
        dt = t - t0
        if dt <= 0.0:
            return None
        self._enc = (t, left, right)
        return self._step(t0, t, left - l0, right - r0)

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
            if self.source == GYRO:
                self._unhealthy('the gyro is stale')
            return None
        if self.source != GYRO:
            if not (math.isfinite(self._healthy_since)
                    and self._last_t - self._healthy_since >= cfg.recover_time):
                return None
            start = self._raw(t0)
            if start is None:
                return None
            self.source = GYRO
            self.reason = ''
            self.switches += 1
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
            dpsi, var = dpsi_e, self._model_variance(dpsi_e, big)
        else:
            dpsi_g, mean_raw, span = gyro
            if still and self._still_for >= cfg.still_time:
                self._learn_bias(mean_raw, span)
            var_e = self._model_variance(dpsi_e, big)
            var_g = cfg.gyro_noise ** 2 * dt + (cfg.scale_std * dpsi_g) ** 2
            gain = var_e / (var_e + var_g) if var_e + var_g > 0.0 else 0.0
            dpsi = dpsi_e + gain * (dpsi_g - dpsi_e)
            var = (1.0 - gain) * var_e
            if cfg.adapt:
                self._adapt(turn, dpsi_g, dt)
        dx = 0.5 * (true_left + true_right) + self._offset * dpsi
        dy = -m.x * dpsi
        x, y, theta = self.pose
        delta_x, delta_y, _ = arc_step(theta, dx, dy, dpsi)
        self.pose = (x + delta_x, y + delta_y, theta + dpsi)
        self.twist = (dx / dt, dy / dt, dpsi / dt)
        self.heading_variance += var
        return self.pose, self.twist

    def _model_variance(self, dpsi_e, big):
        cfg = self.config
        return (cfg.model_yaw_rel_std * dpsi_e) ** 2 + cfg.model_yaw_var_per_m * 0.5 * big

    def _learn_bias(self, mean_raw, span):
        self._still_seen += span
        weight = span / min(self._still_seen, self.config.bias_time)
        self.bias += min(weight, 1.0) * (mean_raw - self.bias)

    def _adapt(self, turn, dpsi_g, dt):
        cfg = self.config
        seg = self._segment
        seg[0] += turn
        seg[1] += dpsi_g
        seg[2] += dt
        if seg[2] < cfg.adapt_segment:
            return
        a, yv, duration = seg
        self._segment = [0.0, 0.0, 0.0]
        if abs(a) < cfg.min_turn:
            return
        forget = math.exp(-duration / cfg.adapt_time)
        self._info = forget * self._info + a * a
        self._moment = forget * self._moment + a * yv
        lo, hi = self._u_bounds
        u = min(max(self._moment / self._info, lo), hi)
        self._spread = 1.0 / u


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
                   segment: float = 1.0) -> float:
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
    float
        The scale; 1.0 when the data cannot tell (fewer than ten segments).

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
        return 1.0
    a, y = np.vstack(rows), np.concatenate(targets)
    keep = np.ones(len(y), dtype=bool)
    for _ in range(3):
        p = np.linalg.lstsq(a[keep], y[keep], rcond=None)[0]
        residual = y - a @ p
        sigma = 1.4826 * np.median(np.abs(residual[keep] - np.median(residual[keep])))
        keep = np.abs(residual) <= 3.0 * max(sigma, 1e-9)
    return float(p[0]) if np.isfinite(p[0]) and p[0] > 0 else 1.0
