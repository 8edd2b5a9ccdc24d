"""
A noise model of tracked odometry fitted to data: track random walk, slip in turns, timing.

Per step of nominal track travel ``d_l, d_r`` (body increments ``(dx, dy, dtheta)`` through
the tread-ICR kinematics ``B`` of :func:`.covariance.body_jacobian`), the body increments
carry independent zero-mean errors of covariance::

    S = track B diag(|d_l|, |d_r|) B^T                    track random walk (Kelly 2004)
      + turn |dtheta| e_theta e_theta^T                   heading random walk in turns
      + slip w |dtheta| (e_x e_x^T + e_y e_y^T)           position random walk in turns
      + floor I,          w = |dtheta| / (|dtheta| + |dx| / track_width)

and, not accumulated, the odometry is off in time by a zero-mean error of variance
``timing`` (s^2) at each end of an interval: the pose covariance of an interval gets
``timing v v^T`` for the pose rate ``v`` (fixed frame) at its end, and at its start; and its
distance scale is off by a relative error of variance ``scale``, the same over the whole
interval (fully correlated): the position covariance gets ``scale p p^T`` for the
displacement ``p`` since the interval's start.

- ``track`` (m^2/m): each track's travel is a random walk in the distance it travelled,
  Kelly's "Linearized error propagation in odometry" (IJRR 23(2), 2004), the model of
  :mod:`.covariance`.
- ``turn`` (rad^2/rad) and ``slip`` (m^2/rad): slip varies from turn to turn (the tread ICRs
  of a real drive move with the ground and the manoeuvre; Martinez et al. 2005 fit them per
  terrain, and one constant set misses that spread), so the heading and the position carry
  a random walk in the angle turned. The position part is weighted by how tight the turn
  is, ``w`` (1 turning on the spot, ``-> 0`` in a gentle curve): on the Warthog grass runs of
  ../shared/realdata the errors of constant-ICR odometry grow with the angle turned in
  tight turns and pivots, not in gentle curves. Both terms and ``w`` are our own choice,
  made on those runs (benchmarks/bench_covariance_fit.py), not an equation of the papers.
- ``timing`` (s^2): the encoder speeds arrive held (the Warthog's change about 8 times a
  second) and a reference's stamps carry a varying latency; an error of the time shifts
  the pose along its rate. Also our own choice.
- ``scale`` (1, relative variance): a distance scale the calibration could not determine
  (no pose, GNSS or straight: identify_icr holds it at the nominal one and writes its prior
  uncertainty here) keeps the path's shape and stretches it: an error ``sigma_s p`` of the
  displacement ``p``, whatever the window's length (the ``timing`` term, constant in the
  length, carried it exactly for one length only: 4 times too much after 5 s for 10 s).
  Not accumulated per step; fitted only where asked (:func:`.evaluate.noise.fit_noise`).
- ``drift`` (1, relative variance): the displacement ``p`` since the interval's start is off
  by ``s p + beta perp(p)``, a distance scale ``s`` and a crab angle ``beta`` (the direction
  of travel off the heading) each of variance ``drift``, constant over the interval: the
  position covariance gets ``drift |p|^2 I``. For the gyro-aided odometry, whose heading
  the gyro gives and whose errors grow as the square of the window (issue 35): its own
  constants are fitted on gyro-aided windows (:mod:`.evaluate.gyro_noise`); the encoders'
  model has none. Our own choice, not an equation of the papers.

The pose covariance is propagated through the ICR kinematics along the path, linearised as
Kelly does (:func:`propagate_body`, one step, and its float form for the node,
:func:`step_covariance` with :func:`propagate_step`; :func:`window_bases`, every window of a
path at once): an error of the body increments at step ``k`` moves the final position by
``R(theta_k) (dx, dy)`` and, through the heading, by ``dtheta`` times the perpendicular of
the path still to go. Every term is linear in its constant, so the covariance after a
window is ``sum_m c_m A_m`` with bases ``A_m`` that depend on the path only;
:func:`consistency` measures how often windowed errors fall inside the published ellipses;
:mod:`.evaluate.noise` fits the constants to the windows evaluate_model scores.

The twist covariance is that of the mean body twist over :data:`.covariance.TWIST_TIME`
from the same ``S`` (:meth:`NoiseModel.twist`), as :mod:`.covariance` does for its own.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
import math

import numpy as np

from .covariance import body_jacobian, saturate, TWIST_TIME
from .kinematics import IcrParams

# Chi-square quantiles of 2 degrees of freedom (the 50 % and 95 % ellipses) and of 1 (the
# 50 % and 95 % intervals of the heading).
CHI2_50 = 1.3862943611198906
CHI2_95 = 5.991464547107979
CHI2_1_50 = 0.454936423119572
CHI2_1_95 = 3.841458820694124

TERMS = ('track', 'turn', 'slip', 'timing', 'scale')
"""The constants of the model, in the order of :func:`window_bases`' bases."""
FITTED = TERMS[:4]
"""The terms :func:`.evaluate.noise.fit_noise` fits by default (``scale`` is a prior's)."""


@dataclass(frozen=True, slots=True)
class NoiseModel:
    """
    Constants of the odometry noise model (module docstring).

    The defaults are today's :class:`.covariance.TrackNoise`: the track random walk alone.

    Attributes
    ----------
    track : float
        Variance of each track's travel per metre it travelled, m^2/m.
    turn : float
        Variance of the heading per radian turned, rad^2/rad.
    slip : float
        Variance of each position coordinate per radian turned on the spot, m^2/rad.
    timing : float
        Variance of the time of the odometry at each end of an interval, s^2.
    floor : float
        Variance added per step to each body increment (m^2, m^2, rad^2), so that the
        covariance stays positive definite at a standstill.
    scale : float
        Relative variance of the distance scale, the same over an interval: the position
        covariance gets ``scale p p^T`` for the displacement ``p`` since its start (1).
    drift : float
        Relative variance of the displacement's length and direction, the same over an
        interval: the position covariance gets ``drift |p|^2 I`` (1).

    Raises
    ------
    ValueError
        When any value is not a finite number >= 0 (the message names it).

    """

    track: float = 1e-3
    turn: float = 0.0
    slip: float = 0.0
    timing: float = 0.0
    floor: float = 1e-9
    scale: float = 0.0
    drift: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f'{f.name} must be a number, got {value!r}')
            if not math.isfinite(value) or value < 0.0:
                raise ValueError(f'{f.name} must be finite and >= 0, got {value!r}')
            object.__setattr__(self, f.name, float(value))

    def without_tracks(self) -> NoiseModel:
        """
        Return the model without its track terms (``track`` and ``floor`` 0).

        The node and evaluate_model keep the tracks' random walk in a
        :class:`.covariance.TrackNoise` of its own (each track's constant) and publish the
        turn, slip, timing and scale terms of this one beside it.
        """
        return replace(self, track=0.0, floor=0.0)

    @property
    def beside_the_steps(self) -> bool:
        """Return whether ``timing``, ``scale`` or ``drift`` is on: added where published."""
        return self.timing > 0.0 or self.scale > 0.0 or self.drift > 0.0

    @property
    def constants(self) -> np.ndarray:
        """Return the constants of :data:`TERMS`, in that order."""
        return np.array([getattr(self, t) for t in TERMS])

    def body_covariance(self, icr: IcrParams, d_left, d_right) -> np.ndarray:
        """
        Covariance ``S`` of the body increments of steps of nominal travel.

        Parameters
        ----------
        icr : IcrParams
            Kinematic model.
        d_left, d_right : float or ndarray, shape (N,)
            Nominal travel of each track over each step, m.

        Returns
        -------
        ndarray, shape (3, 3) or (N, 3, 3)
            Of ``(dx, dy, dtheta)``: m^2, m^2, rad^2 (without ``timing``, which does not
            accumulate: :func:`timing_covariance`).

        """
        s = _step_covariances(icr, np.atleast_1d(np.asarray(d_left, float)),
                              np.atleast_1d(np.asarray(d_right, float)))
        s = np.einsum('m,nmij->nij', self.constants[:3], s)   # track, turn, slip
        s += self.floor * np.eye(3)
        return s if np.ndim(d_left) else s[0]

    def twist(self, icr: IcrParams, v_left: float, v_right: float) -> np.ndarray:
        """
        Covariance of the body twist ``(v_x, v_y, w)`` at nominal track speeds, 3 x 3.

        That of the mean twist over :data:`.covariance.TWIST_TIME`, ``S(v T) / T^2`` (module
        docstring): independent of the publish rate. (m/s)^2, (rad/s)^2.
        """
        t = TWIST_TIME
        return self.body_covariance(icr, v_left * t, v_right * t) / (t * t)


PRIOR = NoiseModel(track=1e-3, turn=1e-3, slip=2e-2, timing=0.1 ** 2)
"""
Centre of the fit's prior (:func:`.evaluate.noise.fit_noise`), the values of terms it holds.

``track`` is today's default; the others are of the order the Warthog grass runs give
(benchmarks/bench_covariance_fit.py): a timing error of 0.1 s, a position spread of 0.14 m
per square-root radian turned on the spot, a heading spread of 0.03 rad per square-root
radian turned.
"""


def _step_covariances(icr: IcrParams, d_left, d_right) -> np.ndarray:
    """Per-step body covariance of each accumulating term, unit constants: (N, 3, 3, 3)."""
    b = np.asarray(body_jacobian(icr))
    body = np.column_stack([d_left, d_right]) @ b.T
    turned = np.abs(body[:, 2])
    tight = np.divide(turned * turned, turned + np.abs(body[:, 0]) / icr.track_width,
                      out=np.zeros_like(turned), where=turned > 0.0)
    out = np.zeros((len(turned), 3, 3, 3))
    out[:, 0] = (np.abs(d_left)[:, None, None] * np.outer(b[:, 0], b[:, 0])
                 + np.abs(d_right)[:, None, None] * np.outer(b[:, 1], b[:, 1]))
    out[:, 1, 2, 2] = turned
    out[:, 2, 0, 0] = tight
    out[:, 2, 1, 1] = tight
    return out


def propagate_body(p, delta_x: float, delta_y: float, m, s) -> np.ndarray:
    """
    One step of the pose covariance, ``F P F^T + M S M^T``, Kelly's linearised propagation.

    Parameters
    ----------
    p : array_like, shape (3, 3)
        Pose covariance ``(x, y, theta)`` before the step.
    delta_x, delta_y : float
        The step's displacement in the fixed frame, m (:func:`.covariance.arc_step`).
    m : tuple of tuple of float, 2 x 3
        ``d (delta_x, delta_y) / d (dx, dy, dtheta)`` (:func:`.covariance.arc_step`).
    s : array_like, shape (3, 3)
        Covariance of the body increments (:meth:`NoiseModel.body_covariance`).

    Returns
    -------
    ndarray, shape (3, 3)

    """
    f = np.array([[1.0, 0.0, -delta_y], [0.0, 1.0, delta_x], [0.0, 0.0, 1.0]])
    g = np.vstack([np.asarray(m, float), [0.0, 0.0, 1.0]])
    out = f @ np.asarray(p, float) @ f.T + g @ np.asarray(s, float) @ g.T
    return 0.5 * (out + out.T)


def step_covariance(model: NoiseModel, body, track_width: float, d_left: float,
                    d_right: float):
    """
    Body-increment covariance of one step, as an upper triangle of Python floats.

    The node's per-message form of :meth:`NoiseModel.body_covariance` (numpy's per-call
    overhead on 3 x 3 matrices would cost far more than the arithmetic, as for
    :func:`.covariance.arc_step`).

    Parameters
    ----------
    model : NoiseModel
        The constants.
    body : tuple of tuple of float, 3 x 2
        :func:`.covariance.body_jacobian` of the model in use.
    track_width : float
        m, of the tightness weight ``w``.
    d_left, d_right : float
        Nominal travel of each track over the step, m.

    Returns
    -------
    tuple of float, 6
        ``(xx, xy, xt, yy, yt, tt)`` of ``(dx, dy, dtheta)``.

    """
    (xl, xr), (yl, yr), (tl, tr) = body
    ql = model.track * abs(d_left)
    qr = model.track * abs(d_right)
    dx = xl * d_left + xr * d_right
    turned = abs(tl * d_left + tr * d_right)
    tight = turned * turned / (turned + abs(dx) / track_width) if turned > 0.0 else 0.0
    slip = model.slip * tight
    floor = model.floor
    return (xl * xl * ql + xr * xr * qr + slip + floor, xl * yl * ql + xr * yr * qr,
            xl * tl * ql + xr * tr * qr, yl * yl * ql + yr * yr * qr + slip + floor,
            yl * tl * ql + yr * tr * qr,
            tl * tl * ql + tr * tr * qr + model.turn * turned + floor)


def propagate_step(p, delta_x: float, delta_y: float, m, s):
    """
    One step of the pose covariance, ``F P F^T + M S M^T``, on upper triangles of floats.

    The node's form of :func:`propagate_body`; the layout of :func:`.covariance.propagate`.

    Parameters
    ----------
    p : tuple of float, 6
        Pose covariance before the step, ``(xx, xy, xt, yy, yt, tt)``.
    delta_x, delta_y : float
        The step's displacement in the fixed frame, m (:func:`.covariance.arc_step`).
    m : tuple of tuple of float, 2 x 3
        :func:`.covariance.arc_step`'s Jacobian.
    s : tuple of float, 6
        :func:`step_covariance`.

    Returns
    -------
    tuple of float, 6

    """
    xx, xy, xt, yy, yt, tt = p
    a, b = -delta_y, delta_x
    sxx, sxy, sxt, syy, syt, stt = s
    (g0, g1, g2), (h0, h1, h2) = m
    # G S with G = (m[0], m[1], (0, 0, 1)), unrolled (the node calls this per message).
    gs0 = g0 * sxx + g1 * sxy + g2 * sxt
    gs1 = g0 * sxy + g1 * syy + g2 * syt
    gs2 = g0 * sxt + g1 * syt + g2 * stt
    hs0 = h0 * sxx + h1 * sxy + h2 * sxt
    hs1 = h0 * sxy + h1 * syy + h2 * syt
    hs2 = h0 * sxt + h1 * syt + h2 * stt
    return (xx + a * (2.0 * xt + a * tt) + (gs0 * g0 + gs1 * g1 + gs2 * g2),
            xy + a * yt + b * xt + a * b * tt + (gs0 * h0 + gs1 * h1 + gs2 * h2),
            xt + a * tt + gs2,
            yy + b * (2.0 * yt + b * tt) + (hs0 * h0 + hs1 * h1 + hs2 * h2),
            yt + b * tt + hs2,
            tt + stt)


def turn_slip(model: NoiseModel, track_width: float, dx: float, dtheta: float):
    """
    Return the turn and slip terms of one step's body covariance: position and heading.

    ``(slip w |dtheta|, turn |dtheta|)`` (m^2 on each of ``dx``, ``dy``; rad^2), the terms
    of :func:`step_covariance` beyond the track random walk and the floor; ``dx``, ``dtheta``
    the step's body increments (m, rad).
    """
    turned = abs(dtheta)
    if turned == 0.0:
        return 0.0, 0.0
    return model.slip * turned * turned / (turned + abs(dx) / track_width), model.turn * turned


def turn_slip_step(p, position: float, heading: float, m):
    """
    Add body variances ``diag(position, position, heading)`` through a step: ``p + M S M^T``.

    ``p`` is a propagated pose covariance (upper triangle ``(xx, xy, xt, yy, yt, tt)``), ``m``
    :func:`.covariance.arc_step`'s Jacobian (the node adds :func:`turn_slip` this way to its
    track random walk, whose two tracks may differ).
    """
    (g0, g1, g2), (h0, h1, h2) = m
    xx, xy, xt, yy, yt, tt = p
    return (xx + (position * (g0 * g0 + g1 * g1) + heading * g2 * g2),
            xy + (position * (g0 * h0 + g1 * h1) + heading * g2 * h2),
            xt + heading * g2,
            yy + (position * (h0 * h0 + h1 * h1) + heading * h2 * h2),
            yt + heading * h2,
            tt + heading)


def timing_covariance(model: NoiseModel, v_x: float, v_y: float, w: float):
    """
    Return ``timing v v^T`` as an upper triangle: what a published pose covariance adds.

    ``v = (v_x, v_y, w)`` is the pose rate in the frame of the covariance (the fixed frame:
    m/s, m/s, rad/s). Not accumulated: the node adds it to the covariance it publishes
    (the time error at the end), and starts a reset from it (the time error at the start).
    """
    k = model.timing
    return (k * v_x * v_x, k * v_x * v_y, k * v_x * w, k * v_y * v_y, k * v_y * w, k * w * w)


def published_covariance(upper, pose, twist, start_twist, model: NoiseModel | None):
    """
    Return the pose covariance published: ``upper``, the time error at both ends, the scale.

    The time error (variance ``model.timing``, s^2) at the end moves the pose by its fixed-
    frame rate (``twist`` rotated by ``pose``'s heading); at the start (the reset) it moves
    the start pose by ``start_twist`` and turns it by ``w0 dt``, which swings the whole
    displacement ``(x, y)`` since: ``(u_x - w0 y, u_y + w0 x, w0)`` (the lever arm). Both
    independent, not accumulated. A distance scale off by a relative error of variance
    ``model.scale`` moves ``(x, y)`` by ``scale (x, y)(x, y)^T`` (the pose is since the reset),
    a scale and crab angle of variance ``model.drift`` by ``drift (x^2 + y^2) I``. ``model``
    None: ``upper`` unchanged.
    """
    if model is None or not model.beside_the_steps:
        return upper
    x, y, theta = pose
    k = model.scale
    d = model.drift * (x * x + y * y)
    upper = (upper[0] + k * x * x + d, upper[1] + k * x * y, upper[2],
             upper[3] + k * y * y + d, upper[4], upper[5])
    v_x, v_y, w = twist
    c, s = math.cos(theta), math.sin(theta)
    end = timing_covariance(model, c * v_x - s * v_y, s * v_x + c * v_y, w)
    u_x, u_y, w0 = start_twist
    start = timing_covariance(model, u_x - w0 * y, u_y + w0 * x, w0)
    return saturate(tuple(p + e + s0 for p, e, s0 in zip(upper, end, start)))


def _prefix(values):
    """Cumulative sums with a leading zero along axis 0."""
    values = np.asarray(values, float)
    return np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(values, axis=0)])


def window_bases(icr: IcrParams, d_left, d_right, dt, start, end):
    """
    Pose-covariance bases of windows of a path: one 3 x 3 matrix per window and term.

    The path is the odometry of the steps (from the origin); a window runs from step
    boundary ``start`` to ``end``. The covariance of its final pose relative to its start,
    linearised about the path (module docstring), is ``sum_m c_m A[:, m]`` in the frame of
    the heading at ``start``, for the constants ``c`` of :data:`TERMS`; the ``floor`` is
    left out (negligible while moving). Vectorised over the windows with cumulative sums;
    the steps are integrated with the midpoint heading (they are short).

    Parameters
    ----------
    icr : IcrParams
        Kinematic model.
    d_left, d_right : ndarray, shape (N,)
        Nominal travel of each track over each step, m.
    dt : ndarray, shape (N,)
        Duration of each step, s (> 0), for the rates of the timing term.
    start, end : ndarray of int, shape (W,)
        Step boundaries (0..N) of each window, ``start < end``.

    Returns
    -------
    bases : ndarray, shape (W, len(TERMS), 3, 3)
        Of the final pose ``(x, y, theta)`` relative to the window's start.
    motion : ndarray, shape (W, 3)
        The odometry's motion over each window in the frame of its start: ``(x, y, theta)``.

    """
    d_left = np.asarray(d_left, float)
    d_right = np.asarray(d_right, float)
    start = np.asarray(start, np.intp)
    end = np.asarray(end, np.intp)
    b = np.asarray(body_jacobian(icr))
    body = np.column_stack([d_left, d_right]) @ b.T                     # (N, 3)
    dth = body[:, 2]
    heading = np.concatenate([[0.0], np.cumsum(dth)])
    mid = heading[:-1] + 0.5 * dth
    c, s = np.cos(mid), np.sin(mid)
    px = np.concatenate([[0.0], np.cumsum(c * body[:, 0] - s * body[:, 1])])
    py = np.concatenate([[0.0], np.cumsum(s * body[:, 0] + c * body[:, 1])])
    # A heading error of step k acts from its middle; its lever arm to the window's end is
    # q_end - q_k, with q = perp(p) = (-y, x).
    q = np.column_stack([-0.5 * (py[:-1] + py[1:]), 0.5 * (px[:-1] + px[1:])])
    qe = np.column_stack([-py[end], px[end]])
    rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (N, 2, 2)
    steps = _step_covariances(icr, d_left, d_right)

    def over(values):
        prefix = _prefix(values)
        return prefix[end] - prefix[start]

    bases = np.zeros((len(start), len(TERMS), 3, 3))
    for k in range(steps.shape[1]):
        sk = steps[:, k]
        # Position block in the fixed frame: R S_pp R^T; position-heading: R S_pt.
        pp = rot @ sk[:, :2, :2] @ np.swapaxes(rot, 1, 2)
        cross = (rot @ sk[:, :2, 2:3])[:, :, 0]
        v = sk[:, 2, 2]
        sum_c = over(cross)
        sum_v = over(v)
        sum_vq = over(v[:, None] * q)
        # sum_k c_k (qe - q_k)^T and sum_k v_k (qe - q_k)(qe - q_k)^T
        cross_term = sum_c[:, :, None] * qe[:, None, :] - over(cross[:, :, None] * q[:, None, :])
        heading_term = (sum_v[:, None, None] * qe[:, :, None] * qe[:, None, :]
                        - qe[:, :, None] * sum_vq[:, None, :]
                        - sum_vq[:, :, None] * qe[:, None, :]
                        + over(v[:, None, None] * q[:, :, None] * q[:, None, :]))
        bases[:, k, :2, :2] = (over(pp) + cross_term + np.swapaxes(cross_term, 1, 2)
                               + heading_term)
        bases[:, k, :2, 2] = sum_c + qe * sum_v[:, None] - sum_vq
        bases[:, k, 2, :2] = bases[:, k, :2, 2]
        bases[:, k, 2, 2] = sum_v
    # Timing: the pose rate at each end (that of the step ending there), fixed frame. At the
    # start a time error also turns the start heading by w0 dt, which swings the whole
    # displacement since: the lever arm (-w0 dy, w0 dx), as published_covariance's.
    rate = body / np.asarray(dt, float)[:, None]
    k = TERMS.index('timing')
    lever_x, lever_y = px[end] - px[start], py[end] - py[start]
    for at in (start, end):
        step = np.clip(at - 1, 0, len(dth) - 1)
        h = heading[at]
        u = np.column_stack([np.cos(h) * rate[step, 0] - np.sin(h) * rate[step, 1],
                             np.sin(h) * rate[step, 0] + np.cos(h) * rate[step, 1],
                             rate[step, 2]])
        if at is start:
            u[:, 0] -= rate[step, 2] * lever_y
            u[:, 1] += rate[step, 2] * lever_x
        bases[:, k] += u[:, :, None] * u[:, None, :]
    # Scale: the displacement over the window, fully correlated (published_covariance's).
    k = TERMS.index('scale')
    bases[:, k, 0, 0] = lever_x * lever_x
    bases[:, k, 0, 1] = bases[:, k, 1, 0] = lever_x * lever_y
    bases[:, k, 1, 1] = lever_y * lever_y
    # To the frame of the window's start heading.
    h0 = heading[start]
    c0, s0 = np.cos(h0), np.sin(h0)
    r0 = np.zeros((len(start), 3, 3))
    r0[:, 0, 0], r0[:, 0, 1], r0[:, 1, 0], r0[:, 1, 1], r0[:, 2, 2] = c0, s0, -s0, c0, 1.0
    bases = r0[:, None] @ bases @ np.swapaxes(r0, 1, 2)[:, None]
    dx, dy = px[end] - px[start], py[end] - py[start]
    motion = np.column_stack([c0 * dx + s0 * dy, -s0 * dx + c0 * dy, heading[end] - h0])
    return 0.5 * (bases + np.swapaxes(bases, 2, 3)), motion


def covariances(bases, model: NoiseModel, floor: float = 1e-12) -> np.ndarray:
    """
    Return the windows' position covariances ``sum_m c_m A_m`` (W, 2, 2) of a model, m^2.

    ``floor`` (m^2) is added on the diagonal so that a window without motion stays
    invertible.
    """
    cov = np.einsum('wmij,m->wij', bases[:, :, :2, :2], model.constants)
    cov[:, 0, 0] += floor
    cov[:, 1, 1] += floor
    return cov


def nees(errors_xy, covariances_xy) -> np.ndarray:
    """
    Normalised estimation error squared of 2-D errors, ``e^T P^-1 e``, one per window.

    Parameters
    ----------
    errors_xy : array_like, shape (W, 2)
        Final position errors, m.
    covariances_xy : array_like, shape (W, 2, 2)
        Their published covariances, m^2.

    """
    e = np.asarray(errors_xy, float)
    p = np.asarray(covariances_xy, float)
    a, b, d = p[:, 0, 0], p[:, 0, 1], p[:, 1, 1]
    det = a * d - b * b
    return (d * e[:, 0] ** 2 - 2.0 * b * e[:, 0] * e[:, 1] + a * e[:, 1] ** 2) / det


def consistency(errors_xy, covariances_xy) -> dict:
    """
    How often windowed position errors fall inside the published ellipses.

    The share of windows whose error is inside the 50 % and the 95 % ellipse of its
    covariance (NEES below the chi-square quantiles of 2 degrees of freedom, 1.386 and
    5.991) and the mean NEES (2 for a consistent covariance, Bar-Shalom et al. 2001,
    sec. 5.4).

    Parameters
    ----------
    errors_xy : array_like, shape (W, 2)
        Final position errors of the windows, m (any frame, the covariance's).
    covariances_xy : array_like, shape (W, 2, 2)
        Their covariances, m^2, positive definite.

    Returns
    -------
    dict
        ``inside_50``, ``inside_95`` (fractions), ``mean_nees`` and ``windows`` (the count);
        the figures are None without windows.

    """
    e = np.asarray(errors_xy, float).reshape(-1, 2)
    if len(e) == 0:
        return {'inside_50': None, 'inside_95': None, 'mean_nees': None, 'windows': 0}
    n = nees(e, np.asarray(covariances_xy, float).reshape(-1, 2, 2))
    return {'inside_50': float(np.mean(n <= CHI2_50)), 'inside_95': float(np.mean(n <= CHI2_95)),
            'mean_nees': float(np.mean(n)), 'windows': int(len(n))}


def heading_consistency(errors, variances) -> dict:
    """
    How often windowed heading errors fall inside the published intervals (a gyro reference).

    As :func:`consistency` with one degree of freedom: the shares inside the 50 % and 95 %
    intervals (normalised squared error below 0.455 and 3.841) and the mean normalised
    squared error (1 for a consistent variance).

    Parameters
    ----------
    errors : array_like, shape (W,)
        Final heading errors, rad.
    variances : array_like, shape (W,)
        Their variances, rad^2, > 0.

    """
    e = np.asarray(errors, float).ravel()
    if len(e) == 0:
        return {'inside_50': None, 'inside_95': None, 'mean_nees': None, 'windows': 0}
    n = e * e / np.asarray(variances, float).ravel()
    return {'inside_50': float(np.mean(n <= CHI2_1_50)),
            'inside_95': float(np.mean(n <= CHI2_1_95)), 'mean_nees': float(np.mean(n)),
            'windows': int(len(n))}
