"""Steering efficiency from spin-in-place runs, Martinez et al. (2005) eq. (16)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ExcitationError, IdentificationError
from ..kinematics import IcrParams


@dataclass(frozen=True)
class SpinResult:
    """Steering efficiency from spin-in-place runs: mean ``chi``, its std, and the ``runs``."""

    chi: float
    chi_std: float
    runs: list

    def icr(self, track_width: float, scales=(1.0, 1.0)) -> IcrParams:
        """Return the symmetric model of this efficiency (Martinez sec. 4.2)."""
        half = 0.5 * track_width / self.chi
        return IcrParams(track_width, half, -half, 0.0, scales[0], scales[1])


def spin_in_place(recordings, track_width: float, scales=(1.0, 1.0), min_angle: float = 0.5,
                  balance: float = 0.2) -> SpinResult:
    """
    Steering efficiency from spin-in-place runs, Martinez eq. (16).

    ``chi = L phi / (int V_r dt - int V_l dt)``, ``phi`` the turned angle from ground truth, ``V``
    the true track speeds. A run: tracks opposed at nearly equal speeds (``|V_l + V_r| <= balance
    |V_r - V_l|``), turning at least ``min_angle`` rad. Raises ExcitationError with no run,
    IdentificationError for chi outside (0, 1].
    """
    runs = []
    for index, rec in enumerate(recordings):
        if len(rec.enc_t) < 2 or len(rec.gt_t) < 2:
            continue
        d_left = np.diff(rec.left) * scales[0]
        d_right = np.diff(rec.right) * scales[1]
        spin = (d_left * d_right < 0) & (np.abs(d_left + d_right)
                                         <= balance * np.abs(d_right - d_left))
        # Runs of spinning one way: +1 left, -1 right, 0 not spinning.
        direction = np.where(spin, np.sign(d_right - d_left), 0).astype(np.int8)
        change = np.flatnonzero(np.diff(np.concatenate([[0], direction, [0]])))
        yaw = np.unwrap(rec.gt_yaw)
        for first, last in zip(change[:-1], change[1:]):
            if direction[first] == 0:
                continue
            t0, t1 = rec.enc_t[first], rec.enc_t[last]
            lo, hi = np.searchsorted(rec.gt_t, [t0, t1 + 1e-12])
            if hi - lo < 2:
                continue
            ta, tb = rec.gt_t[lo], rec.gt_t[hi - 1]
            angle = float(yaw[hi - 1] - yaw[lo])
            travel = (np.diff(np.interp([ta, tb], rec.enc_t, rec.right))[0] * scales[1]
                      - np.diff(np.interp([ta, tb], rec.enc_t, rec.left))[0] * scales[0])
            if abs(angle) < min_angle or travel == 0.0:
                continue
            runs.append({'recording': index, 't0': float(ta), 't1': float(tb), 'angle': angle,
                         'travel_difference': float(travel),
                         'chi': float(track_width * angle / travel)})
    if not runs:
        raise ExcitationError(
            f'no spin-in-place run found: the tracks must turn in opposite directions at '
            f'nearly equal speeds while the vehicle turns at least {min_angle} rad')
    chis = np.array([r['chi'] for r in runs])
    chi = float(chis.mean())
    if not 0.0 < chi <= 1.0:
        raise IdentificationError(
            f'spin-in-place runs give chi = {chi:.3f}, outside (0, 1]: check the track width '
            'and the sprocket radius (and that the encoders count forwards as positive)')
    return SpinResult(chi, float(chis.std()), runs)
