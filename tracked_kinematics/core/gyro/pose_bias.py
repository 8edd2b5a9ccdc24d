"""
The gyro bias's share of the pose covariance: its error is common to every step.

A bias error ``db`` turns each step's fused heading increment by ``-K dt db / gyro_scale``
(``K`` the step's gain): errors of the steps that are not independent, so they cannot be
added as each step's variance. :class:`PoseBiasCross` carries the pose's cross-covariance
with the bias ``c`` through the steps, ``c' = F c + h s_b^2`` and ``P' = F P F^T + Q +
F c h^T + h c^T F^T + s_b^2 h h^T``, with ``F`` the step's pose Jacobian and ``h`` the pose
increment per unit of bias error (through the exact arc and the ICRs' lever arms ``(c, -x)``):
the covariance of the pose augmented by the bias, marginalised (Bar-Shalom et al. 2001,
sec. 5.2, the augmented state of a bias). Linearised; the bias variance ``s_b^2`` is the
filter's at each step.
"""

from __future__ import annotations

import math


class PoseBiasCross:
    """The pose's cross-covariance with the gyro bias, since the last reset."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        """Zero the cross-covariance (the pose is reset: it knows nothing of the bias)."""
        self.cross = (0.0, 0.0, 0.0)
        self._bb = 0.0

    def step(self, p, delta_x: float, delta_y: float, jacobian, gain: float, lever,
             sb2: float):
        """
        Return the propagated covariance ``p`` with the bias's share; carry the cross term.

        Parameters
        ----------
        p : tuple of float, 6
            The step's propagated pose covariance without the bias (upper triangle).
        delta_x, delta_y : float
            The step's displacement in the fixed frame, m.
        jacobian : tuple
            :func:`..covariance.arc_step`'s 2 x 3 Jacobian.
        gain : float
            rad per rad/s: the heading increment's error per unit of bias error (0: the
            heading is not the gyro's in this step).
        lever : tuple of float, 3
            The body increment per rad of heading increment, ``(c, -x, 1)``.
        sb2 : float
            rad^2/s^2, the bias's variance now.

        """
        c0, c1, c2 = self.cross
        if self._bb > 0.0 and sb2 < self._bb:
            # The bias became better known: its correlation with the pose shrinks with it.
            f = math.sqrt(sb2 / self._bb)
            c0, c1, c2 = c0 * f, c1 * f, c2 * f
        a0, a1, a2 = c0 - delta_y * c2, c1 + delta_x * c2, c2
        self._bb = sb2
        if gain == 0.0:
            self.cross = (a0, a1, a2)
            return p
        (g0, g1, g2), (h0, h1, h2) = jacobian
        u0, u1, u2 = lever
        h = (gain * (g0 * u0 + g1 * u1 + g2 * u2), gain * (h0 * u0 + h1 * u1 + h2 * u2), gain)
        xx, xy, xt, yy, yt, tt = p
        self.cross = (a0 + sb2 * h[0], a1 + sb2 * h[1], a2 + sb2 * h[2])
        return (xx + 2.0 * a0 * h[0] + sb2 * h[0] * h[0],
                xy + a0 * h[1] + h[0] * a1 + sb2 * h[0] * h[1],
                xt + a0 * h[2] + h[0] * a2 + sb2 * h[0] * h[2],
                yy + 2.0 * a1 * h[1] + sb2 * h[1] * h[1],
                yt + a1 * h[2] + h[1] * a2 + sb2 * h[1] * h[2],
                tt + 2.0 * a2 * h[2] + sb2 * h[2] * h[2])
