"""
Stationary track-soil dynamics of a tracked vehicle: track speeds -> body twist -> tread ICRs.

Martinez et al. (2005), sec. 4.1 and 5.2, compute the map of tread ICR positions of a
vehicle, without driving it, from the stationary response of a dynamic model: a pressure
field under the tracks set by the centre of mass (Fig. 5) and anisotropic Coulomb friction on
the slip velocity of every contact point (eqs. 22-23). This module implements that model in
the ROS frame (x forward, y left; base_link at the centre of the two contact patches).

Model and assumptions (hard, flat, uniform soil at moderate speed, as in the paper):

- Each track touches the ground on a rectangle ``contact_length x contact_width`` centred on
  its centreline ``y = +-track_width / 2``. The patches are discretised into a grid of cells
  (midpoint rule); every sum below is vectorised over the cells.
- Pressure is linear along the track and constant across it (Fig. 5). With three unknowns
  ``p(x, y_s) = a + b x + c y_s`` (``y_s`` the track centreline) the three equations of
  statics (total load ``m g``, moments putting the resultant under the centre of mass) fix
  it uniquely: this is the distribution of a rigid body on a uniform elastic foundation. It
  is computed on the grid itself, so the discrete loads are statically consistent exactly.
- Friction per unit area on a tread point of slip velocity ``v_s`` (the velocity of the tread
  material over the ground) is ``-p diag(mu_x, mu_y) v_s / |v_s|`` (eq. 22 with eq. 23 in
  ROS axes: ``mu_x`` along the track, ``mu_y`` across it; the paper's ``mu_y`` is our
  ``mu_x``). Coulomb's law is non-smooth at zero slip; we regularise the unit vector as
  ``v_s / sqrt(|v_s|^2 + eps^2)`` with ``eps`` a small fraction (default 1e-3) of the track
  speed, which changes the tread ICRs by well under a millimetre and makes the equations
  smooth, so Newton-type solvers converge.
- Stationary motion: the body twist ``(v_x, v_y, w)`` is constant, so eqs. (14)-(15) with the
  accelerations set to zero reduce to: the friction forces and their moment over both patches
  balance. No motion resistance (hard soil), no gyroscopic torques, no aerodynamic drag.
- Optional load transfer (``com_height > 0``): the steady-turn centripetal acceleration of
  the centre of mass, ``a = w x v_G``, is kept in eq. (14) (``m a = sum F``) and its inertial
  moment at height ``com_height`` shifts the pressure towards the outer track (and the rear
  when ``a_x > 0``). The response then depends on the speed, not only on the ratio of the
  track speeds. With ``com_height = 0`` the model is the paper's: no inertia at all.

Without inertia the equations are homogeneous: scaling both track speeds by ``s > 0`` scales
the twist by ``s``, and reversing both reverses it; mass and the common scale of the friction
coefficients drop out, only their ratio and the pressure shape matter.

The tread ICRs follow from the twist by Martinez eqs. (3)-(6), in ROS axes::

    y_left = (v_x - V_l) / w,   y_right = (v_x - V_r) / w,   x = -v_y / w

:mod:`.icr_maps` computes them over a grid of track speeds and averages them (sec. 5.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize


GRAVITY = 9.81
"""Standard gravity, m/s^2."""


@dataclass(frozen=True, slots=True)
class Vehicle:
    """
    Description of a tracked vehicle and its soil, for the dynamic model.

    All coordinates in base_link (x forward, y left, origin at the centre of the two contact
    patches). Martinez et al. give the Auriga-alpha centre of mass as (-0.015, 0.04) m in
    their frame (X right, Y forward): in ROS axes ``com_x = 0.04``, ``com_y = 0.015``.

    Attributes
    ----------
    track_width : float
        Distance between the track centrelines, m (``L``).
    contact_length : float
        Length of the ground contact of one track, m.
    contact_width : float
        Width of one track belt, m (< ``track_width``: the patches must not overlap).
    mass : float
        Vehicle mass, kg.
    com_x, com_y : float
        Centre of mass in base_link, m. The static pressure must stay >= 0 everywhere:
        ``|com_x| <= contact_length / 6`` for a linear distribution, and the centre of mass
        between the tracks.
    com_height : float
        Height of the centre of mass above the ground, m. 0 (default) is the paper's model
        without inertia; a height > 0 adds centripetal force and load transfer in turns.
    mu_x, mu_y : float
        Coulomb friction coefficients along and across the tracks (eq. 23, ROS axes).
    max_track_speed : float
        Largest track speed of the drives, m/s (the range of the ICR map).
    name : str
        Label for reports.

    Raises
    ------
    ValueError
        On a geometry that cannot hold (overlapping contact patches, the centre of mass
        outside the middle third or beyond a track); each value's own range is checked
        where it enters (:data:`tracked_kinematics.params.vehicles.VEHICLE_PARAMS`).

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
    """
    Cells of both contact patches: centres, areas and the track each belongs to.

    Attributes
    ----------
    x, y : ndarray, shape (M,)
        Cell centres in base_link, m.
    area : ndarray, shape (M,)
        Cell areas, m^2.
    left : ndarray of bool, shape (M,)
        True for cells of the left track.
    y_track : ndarray, shape (M,)
        Centreline of the cell's track, m (``+-track_width / 2``).

    """

    x: np.ndarray
    y: np.ndarray
    area: np.ndarray
    left: np.ndarray
    y_track: np.ndarray


def contact_grid(vehicle: Vehicle, n_long: int = 40, n_lat: int = 4) -> ContactGrid:
    """
    Discretise both contact patches into ``n_long x n_lat`` cells each (midpoint rule).

    Parameters
    ----------
    vehicle : Vehicle
        Geometry.
    n_long, n_lat : int
        Cells along and across each track.

    Returns
    -------
    ContactGrid

    """
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

    ``p = a + b x + c y_track`` with ``a, b, c`` chosen so that, on this grid, the loads sum
    to ``m g`` and their resultant lies under ``(com_x, com_y)``.

    Parameters
    ----------
    vehicle : Vehicle
        Mass and static centre of mass.
    grid : ContactGrid
        Cells.
    com_x, com_y : float, optional
        Effective centre of mass (default: the vehicle's); the load transfer of a turn moves
        it (:class:`StationarySolver`).

    Returns
    -------
    ndarray, shape (M,)
        Loads; may be negative for an effective centre of mass far outside the patches
        (the caller clips).

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
    Stationary response to one pair of track speeds.

    Attributes
    ----------
    twist : ndarray, shape (3,)
        ``(v_x, v_y, w)`` in base_link: m/s, m/s, rad/s.
    converged : bool
        The balance residual is below tolerance.
    residual : float
        Largest balance residual, as a fraction of ``mu_x m g`` (forces) and of
        ``mu_x m g contact_length`` (moment).

    """

    twist: np.ndarray
    converged: bool
    residual: float


class StationarySolver:
    """
    Body twist at which the friction forces and moment over both contact patches balance.

    Martinez et al. (2005) eqs. (14)-(15) with zero accelerations (plus the centripetal term
    when the vehicle has a ``com_height > 0``), friction by eqs. (22)-(23) on the slip velocity
    of every cell. The three balance equations are solved with MINPACK's hybrid Powell method
    (``scipy.optimize.root``, ``method='hybr'``) and an analytic Jacobian, from the ideal
    differential-drive twist; on failure, again by continuation from a heavily regularised
    (almost viscous, hence almost linear) friction law down to ``eps``.

    Parameters
    ----------
    vehicle : Vehicle
        Vehicle and soil.
    n_long, n_lat : int
        Grid cells along and across each patch.
    eps : float
        Regularisation velocity of the Coulomb unit vector, as a fraction of the larger
        track speed.
    tol : float
        Convergence tolerance on the normalised balance residual.

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
            ``(F_x - m a_x, F_y - m a_y) / (mu_x m g)`` and ``M_z / (mu_x m g l)``, the moment
            taken about the centre of mass (``a = 0`` when ``com_height = 0``).
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
        """
        Normalised balance residual and Jacobian of one problem (see :meth:`residuals`).

        Parameters
        ----------
        twist : array_like, shape (3,)
            Trial ``(v_x, v_y, w)``.
        v_left, v_right : float
            Track speeds, m/s.
        eps : float, optional
            Absolute regularisation velocity, m/s (default: the solver's fraction of the
            larger track speed).

        Returns
        -------
        r : ndarray, shape (3,)
        jac : ndarray, shape (3, 3)

        """
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
        result = optimize.root(lambda t: self.residual(t, v_left, v_right, eps), guess,
                               jac=True, method='hybr', options={'xtol': 1e-13})
        r, _ = self.residual(result.x, v_left, v_right, eps)
        return result.x, float(np.max(np.abs(r)))

    def solve(self, v_left: float, v_right: float, guess=None) -> Solution:
        """
        Stationary body twist for one pair of track speeds, by scipy's hybrid Powell method.

        Parameters
        ----------
        v_left, v_right : float
            True track speeds, m/s.
        guess : array_like, shape (3,), optional
            Starting twist (default: ideal differential drive).

        Returns
        -------
        Solution

        """
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
        Stationary twists for many pairs of track speeds at once.

        A damped Newton iteration runs on all pairs together (vectorised residuals, batched
        3 x 3 solves): from ``guess`` when given, else first on a strongly regularised
        friction law (``eps`` x 30, nearly viscous) from the ideal twist and then on the
        requested one. Pairs it leaves unconverged are solved one by one with :meth:`solve`
        (hybrid Powell, continuation in ``eps``).

        Parameters
        ----------
        v_left, v_right : array_like, shape (N,)
            Track speeds, m/s.
        guess : array_like, shape (N, 3), optional
            Starting twists (for a continuation, e.g. over speed).

        Returns
        -------
        twist : ndarray, shape (N, 3)
            NaN rows where no method converged.
        converged : ndarray of bool, shape (N,)

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
        """
        Factor raising track speeds below 1e-6 max_track_speed to that floor.

        Tiny speeds would underflow the regularisation (``eps^2``); the response there is
        inertia-free, hence homogeneous, so solving at the floor and scaling back is exact.
        """
        floor = 1e-6 * self.vehicle.max_track_speed
        return np.where(speed < floor, floor / np.maximum(speed, 1e-300), 1.0)
