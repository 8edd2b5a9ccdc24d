"""
Tread-ICR kinematics of a tracked vehicle, in the ROS frame (x forward, y left).

Martinez et al. (2005), sec. 3, with the paper's tread ICR ``(x_ICR, y_ICR)`` at ROS ``(x = y_ICR,
y = -x_ICR)``. See docs/model.md, "Frames: the papers and ROS", for the derivation of every formula
below.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import require_numbers


def steering_efficiency(track_width, y_left, y_right):
    """Steering efficiency ``chi = L / (y_left - y_right)`` of tread ICRs, Martinez eq. (12)."""
    return track_width / (y_left - y_right)


def eccentricity(y_left, y_right):
    """Eccentricity ``e = -(y_left + y_right) / (y_left - y_right)``, Martinez eq. (13)."""
    return -(y_left + y_right) / (y_left - y_right)


@dataclass(frozen=True, slots=True)
class IcrParams:
    """
    Constant tread-ICR model of one vehicle on one terrain (base_link, m).

    Attributes
    ----------
    track_width : float
        Distance between the track centrelines, m (``L`` in Martinez, ``B`` in Fink & Stump).
    y_left, y_right : float
        Lateral coordinates of the tread ICRs, ``y_left > y_right`` (ideal: ``+-track_width / 2``).
    x : float
        Longitudinal coordinate shared by both tread ICRs (+ ahead of base_link).
    scale_left, scale_right : float
        True track speed = scale * nominal speed (``alpha_l``, ``alpha_r``, Martinez eqs. 20-21).

    Raises
    ------
    ValueError
        On a non-finite value, ``track_width <= 0``, ``y_left <= y_right``, chi outside (0, 1]
        or a scale <= 0; the message names it.

    """

    track_width: float
    y_left: float
    y_right: float
    x: float = 0.0
    scale_left: float = 1.0
    scale_right: float = 1.0

    def __post_init__(self):
        require_numbers(self, finite=('y_left', 'y_right', 'x'),
                        positive=('track_width', 'scale_left', 'scale_right'))
        if self.y_left <= self.y_right:
            raise ValueError(
                f'y_left ({self.y_left!r} m) must be greater than y_right ({self.y_right!r} m): '
                'the left tread ICR lies to the left of the right one')
        chi = self.chi
        if not 0.0 < chi <= 1.0 + 1e-12:
            raise ValueError(
                f'steering efficiency chi = track_width / (y_left - y_right) = {chi:.4g} is '
                f'outside (0, 1]: the tread ICRs ({self.y_left!r}, {self.y_right!r} m) must be '
                f'at least track_width = {self.track_width!r} m apart')

    @property
    def chi(self) -> float:
        """Steering efficiency ``L / (y_left - y_right)``, Martinez eq. (12)."""
        return steering_efficiency(self.track_width, self.y_left, self.y_right)

    @property
    def eccentricity(self) -> float:
        """Eccentricity ``-(y_left + y_right) / (y_left - y_right)``, Martinez eq. (13)."""
        return eccentricity(self.y_left, self.y_right)

    @classmethod
    def ideal(cls, track_width: float) -> IcrParams:
        """Ideal differential drive: ICRs on the track centrelines, no scale correction."""
        return cls(track_width, 0.5 * track_width, -0.5 * track_width)

    @classmethod
    def symmetric(cls, track_width: float, chi: float) -> IcrParams:
        """Symmetric model ``y_left = -y_right = track_width / (2 chi)`` (Martinez eq. 12)."""
        half = 0.5 * float(track_width) / float(chi)
        return cls(track_width, half, -half)

    @classmethod
    def from_paper(cls, x_icr_left: float, x_icr_right: float, y_icr: float,
                   track_width: float, alpha_left: float = 1.0,
                   alpha_right: float = 1.0) -> IcrParams:
        """
        Convert the paper's coordinates (Y forward, X right; m) to ROS.

        ``x_icr_left`` (< 0), ``x_icr_right`` (> 0), ``y_icr`` and ``track_width`` are Martinez's
        ``x_ICRl``, ``x_ICRr``, ``y_ICRv`` and ``L``; ``alpha_*`` the corrections of eqs.
        (20)-(21).
        """
        return cls(track_width, -float(x_icr_left), -float(x_icr_right), float(y_icr),
                   alpha_left, alpha_right)

    def to_paper(self) -> dict[str, float]:
        """Inverse of :meth:`from_paper`: the paper's symbols as a dict."""
        return {'x_icr_left': -self.y_left, 'x_icr_right': -self.y_right,
                'y_icr': self.x, 'L': self.track_width,
                'alpha_left': self.scale_left, 'alpha_right': self.scale_right}


def forward(v_left, v_right, icr: IcrParams):
    """
    Body twist from true track speeds through the tread ICRs.

    Implements Martinez et al. (2005) eqs. (7)-(9), rewritten in the ROS frame::

        w   = (V_r - V_l) / (y_left - y_right)
        v_x = (V_r + V_l) / 2 + w (y_left + y_right) / 2
        v_y = -w x

    Linear, so it maps travel over a step (m -> m, rad) as well as speeds.

    Parameters
    ----------
    v_left, v_right : array_like
        True track speeds in m/s (after scale correction, see :func:`true_speeds`).
    icr : IcrParams
        Tread ICR coordinates in base_link.

    Returns
    -------
    v_x, v_y, w : ndarray
        Body twist in base_link: m/s, m/s, rad/s.

    """
    v_left = np.asarray(v_left, dtype=float)
    v_right = np.asarray(v_right, dtype=float)
    w = (v_right - v_left) / (icr.y_left - icr.y_right)
    v_x = 0.5 * (v_right + v_left) + w * (0.5 * (icr.y_left + icr.y_right))
    v_y = -icr.x * w
    return v_x, v_y, w


def inverse(v_x, w, icr: IcrParams):
    """
    Compute the true track speeds (m/s) that produce a twist ``v_x`` (m/s), ``w`` (rad/s).

    Implements Martinez et al. (2005) eqs. (10)-(11) in the ROS frame::

        V_l = v_x - y_left  w
        V_r = v_x - y_right w

    The lateral velocity cannot be imposed; the vehicle shows ``-x w``. Divide by the scales
    (:func:`nominal_speeds`) for setpoints of a controller that trusts its encoders.
    """
    v_x = np.asarray(v_x, dtype=float)
    w = np.asarray(w, dtype=float)
    return v_x - icr.y_left * w, v_x - icr.y_right * w


def true_speeds(nominal_left, nominal_right, icr: IcrParams):
    """Convert encoder (nominal) track speeds to true ones, Martinez eqs. (20)-(21)."""
    return (np.asarray(nominal_left, dtype=float) * icr.scale_left,
            np.asarray(nominal_right, dtype=float) * icr.scale_right)


def nominal_speeds(true_left, true_right, icr: IcrParams):
    """Convert true track speeds to encoder (nominal) ones: inverse of :func:`true_speeds`."""
    return (np.asarray(true_left, dtype=float) / icr.scale_left,
            np.asarray(true_right, dtype=float) / icr.scale_right)
