"""
Does the gyro see the turns the tracks make? A check that runs all the time.

Over segments of motion the gyro's raw heading ``y`` is regressed on the turn ``a`` the
tracks make and the duration ``d``, ``y = k a + b d``, weighted by each segment's expected
residual, with no prior on ``k`` (what the bias filter knows of ``b`` is the only prior),
forgetting per radian turned (:data:`MEMORY`). The ratio of ``k`` to the terrain file's
``gyro_scale / (y_left - y_right)`` is about 1 on a gyro read right; with the steering
efficiency anywhere in the adaptation's bounds (0.2-1) it lies in ``[low, high]``. The check
refuses a ratio that is negative
(a gyro turning the other way: mounted upside down, or publishing NED), far below the
plausible range (another axis), or far above it (other units, a wrong ``gyro_scale``),
beyond three standard errors; and accepts one inside it once the standard error is small.
"""

from __future__ import annotations

import math

#: rad turned the check remembers.
MEMORY = 20.0

#: rad turned before a verdict.
MIN_TURN = 0.1

#: Largest standard error of the ratio for a verdict.
MAX_RATIO_STD = 0.2

#: Margin beyond the plausible ratios before a ratio is refused.
MARGIN = 1.5

PENDING = 'pending'
AGREES = 'agrees'
REFUSED = 'refused'


class AgreementCheck:
    """
    The gyro's turn gain against the tracks', unconstrained (module docstring).

    Parameters
    ----------
    k0 : float
        rad/m, the terrain file's ``gyro_scale / (y_left - y_right)``.
    low, high : float
        The plausible ratios ``k / k0``.

    Attributes
    ----------
    verdict : str
        :data:`PENDING`, :data:`AGREES` or :data:`REFUSED`.
    reason : str
        Why refused ('' otherwise).
    ratio : float
        ``k / k0`` (nan before any turn).

    """

    def __init__(self, k0: float, low: float, high: float):
        self.k0 = k0
        self.low = low
        self.high = high
        self._sums = [0.0] * 6      # aa, ad, dd, ay, dy, yy
        self._n = 0.0
        self.turned = 0.0
        self.verdict = PENDING
        self.reason = ''
        self.ratio = math.nan

    def add(self, a: float, d: float, y: float, r: float, bias: float,
            bias_var: float) -> None:
        """
        Add a segment of motion: turn ``a`` (m), ``d`` s, gyro heading ``y`` (rad).

        ``r`` rad^2 is the segment's expected residual variance (the model's slip and the
        gyro's noise); ``bias`` and ``bias_var`` what is known of the bias (a prior that
        separates it from the turn gain when the turns are one-sided).
        """
        turned = abs(a * self.k0)
        forget = math.exp(-turned / MEMORY)
        s = self._sums
        w = 1.0 / max(r, 1e-12)
        for i, value in enumerate((a * a, a * d, d * d, a * y, d * y, y * y)):
            s[i] = forget * s[i] + w * value
        self._n = forget * self._n + 1.0
        self.turned += turned
        self._decide(bias, bias_var)

    def _decide(self, bias: float, bias_var: float) -> None:
        aa, ad, dd, ay, dy, yy = self._sums
        prior = 1.0 / max(bias_var, 1e-18)
        dd_p, dy_p = dd + prior, dy + prior * bias
        det = aa * dd_p - ad * ad
        if self.turned < MIN_TURN or self._n < 3.0 or not det > 0.0:
            return
        k = (dd_p * ay - ad * dy_p) / det
        b = (aa * dy_p - ad * ay) / det
        chi2 = yy - 2.0 * (k * ay + b * dy) + k * k * aa + 2.0 * k * b * ad + b * b * dd
        inflate = max(1.0, chi2 / max(self._n - 1.0, 1.0))
        std = math.sqrt(inflate * dd_p / det) / abs(self.k0)
        ratio = self.ratio = k / self.k0
        if std > MAX_RATIO_STD:
            return
        if ratio < 0.0 and ratio + 3.0 * std < 0.0:
            self._refuse(f'the gyro turns the other way than the tracks (ratio {ratio:.2f}): '
                         'an IMU mounted upside down or publishing NED (z down)? check its '
                         'mounting, frame_id and sign')
        elif ratio + 3.0 * std < self.low / MARGIN:
            self._refuse(f'the gyro sees {ratio:.2f} of the turns the tracks make: the yaw '
                         'rate on another axis (mounting, frame_id)?')
        elif ratio - 3.0 * std > self.high * MARGIN:
            self._refuse(f'the gyro turns {ratio:.2f} times what the tracks allow: other units '
                         '(deg/s?) or a wrong gyro_scale?')
        elif self.low / MARGIN <= ratio <= self.high * MARGIN:
            self.verdict = AGREES
            self.reason = ''

    def _refuse(self, reason: str) -> None:
        self.verdict = REFUSED
        self.reason = reason
