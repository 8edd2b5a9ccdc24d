"""
Tread ICR maps of a vehicle from its stationary dynamics (Martinez et al. 2005, sec. 5.2).

Tread ICRs of every pair of equidistant track speeds, and their average: the constant ICRs of the
kinematic model. See docs/simulator.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import StationarySolver, Vehicle
from ..errors import TrackedKinematicsError
from ..kinematics import IcrParams


def tread_icrs(v_left, v_right, twist, min_turn_rate: float = 1e-9):
    """
    Tread ICRs (m) of a body twist, Martinez eqs. (3)-(6) in ROS axes.

    ``y_left = (v_x - V_l) / w``, ``y_right = (v_x - V_r) / w``, ``x = -v_y / w``; NaN where ``|w|
    < min_turn_rate`` (rad/s).
    """
    twist = np.atleast_2d(np.asarray(twist, float))
    v_x, v_y, w = twist[:, 0], twist[:, 1], twist[:, 2]
    turning = np.abs(w) > min_turn_rate
    safe_w = np.where(turning, w, 1.0)
    nan = np.full_like(w, np.nan)
    return (np.where(turning, (v_x - np.asarray(v_left, float)) / safe_w, nan),
            np.where(turning, (v_x - np.asarray(v_right, float)) / safe_w, nan),
            np.where(turning, -v_y / safe_w, nan))


@dataclass(frozen=True)
class IcrMap:
    """
    Tread ICRs over a grid of equidistant track speeds (Martinez Figs. 6-7).

    ``v_left[i, j] = speeds[i]``, ``v_right[i, j] = speeds[j]`` (m/s); ``twist`` (n, n, 3) and the
    ICRs (m) are NaN for straight motion, standstill and failed solves.
    """

    vehicle: Vehicle
    speeds: np.ndarray
    v_left: np.ndarray
    v_right: np.ndarray
    twist: np.ndarray
    y_left: np.ndarray
    y_right: np.ndarray
    x: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """Pairs with defined ICRs (turning, solved)."""
        return np.isfinite(self.y_left) & np.isfinite(self.y_right) & np.isfinite(self.x)

    @property
    def failed(self) -> int:
        """Count the pairs where the solver did not converge."""
        return int(np.sum(~np.isfinite(self.twist[..., 0])))


def icr_map(vehicle: Vehicle, n: int = 21, solver: StationarySolver | None = None,
            max_speed: float | None = None) -> IcrMap:
    """
    Solve the stationary problem for all pairs of ``n`` equidistant speeds (Martinez sec. 5.2).

    The range is ``(-max_speed, max_speed)`` m/s (default ``vehicle.max_track_speed``).
    """
    if n < 2:
        raise ValueError(f'the map needs n >= 2 speeds per track, got {n}')
    solver = solver or StationarySolver(vehicle)
    top = vehicle.max_track_speed if max_speed is None else float(max_speed)
    speeds = np.linspace(-top, top, n)
    v_left, v_right = np.meshgrid(speeds, speeds, indexing='ij')
    twist, _ = solver.solve_many(v_left.ravel(), v_right.ravel())
    y_left, y_right, x = tread_icrs(v_left.ravel(), v_right.ravel(), twist,
                                    min_turn_rate=1e-6 * top / vehicle.track_width)
    # Equal speeds: straight motion, the ICRs are at infinity of the 0/0 limit; leave out.
    straight = np.isclose(v_left.ravel(), v_right.ravel(), rtol=0.0, atol=1e-12 * top)
    for arr in (y_left, y_right, x):
        arr[straight] = np.nan
    shape = v_left.shape
    return IcrMap(vehicle, speeds, v_left, v_right, twist.reshape(shape + (3,)),
                  y_left.reshape(shape), y_right.reshape(shape), x.reshape(shape))


def averaged_icr(icr_map_: IcrMap, weighting: str = 'uniform') -> IcrParams:
    """
    Constant tread ICRs fitted to a map (Martinez sec. 5.2), unit scales.

    ``weighting='uniform'``: the plain mean, as the paper; ``'turn_rate'``: the least-squares fit
    of the inverse kinematics, a mean weighted by ``w^2``.
    """
    valid = icr_map_.valid
    if not np.any(valid):
        raise TrackedKinematicsError('the ICR map has no turning pair with a solution')
    if weighting == 'uniform':
        weights = np.ones(int(valid.sum()))
    elif weighting == 'turn_rate':
        weights = icr_map_.twist[..., 2][valid] ** 2
    else:
        raise ValueError(f"weighting must be 'uniform' or 'turn_rate', got {weighting!r}")
    mean = [float(np.average(arr[valid], weights=weights))
            for arr in (icr_map_.y_left, icr_map_.y_right, icr_map_.x)]
    return IcrParams(icr_map_.vehicle.track_width, *mean)
