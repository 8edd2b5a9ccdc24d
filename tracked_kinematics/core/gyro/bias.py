"""
The gyro's bias and turn gain against the tracks, and its noise density: one small filter.

The gyro's raw heading over a stretch of ``d`` seconds in which the tracks turn by ``a``
metres (``a = D_r - D_l``, scaled travel) is, to the model's slip error and the gyro's noise,

    ``y = k a + b d + v s``,  ``k = gyro_scale / (y_left - y_right)``  (Martinez et al. 2005,
    eq. 7)

with ``b`` the bias (rad/s) and ``v`` the heading per metre ``s`` driven that the tracks miss
(a scale mismatch of the two sides: true motion, which the gyro sees; without it a veer on
straights passes for a bias), a first-order Gauss-Markov process about zero (spread
:data:`VEER_PRIOR`, memory :data:`VEER_MEMORY` metres): at a constant speed ``d`` and ``s``
are collinear and only that prior splits their sum. :class:`TurnBias` is a Kalman filter
of ``(k, b, v)``: a prior on ``k`` from the terrain file (``adapt_prior``, relative) and
on ``b`` (``gyro_bias`` with ``gyro_bias_sigma``, or none), segments of motion and blocks
of standstill as observations.
So the bias is estimated in motion as well as at standstill, with its uncertainty; where
``a`` and ``d`` are collinear (a drive on one-sided curvature from the start) the two stay
correlated and ``b``'s variance large: the bias is not called known. ``k`` forgets per
radian turned (``adapt_turn``), ``b`` drifts as a random walk (``bias_time``). The segments'
noise is the model's expected heading error (the configured one and the terrain file's turn
term) times the variance factor their residuals measure; when the factor grows, what the
earlier segments taught is scaled with it (:meth:`TurnBias.variance_factor`): a terrain that
slips far more than expected (ice) leaves the bias as uncertain as it is, not decided by
the first few segments.

A standstill teaches only what agrees with zero motion: its blocks are checked, cumulated
since the last checkpoint, against the prediction before them (the encoders' creep enters
through ``a``), and each block against the standstill's blocks of the :data:`CHECKPOINT`
seconds before it (which needs no prior); a standstill whose mean rate disagrees beyond three
standard deviations (a turntable, a push) is undone and learns nothing: back to its last
checkpoint, or to its start where the bias was too little known there to tell which of its
rates is the bias. The noise density is measured from the differences of consecutive blocks,
which no bias enters (a block's spread about a mean that
includes it is biased low: 0.70x on four blocks).
"""

from __future__ import annotations

import math

import numpy as np

from .gyro_config import GyroConfig, SUM_TOLERANCE

#: s, blocks of standstill over which the gyro is observed and its noise measured.
NOISE_BLOCK = 0.5

#: s of consistent standstill after which what it taught is kept (a checkpoint).
CHECKPOINT = 5.0

#: rad/s: the bias's standard deviation without any prior (unknown).
BIAS_UNKNOWN = 0.5

#: Blocks before the measured noise density replaces the configured one.
NOISE_BLOCKS = 4

#: rad/m: the prior standard deviation of the model's veer (heading per metre on straights).
VEER_PRIOR = 0.02

#: m driven over which the veer may change by its prior.
VEER_MEMORY = 500.0

#: rad/s: a change of the bias a standstill may show without being called a rotation (a
#: MEMS gyro's bias moves by a few 0.001 rad/s within seconds: 0.003 on the Warthog's); a
#: turntable or a push turns faster.
BIAS_STEP = 0.005

#: Segments over which the normalised innovations are averaged, and their smallest mean.
NIS_MEMORY = 50
NIS_PRIOR = 10
MIN_NIS = 0.1

#: Standard deviations beyond which a standstill is not one (it turns).
STILL_GATE = 3.0


class TurnBias:
    """
    Kalman filter of the gyro's turn gain ``k``, bias ``b`` and the model's veer ``v``.

    The observation of a stretch is ``y = k a + b d + v s`` (module docstring), ``s`` the
    distance driven (m, signed): ``v`` (rad/m) is the heading the tracks miss on straights
    (a scale mismatch of the two sides), which the gyro sees and which is not its bias.

    Parameters
    ----------
    k0 : float
        rad/m, the terrain file's ``gyro_scale / (y_left - y_right)``.
    config : GyroConfig

    Attributes
    ----------
    x : ndarray, shape (3,)
        ``(k, b, v)``.
    p : ndarray, shape (3, 3)
        Their covariance.
    turned : float
        rad turned (as the model says) since the start.

    """

    def __init__(self, k0: float, config: GyroConfig):
        self.config = config
        self.k0 = k0
        sigma_b = config.gyro_bias_sigma if config.gyro_bias_sigma > 0.0 else BIAS_UNKNOWN
        self._prior_kk = (config.adapt_prior * k0) ** 2
        self._prior_bb = sigma_b * sigma_b
        self.x = np.array([k0, config.gyro_bias, 0.0])
        self.p = np.diag([self._prior_kk, sigma_b * sigma_b, VEER_PRIOR ** 2])
        self.turned = 0.0
        self._nis = 1.0
        self._model_rate = None
        self._segments = 0
        self._noise2 = 0.0
        self._blocks = 0
        self.still_refused = False
        self._still_reset()
        self._checkpoint = None
        self._start = None

    # Results ---------------------------------------------------------------------------

    @property
    def k(self) -> float:
        """Return rad/m: the gyro's heading per metre of turn of the tracks."""
        return float(self.x[0])

    @property
    def b(self) -> float:
        """Return rad/s: the bias."""
        return float(self.x[1])

    @property
    def bias_var(self) -> float:
        """Return rad^2/s^2: the variance of the bias."""
        return max(float(self.p[1, 1]), 0.0)

    @property
    def bias_std(self) -> float:
        """Return rad/s: the standard deviation of the bias."""
        return math.sqrt(self.bias_var)

    def set_bias(self, b: float, var: float) -> None:
        """Take a bias known elsewhere (another filter's), uncorrelated with the rest."""
        self.x[1] = b
        self.p[1, :] = 0.0
        self.p[:, 1] = 0.0
        self.p[1, 1] = var

    @property
    def noise(self) -> float:
        """Return rad/s/sqrt(Hz): the measured noise density, or the configured one."""
        if self.config.measure_noise and self._blocks >= NOISE_BLOCKS:
            return math.sqrt(self._noise2)
        return self.config.gyro_noise

    @property
    def nis(self) -> float:
        """Return the running mean of the normalised innovations in motion."""
        return self._nis

    def adopt_noise(self, other: TurnBias) -> None:
        """Take the noise density another filter measured."""
        self._noise2, self._blocks = other._noise2, other._blocks

    # The filter ------------------------------------------------------------------------

    def predict(self, dt: float, turned: float, distance: float) -> None:
        """Let ``dt`` s pass in which the model turned ``turned`` rad and drove ``distance`` m."""
        q = self.noise
        p = self.p
        p[1, 1] = min(p[1, 1] + q * q * dt / (self.config.bias_time ** 2), BIAS_UNKNOWN ** 2)
        # The veer: a first-order Gauss-Markov process about zero (memory VEER_MEMORY
        # metres, stationary spread VEER_PRIOR), not a random walk: where the duration and
        # the distance are collinear (a constant speed) nothing else keeps it, and the
        # bias, near zero.
        fade = math.exp(-abs(distance) / VEER_MEMORY)
        self.x[2] *= fade
        p[2, :] *= fade
        p[:, 2] *= fade
        p[2, 2] += (1.0 - fade * fade) * VEER_PRIOR ** 2
        grow = math.exp(min(abs(turned) / self.config.adapt_turn, 50.0))
        if grow > 1.0 and p[0, 0] > 0.0:
            kk = min(p[0, 0] * grow, max(self._prior_kk, p[0, 0]))
            f = math.sqrt(kk / p[0, 0])
            p[0, :] *= f
            p[:, 0] *= f
        self.turned += abs(turned)

    def innovation(self, h, y: float) -> tuple[float, float]:
        """Return the innovation of ``y = h . (k, b, v)`` and its variance without noise."""
        h = np.asarray(h, float)
        return y - float(h @ self.x), float(h @ self.p @ h)

    def update(self, h, y: float, r: float) -> float:
        """Observe ``y = h . (k, b, v)`` with noise variance ``r``; return the NIS."""
        h = np.asarray(h, float)
        nu, s0 = self.innovation(h, y)
        s = s0 + r
        if not (s > 0.0 and math.isfinite(s) and math.isfinite(nu)):
            return 0.0
        ph = self.p @ h
        gain = ph / s
        self.x = self.x + gain * nu
        p = self.p - np.outer(gain, ph)
        self.p = 0.5 * (p + p.T)
        return nu * nu / s

    def motion(self, h, y: float, model_var: float) -> None:
        """
        Observe a segment of motion: ``model_var`` rad^2, the model's heading variance over it.

        The noise is the model's and the gyro's, scaled by the running mean of the normalised
        innovations (:data:`NIS_MEMORY` segments, at least :data:`MIN_NIS`): the filter's
        variances stay honest when the file's slip error is too small, or too large.
        """
        scale = self.config.gyro_scale
        q = self.noise
        r = (scale * scale * model_var + q * q * h[1]) * self._nis
        nis = self.update(h, y, r) * self._nis
        # The mean, with NIS_PRIOR segments of 1 before the first (a few lucky segments
        # must not make the filter overconfident), forgetting beyond NIS_MEMORY.
        self._segments += 1
        weight = 1.0 / min(self._segments + NIS_PRIOR, NIS_MEMORY)
        before = self.variance_factor
        self._nis = max(MIN_NIS, self._nis + weight * (nis - self._nis))
        self._rescale(self.variance_factor / before)
        if h[1] > 0.0:
            self._model_rate = (model_var / h[1] if self._model_rate is None else
                                self._model_rate + weight * (model_var / h[1]
                                                             - self._model_rate))

    @property
    def model_rate_var(self) -> float:
        """
        Return rad^2/s: the model's heading variance per second of motion, as the gyro saw it.

        The running mean of the segments' expected model variance per second (the same
        memory as the variance factor), times :attr:`variance_factor`; 0 before a segment.
        """
        return 0.0 if self._model_rate is None else self._model_rate * self.variance_factor

    @property
    def variance_factor(self) -> float:
        """
        Return the segments' residual variance over the configured one, at least 1.

        The a posteriori variance factor of the motion's weighted regression (the residuals'
        variance per unit weight, which scales the estimate's covariance, as scipy's
        ``curve_fit`` does without ``absolute_sigma``), from the running mean of the
        normalised innovations: the tracks' heading error as the gyro sees it, relative to
        the one expected (``model_yaw_rel_std``, ``model_yaw_var_per_m`` and the terrain
        file's turn term).
        """
        return max(1.0, self._nis)

    def _rescale(self, factor: float) -> None:
        """
        Scale the turn gain's and the bias's covariance by ``factor``, at most to their priors.

        The segments were taken with the variance factor of their time: when it grows, what
        they taught is known less (and the next segments weigh as much as the earlier ones,
        instead of the first few of a terrain whose slip is far above the file's deciding
        the bias for good). Scaled as ``D P D`` (positive diagonal ``D``): the correlations
        are kept. The veer is not scaled: what holds it is its prior, no segment's.
        """
        if factor == 1.0:
            return
        p = self.p
        caps = (max(self._prior_kk, p[0, 0]), max(self._prior_bb, p[1, 1]))
        d = np.array([math.sqrt(factor * min(1.0, cap / (factor * v))) if v > 0.0 else 1.0
                      for v, cap in zip(np.diag(p), caps)] + [1.0])
        self.p = p * np.outer(d, d)

    # Standstill ------------------------------------------------------------------------

    def _still_reset(self) -> None:
        self._block = [0.0, 0.0, 0.0]    # a, d, y of the current block
        self._since = [0.0, 0.0, 0.0]    # the same since the checkpoint
        self._previous = None            # the previous block's (mean rate, duration)
        self._recent = []                # (mean rate, s) of the standstill's last blocks

    def still(self, a: float, d: float, y: float) -> None:
        """Observe a standstill step, after ``still_time``: creep ``a`` m, ``d`` s, ``y`` rad."""
        if self.still_refused:
            return
        if self._checkpoint is None:
            self._checkpoint = (self.x.copy(), self.p.copy(), self._noise2, self._blocks)
            if self._start is None:
                self._start = self._checkpoint
        block = self._block
        block[0] += a
        block[1] += d
        block[2] += y
        if block[1] < NOISE_BLOCK - SUM_TOLERANCE:
            return
        a, d, y = block
        self._block = [0.0, 0.0, 0.0]
        since = self._since
        since[0] += a
        since[1] += d
        since[2] += y
        x0, p0, _, _ = self._checkpoint
        h = np.array([since[0], since[1], 0.0])
        nu = since[2] - float(h @ x0)
        s = float(h @ p0 @ h) + self.noise ** 2 * since[1] + (BIAS_STEP * since[1]) ** 2
        if nu * nu > STILL_GATE * STILL_GATE * s:
            # It turns while the tracks stand still (against what was known before).
            self._refuse(abs(nu) / since[1])
            return
        mean = (y - self.k * a) / d
        recent = self._recent
        if recent:
            # Against this standstill's blocks of the last CHECKPOINT seconds, whatever was
            # known before: a turntable in the first seconds of a node with no bias prior.
            span = sum(e for _, e in recent)
            step = mean - sum(m * e for m, e in recent) / span
            var = self.noise ** 2 * (1.0 / d + 1.0 / span) + BIAS_STEP ** 2
            if step * step > STILL_GATE * STILL_GATE * var:
                self._refuse(abs(step))
                return
        recent.append((mean, d))
        while sum(e for _, e in recent[1:]) >= CHECKPOINT - SUM_TOLERANCE:
            recent.pop(0)
        previous, self._previous = self._previous, (mean, d)
        if previous is not None:
            # Differences of consecutive blocks: free of the bias, whatever it is.
            self._blocks += 1
            weight = max(1.0 / self._blocks, d / self.config.bias_time)
            sample = (mean - previous[0]) ** 2 / (1.0 / d + 1.0 / previous[1])
            self._noise2 += weight * (sample - self._noise2)
        self.update((a, d, 0.0), y, max(self.noise ** 2, 1e-12) * d)
        if since[1] >= CHECKPOINT - SUM_TOLERANCE:
            self._checkpoint = None
            self._since = [0.0, 0.0, 0.0]

    def _refuse(self, step: float) -> None:
        """
        Undo what this standstill taught, ``step`` rad/s the rate it changed by.

        What it taught since its last checkpoint; all it taught where the bias at its start
        was too little known to tell the rate it kept from this one (a turntable from the
        start: which of the two is the bias, nothing says; the motion that follows will).
        """
        start = self._start
        if STILL_GATE * math.sqrt(max(float(start[1][1, 1]), 0.0)) > step:
            self._checkpoint = start
        x0, p0, self._noise2, self._blocks = self._checkpoint
        self.x, self.p = x0.copy(), p0.copy()
        self.still_refused = True

    def moving(self) -> None:
        """End the standstill: keep what it taught (if it agreed with zero motion)."""
        self._checkpoint = None
        self._start = None
        self.still_refused = False
        self._still_reset()
