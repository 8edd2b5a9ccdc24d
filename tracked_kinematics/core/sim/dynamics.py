"""
Stationary track-soil dynamics of a tracked vehicle: track speeds -> body twist -> tread ICRs.

Martinez et al. (2005), sec. 4.1 and 5.2: linear pressure under the tracks (Fig. 5) and
regularised anisotropic Coulomb friction (eqs. 22-23), balanced at zero acceleration (eqs.
14-15), in the ROS frame. See docs/simulator.md, "The dynamic model and its assumptions".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


GRAVITY = 9.81
"""Standard gravity, m/s^2."""


@dataclass(frozen=True, slots=True)
class Vehicle:
    """
    Description of a tracked vehicle and its soil, for the dynamic model (SI units, base_link).

    Attributes
    ----------
    track_width : float
        Distance between the track centrelines, m (``L``).
    contact_length, contact_width : float
        Length and belt width of one track's ground contact, m (width < ``track_width``).
    mass : float
        kg.
    com_x, com_y : float
        Centre of mass, m; needs ``|com_x| <= contact_length / 6`` and to lie between the tracks.
    com_height : float
        m; 0 (default) is the paper's model without inertia, > 0 adds load transfer in turns.
    mu_x, mu_y : float
        Coulomb friction coefficients along and across the tracks (eq. 23, ROS axes).
    max_track_speed : float
        Largest track speed of the drives, m/s (the range of the ICR map).
    name : str
        Label for reports.

    """

    track_width: float
    contact_length: float
    contact_width: float
    mass: float
    com_x: float = 0.0
    com_y: float = 0.0
    com_height: float = 0.0
    mu_x: float = 0.8
    mu_y: float = 0.8
    max_track_speed: float = 1.0
    name: str = ''

    def __post_init__(self):
        # Each value's range is checked where it enters (a vehicle file: VEHICLE_PARAMS);
        # what no single range says, the geometry as a whole, is checked here.
        if self.contact_width >= self.track_width:
            raise ValueError(
                f'contact_width ({self.contact_width!r} m) must be smaller than track_width '
                f'({self.track_width!r} m): the two contact patches would overlap')
        if abs(self.com_x) > self.contact_length / 6.0 + 1e-12:
            raise ValueError(
                f'com_x = {self.com_x!r} m is outside the middle third of the contact length '
                f'(|com_x| <= {self.contact_length / 6.0:.4g} m): the linear pressure '
                'distribution would be negative at one end')
        if abs(self.com_y) >= 0.5 * self.track_width:
            raise ValueError(
                f'com_y = {self.com_y!r} m must lie between the track centrelines '
                f'(|com_y| < {0.5 * self.track_width:.4g} m)')

    @property
    def inertial(self) -> bool:
        """Tell whether the model keeps centripetal force and load transfer (com_height > 0)."""
        return self.com_height > 0.0


@dataclass(frozen=True)
class ContactGrid:
    """Cells of both patches: centres ``x, y`` (m), ``area`` (m^2), ``left``, ``y_track``."""

    x: np.ndarray
    y: np.ndarray
    area: np.ndarray
    left: np.ndarray
    y_track: np.ndarray


def contact_grid(vehicle: Vehicle, n_long: int = 40, n_lat: int = 4) -> ContactGrid:
    """Discretise both contact patches into ``n_long x n_lat`` cells each (midpoint rule)."""
    if n_long < 2 or n_lat < 1:
        raise ValueError(f'need n_long >= 2 and n_lat >= 1, got {n_long}, {n_lat}')
    length, width = vehicle.contact_length, vehicle.contact_width
    xs = (np.arange(n_long) + 0.5) / n_long * length - 0.5 * length
    ys = (np.arange(n_lat) + 0.5) / n_lat * width - 0.5 * width
    gx, gy = np.meshgrid(xs, ys, indexing='ij')
    gx, gy = gx.ravel(), gy.ravel()
    half = 0.5 * vehicle.track_width
    cell = length * width / (n_long * n_lat)
    m = gx.size
    return ContactGrid(
        x=np.concatenate([gx, gx]), y=np.concatenate([half + gy, -half + gy]),
        area=np.full(2 * m, cell), left=np.concatenate([np.ones(m, bool), np.zeros(m, bool)]),
        y_track=np.concatenate([np.full(m, half), np.full(m, -half)]))


def normal_loads(vehicle: Vehicle, grid: ContactGrid, com_x=None, com_y=None) -> np.ndarray:
    """
    Compute the normal force on every cell, N: the linear pressure of Martinez Fig. 5.

    ``p = a + b x + c y_track`` with the loads summing to ``m g`` under ``(com_x, com_y)``
    (default: the vehicle's). May be negative for a centre of mass far outside (caller clips).
    """
    com_x = vehicle.com_x if com_x is None else com_x
    com_y = vehicle.com_y if com_y is None else com_y
    weight = vehicle.mass * GRAVITY
    area = grid.area
    a = weight / area.sum()
    b = weight * com_x / np.sum(area * grid.x ** 2)
    c = weight * com_y / np.sum(area * grid.y_track ** 2)
    return area * (a + b * grid.x + c * grid.y_track)


@dataclass(frozen=True)
class Solution:
    """
    Stationary response to one pair of track speeds: ``twist`` (m/s, m/s, rad/s), convergence.

    ``residual`` is the largest balance residual, normalised as in
    :meth:`StationarySolver.residuals`.
    """

    twist: np.ndarray
    converged: bool
    residual: float


class StationarySolver:
    """
    Body twist at which the friction forces and moment over both contact patches balance.

    Martinez et al. (2005) eqs. (14)-(15) with zero accelerations (plus the centripetal term
    when ``com_height > 0``), friction by eqs. (22)-(23). ``eps`` is the Coulomb regularisation
    velocity as a fraction of the larger track speed; ``tol`` the tolerance on the normalised
    residual.
    """

    def __init__(self, vehicle: Vehicle, n_long: int = 40, n_lat: int = 4, eps: float = 1e-3,
                 tol: float = 1e-9):
        if not eps > 0.0:
            raise ValueError(f'eps must be > 0, got {eps!r}')
        self.vehicle = vehicle
        self.grid = contact_grid(vehicle, n_long, n_lat)
        self.eps = float(eps)
        self.tol = float(tol)
        g = self.grid
        self._loads0 = normal_loads(vehicle, g)
        # Loads are linear in the effective centre of mass: d loads / d com_x, d com_y.
        self._dloads_dx = normal_loads(vehicle, g, 1.0, 0.0) - normal_loads(vehicle, g, 0.0, 0.0)
        self._dloads_dy = normal_loads(vehicle, g, 0.0, 1.0) - normal_loads(vehicle, g, 0.0, 0.0)
        self._force_scale = vehicle.mu_x * vehicle.mass * GRAVITY
        self._moment_scale = self._force_scale * vehicle.contact_length

    # The balance equations -----------------------------------------------------------------

    def _accel(self, v_x, v_y, w):
        """Centripetal acceleration of the centre of mass, shape (N, 2), and d/d twist."""
        xg, yg = self.vehicle.com_x, self.vehicle.com_y
        vgx, vgy = v_x - w * yg, v_y + w * xg
        accel = np.stack([-w * vgy, w * vgx], axis=-1)
        zero = np.zeros_like(w)
        jac = np.stack([np.stack([zero, -w, -(vgy + w * xg)], axis=-1),
                        np.stack([w, zero, vgx - w * yg], axis=-1)], axis=-2)
        return accel, jac

    def residuals(self, twist, v_left, v_right, eps):
        """
        Normalised force and moment imbalance of a batch of problems, with Jacobians.

        Parameters
        ----------
        twist : array_like, shape (N, 3)
            Trial ``(v_x, v_y, w)`` per problem.
        v_left, v_right : array_like, shape (N,)
            Track speeds, m/s.
        eps : array_like, shape (N,)
            Absolute regularisation velocity per problem, m/s.

        Returns
        -------
        r : ndarray, shape (N, 3)
            ``(F_x - m a_x, F_y - m a_y) / (mu_x m g)`` and ``M_z / (mu_x m g l)`` (about the
            centre of mass).
        jac : ndarray, shape (N, 3, 3)
            ``d r / d twist``.

        """
        veh, g = self.vehicle, self.grid
        twist = np.atleast_2d(np.asarray(twist, float))
        v_x, v_y, w = (twist[:, k:k + 1] for k in range(3))
        eps = np.asarray(eps, float).reshape(-1, 1)
        track_speed = np.where(g.left, np.asarray(v_left, float).reshape(-1, 1),
                               np.asarray(v_right, float).reshape(-1, 1))
        # Slip velocity of the tread over the ground, shape (N, M): body point velocity
        # (v_x - w y, v_y + w x) plus the tread's velocity relative to the body (-V, 0).
        sx = v_x - w * g.y - track_speed
        sy = v_y + w * g.x
        norm2 = sx * sx + sy * sy + eps * eps
        norm = np.sqrt(norm2)
        ux, uy = sx / norm, sy / norm
        # d u / d s = ((|s|^2 + eps^2) I - s s^T) / n^3
        n3 = norm2 * norm
        dux_dsx = (sy * sy + eps * eps) / n3
        duy_dsy = (sx * sx + eps * eps) / n3
        dux_dsy = -sx * sy / n3
        loads = self._loads0
        if veh.inertial:
            accel, daccel = self._accel(v_x[:, 0], v_y[:, 0], w[:, 0])
            shift = -veh.com_height / GRAVITY
            raw = (self._loads0 + shift * (self._dloads_dx * accel[:, :1]
                                           + self._dloads_dy * accel[:, 1:]))
            loads = np.maximum(raw, 0.0)
        mx = veh.mu_x * loads
        my = veh.mu_y * loads
        ax = g.x - veh.com_x
        ay = g.y - veh.com_y

        def wsum(values, weights):
            # Sum over the cells of values (N, M) times weights (M,) or (N, M).
            return values @ weights if weights.ndim == 1 else np.sum(values * weights, -1)

        # Friction f = -mu loads u; moment about the centre of mass ax f_y - ay f_x.
        r = -np.stack([wsum(ux, mx), wsum(uy, my), wsum(uy, ax * my) - wsum(ux, ay * mx)], -1)
        # Jacobian through the slip, d s / d twist: sx -> (1, 0, -y), sy -> (0, 1, x).
        dx_w = dux_dsy * g.x - dux_dsx * g.y      # d u_x / d w
        dy_w = duy_dsy * g.x - dux_dsy * g.y      # d u_y / d w
        jac = -np.stack([
            np.stack([wsum(dux_dsx, mx), wsum(dux_dsy, mx), wsum(dx_w, mx)], -1),
            np.stack([wsum(dux_dsy, my), wsum(duy_dsy, my), wsum(dy_w, my)], -1),
            np.stack([wsum(dux_dsy, ax * my) - wsum(dux_dsx, ay * mx),
                      wsum(duy_dsy, ax * my) - wsum(dux_dsy, ay * mx),
                      wsum(dy_w, ax * my) - wsum(dx_w, ay * mx)], -1),
        ], axis=1)
        if veh.inertial:
            # Load transfer: d loads / d twist = shift (dL/dx_e da_x + dL/dy_e da_y) where the
            # pressure is positive; centripetal force m a on the force rows.
            live = raw > 0.0
            for k, dloads_k in enumerate((self._dloads_dx, self._dloads_dy)):
                weights = shift * dloads_k * live
                jac[:, 0] -= veh.mu_x * wsum(ux, weights)[:, None] * daccel[:, k]
                jac[:, 1] -= veh.mu_y * wsum(uy, weights)[:, None] * daccel[:, k]
                jac[:, 2] -= (veh.mu_y * wsum(uy, ax * weights)
                              - veh.mu_x * wsum(ux, ay * weights))[:, None] * daccel[:, k]
            r[:, :2] -= veh.mass * accel
            jac[:, :2] -= veh.mass * daccel
        scale = np.array([self._force_scale, self._force_scale, self._moment_scale])
        return r / scale, jac / scale[:, None]

    def residual(self, twist, v_left: float, v_right: float, eps: float | None = None):
        """Normalised balance residual and Jacobian of one problem (see :meth:`residuals`)."""
        if eps is None:
            eps = self.eps * max(abs(v_left), abs(v_right))
        r, jac = self.residuals(np.reshape(twist, (1, 3)), [v_left], [v_right], [eps])
        return r[0], jac[0]

    # Solving ------------------------------------------------------------------------------

    def ideal_twist(self, v_left, v_right) -> np.ndarray:
        """Ideal differential-drive twist(s), shape (..., 3): the solver's starting point."""
        v_left = np.asarray(v_left, float)
        v_right = np.asarray(v_right, float)
        return np.stack([0.5 * (v_left + v_right), np.zeros_like(v_left),
                         (v_right - v_left) / self.vehicle.track_width], axis=-1)

    def _newton(self, twist, v_left, v_right, eps, iterations=40):
        """Damped Newton on a batch: full steps, halved while they do not reduce |r|."""
        r, jac = self.residuals(twist, v_left, v_right, eps)
        cost = np.sum(r * r, axis=-1)
        for _ in range(iterations):
            active = np.max(np.abs(r), axis=-1) > self.tol
            if not np.any(active):
                break
            try:
                step = np.linalg.solve(jac[active], -r[active][..., None])[..., 0]
            except np.linalg.LinAlgError:
                break
            idx = np.flatnonzero(active)
            alpha = np.ones(idx.size)
            pending = np.ones(idx.size, bool)
            for _ in range(12):
                trial = twist[idx[pending]] + alpha[pending, None] * step[pending]
                r_t, jac_t = self.residuals(trial, v_left[idx[pending]], v_right[idx[pending]],
                                            eps[idx[pending]])
                c_t = np.sum(r_t * r_t, axis=-1)
                better = c_t < cost[idx[pending]]
                sel = idx[pending][better]
                twist[sel], r[sel], jac[sel], cost[sel] = trial[better], r_t[better], \
                    jac_t[better], c_t[better]
                still = np.flatnonzero(pending)[~better]
                pending[:] = False
                pending[still] = True
                alpha[still] *= 0.5
                if not np.any(pending):
                    break
        return twist, np.max(np.abs(r), axis=-1)

    def _root(self, v_left, v_right, guess, eps):
        from scipy import optimize   # lazily: 0.3 s, and the nodes import this module
        result = optimize.root(lambda t: self.residual(t, v_left, v_right, eps), guess,
                               jac=True, method='hybr', options={'xtol': 1e-13})
        r, _ = self.residual(result.x, v_left, v_right, eps)
        return result.x, float(np.max(np.abs(r)))

    def solve(self, v_left: float, v_right: float, guess=None) -> Solution:
        """Stationary body twist for one pair of true track speeds (m/s), by hybrid Powell."""
        v_left, v_right = float(v_left), float(v_right)
        speed = max(abs(v_left), abs(v_right))
        if speed == 0.0:
            return Solution(np.zeros(3), True, 0.0)
        lift = self._lift(speed)
        if lift != 1.0:
            sol = self.solve(v_left * lift, v_right * lift,
                             None if guess is None else np.asarray(guess, float) * lift)
            return Solution(sol.twist / lift, sol.converged, sol.residual)
        eps = self.eps * speed
        start = self.ideal_twist(v_left, v_right) if guess is None else np.asarray(guess, float)
        twist, res = self._root(v_left, v_right, start, eps)
        if res > self.tol:
            # Continuation: a large eps makes friction nearly viscous (nearly linear); shrink it.
            twist = self.ideal_twist(v_left, v_right)
            for factor in (0.3, 0.1, 0.03, 0.01):
                twist, _ = self._root(v_left, v_right, twist, factor * speed)
            twist, res = self._root(v_left, v_right, twist, eps)
        return Solution(twist, res <= self.tol, res)

    def solve_many(self, v_left, v_right, guess=None):
        """
        Stationary twists, shape (N, 3), and convergence flags for many pairs of track speeds.

        Damped Newton on all pairs at once (from ``guess``, or via a nearly viscous friction law);
        unconverged pairs go to :meth:`solve`. Rows no method solved are NaN.
        """
        v_left, v_right = np.broadcast_arrays(np.atleast_1d(np.asarray(v_left, float)),
                                              np.atleast_1d(np.asarray(v_right, float)))
        v_left, v_right = v_left.ravel(), v_right.ravel()
        speed = np.maximum(np.abs(v_left), np.abs(v_right))
        twists = np.zeros((v_left.size, 3))
        moving = speed > 0.0
        ok = ~moving
        if np.any(moving):
            lift = self._lift(speed[moving])
            vl, vr, sp = v_left[moving] * lift, v_right[moving] * lift, speed[moving] * lift
            if guess is None:
                start = self.ideal_twist(vl, vr)
                start, _ = self._newton(start, vl, vr, 30.0 * self.eps * sp)
            else:
                start = np.array(np.broadcast_to(guess, v_left.shape + (3,))[moving], float)
                start *= lift[:, None]
            sol, res = self._newton(start, vl, vr, self.eps * sp)
            twists[moving] = sol / lift[:, None]
            ok = ok.copy()
            ok[moving] = res <= self.tol
        for i in np.flatnonzero(~ok):
            sol = self.solve(v_left[i], v_right[i])
            twists[i] = sol.twist if sol.converged else np.nan
            ok[i] = sol.converged
        return twists, ok

    def _lift(self, speed):
        """Factor raising track speeds below 1e-6 max_track_speed up to it (exact: homogeneous)."""
        floor = 1e-6 * self.vehicle.max_track_speed
        return np.where(speed < floor, floor / np.maximum(speed, 1e-300), 1.0)
