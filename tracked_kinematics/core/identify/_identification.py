"""
Identify motion-model parameters from encoder travel and ground-truth poses.

The method is Martinez et al. (2005), sec. 4.2: cut the log into short segments between
ground-truth samples, predict each segment's pose increment from the encoder travel through
the kinematic model, and choose the parameters that minimise the squared differences to the
measured increments, eq. (17)::

    J(p) = sum_i (dx_i - dx^_i)^2 + (dy_i - dy^_i)^2 + lambda^2 (dphi_i - dphi^_i)^2

where ``lambda`` (m/rad) is the heading weight (the paper sums metres and radians as they
are, ``lambda = 1``). Martinez searched ``p`` with a genetic algorithm; Fink & Stump
(sec. III-A, eqs. 4-5) minimise the same kind of cost by nonlinear least squares with the
sensitivity of the integrated pose to the parameters, which is what :class:`SegmentProblem`
computes, in closed form and for every segment at once:

- the whole log is integrated once (:func:`..integration.integrate`) and each segment's
  predicted increment is the relative pose between its end points, exact because relative
  poses along one integrated path equal integrating each segment from the origin;
- the sensitivity of a segment's end pose is eq. (4) unrolled over the encoder steps: each
  step moves the end through its own chord, and turns everything after it about the point
  where it happened. Both sums are per-segment cumulative sums (``np.add.reduceat``), so one
  evaluation is O(N) and has no Python loop over segments.

The fit is robust (soft-L1 loss with a scale from the median absolute residual), bounded
(tread ICRs outside the track centrelines, so ``0 < chi <= 1``, and scales > 0), and checks
that the data turn and drive straight enough to identify what is fitted. Steering efficiency
from spin-in-place runs (Martinez eq. 16) and a hold-out evaluation by time blocks complete
the module.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import time

import numpy as np
from scipy import optimize

from ..errors import ExcitationError, FitError, IdentificationError
from ..integration import integrate, relative_pose, wrap_angle
from ..kinematics import IcrParams
from ..models import ConstantIcr, make_model, MotionModel

# Models the identification fits, in the order they are reported.
FIT_MODELS = ('effective_wheel_base', 'icr', 'icr_scales', 'general_slip', 'adaptive_icr')
COMPARE_MODELS = ('ideal',) + FIT_MODELS
LOSSES = ('soft_l1', 'huber', 'cauchy', 'linear')
METHODS = ('lsq', 'de')

# Parameters that need turning, and those that need straight driving, to be identified.
_TURNING_PARAMS = {'alpha', 'y_left', 'y_right', 'x', 'p1', 'p2', 'p3', 'p4', 'p5', 'p6',
                   'alpha2', 'alpha3', 'alpha5', 'alpha6', 'alpha8', 'alpha9'}
_STRAIGHT_PARAMS = {'scale_left', 'scale_right', 'alpha1', 'alpha4', 'alpha7'}
# ROS names of the parameters, for messages.
_ROS_NAMES = {'y_left': 'icr.y_left', 'y_right': 'icr.y_right', 'x': 'icr.x',
              'scale_left': 'scale.left', 'scale_right': 'scale.right', 'alpha': 'chi'}


# Data -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Recording:
    """
    One continuous log: cumulative encoder travel and ground-truth poses.

    Attributes
    ----------
    enc_t : ndarray, shape (N,)
        Encoder sample times, s, strictly increasing.
    left, right : ndarray, shape (N,)
        Cumulative nominal travel of each track at those times, m (any offset).
    gt_t : ndarray, shape (M,)
        Ground-truth sample times, s, strictly increasing, on the same clock.
    gt_x, gt_y, gt_yaw : ndarray, shape (M,)
        Pose of base_link in a fixed frame: m, m, rad.
    name : str
        Where it came from (a bag path), for reports.

    """

    enc_t: np.ndarray
    left: np.ndarray
    right: np.ndarray
    gt_t: np.ndarray
    gt_x: np.ndarray
    gt_y: np.ndarray
    gt_yaw: np.ndarray
    name: str = ''

    def __post_init__(self):
        for group in (('enc_t', 'left', 'right'), ('gt_t', 'gt_x', 'gt_y', 'gt_yaw')):
            arrays = [np.asarray(getattr(self, n), dtype=float) for n in group]
            if any(a.ndim != 1 or a.shape != arrays[0].shape for a in arrays):
                raise ValueError(f'{", ".join(group)} must be 1-D arrays of one length')
            for n, a in zip(group, arrays):
                if not np.all(np.isfinite(a)):
                    raise ValueError(f'{n} has non-finite values')
                object.__setattr__(self, n, a)
        for n in ('enc_t', 'gt_t'):
            if np.any(np.diff(getattr(self, n)) <= 0.0):
                raise ValueError(f'{n} must be strictly increasing')

    @property
    def duration(self) -> float:
        """Time covered by both encoders and ground truth, s."""
        start = max(self.enc_t[0], self.gt_t[0]) if len(self.enc_t) and len(self.gt_t) else 0
        end = min(self.enc_t[-1], self.gt_t[-1]) if len(self.enc_t) and len(self.gt_t) else 0
        return float(max(0.0, end - start))


@dataclass(frozen=True)
class Segments:
    """
    Segments of encoder steps with the measured pose increment of each.

    The steps of all segments are stored end to end: segment ``i`` is the steps
    ``start[i]:stop[i]``, every segment has at least one step, and a step belongs to one
    segment. Steps are intervals of constant track speed (linear interpolation of the
    cumulative travel between encoder samples), split at the ground-truth times.

    Attributes
    ----------
    d_left, d_right : ndarray, shape (K,)
        Nominal track travel over each step, m.
    dt : ndarray, shape (K,)
        Step durations, s (> 0).
    start : ndarray of int, shape (S,)
        First step of each segment.
    truth : ndarray, shape (S, 3)
        Measured pose increment ``(dx, dy, dphi)`` of each segment in the frame of its start
        pose: m, m, rad in [-pi, pi).
    t0, t1 : ndarray, shape (S,)
        Segment start and end times, s.
    recording : ndarray of int, shape (S,)
        Index of the recording each segment comes from.

    """

    d_left: np.ndarray
    d_right: np.ndarray
    dt: np.ndarray
    start: np.ndarray
    truth: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    recording: np.ndarray

    def __len__(self):
        return len(self.start)

    @property
    def stop(self) -> np.ndarray:
        """One past the last step of each segment."""
        return np.append(self.start[1:], len(self.dt)).astype(np.intp)

    def per_segment(self, values) -> np.ndarray:
        """Sum per-step ``values`` (shape (K, ...)) over each segment."""
        if len(self) == 0:
            return np.zeros((0,) + np.shape(values)[1:])
        return np.add.reduceat(values, self.start, axis=0)

    @property
    def travel(self) -> np.ndarray:
        """Mean absolute nominal travel of the two tracks over each segment, m."""
        return self.per_segment(0.5 * (np.abs(self.d_left) + np.abs(self.d_right)))

    @property
    def ideal_turn(self) -> np.ndarray:
        """Heading change each segment would have as an ideal drive, in track-width units."""
        return self.per_segment(self.d_right - self.d_left)

    def select(self, mask) -> Segments:
        """Return the segments where ``mask`` is true, their steps kept end to end."""
        mask = np.asarray(mask, dtype=bool)
        lengths = self.stop - self.start
        step_mask = np.repeat(mask, lengths)
        kept_lengths = lengths[mask]
        start = np.concatenate([[0], np.cumsum(kept_lengths)[:-1]]).astype(np.intp)
        return Segments(self.d_left[step_mask], self.d_right[step_mask], self.dt[step_mask],
                        start[:len(kept_lengths)], self.truth[mask], self.t0[mask],
                        self.t1[mask], self.recording[mask])

    @classmethod
    def concatenate(cls, parts) -> Segments:
        """Join segment sets end to end."""
        parts = list(parts)
        offsets = np.cumsum([0] + [len(p.dt) for p in parts[:-1]])
        return cls(
            np.concatenate([p.d_left for p in parts]), np.concatenate([p.d_right for p in parts]),
            np.concatenate([p.dt for p in parts]),
            np.concatenate([p.start + o for p, o in zip(parts, offsets)]).astype(np.intp),
            np.concatenate([p.truth for p in parts]).reshape(-1, 3),
            np.concatenate([p.t0 for p in parts]), np.concatenate([p.t1 for p in parts]),
            np.concatenate([p.recording for p in parts]).astype(np.intp))


def _empty_segments() -> Segments:
    empty = np.zeros(0)
    return Segments(empty, empty, empty, np.zeros(0, np.intp), np.zeros((0, 3)), empty, empty,
                    np.zeros(0, np.intp))


def gap_threshold(times, factor: float = 5.0, floor: float = 0.2) -> float:
    """
    Longest interval between samples that is not a gap: ``max(factor x median, floor)`` s.

    Parameters
    ----------
    times : array_like
        Sample times, s, increasing.
    factor : float
        Multiple of the median sample interval.
    floor : float
        Lower bound, s, so that a fast and regular stream does not call jitter a gap.

    """
    intervals = np.diff(np.asarray(times, dtype=float))
    if len(intervals) == 0:
        return floor
    return float(max(factor * np.median(intervals), floor))


def _boundaries(t, segment_length, gap):
    """Ground-truth sample indices that start/end segments, per gap-free block."""
    breaks = np.flatnonzero(np.diff(t) > gap) + 1
    pairs = []
    for block in np.split(np.arange(len(t)), breaks):
        if len(block) < 2:
            continue
        tb = t[block]
        if segment_length:
            targets = tb[0] + segment_length * np.arange(
                int(np.floor((tb[-1] - tb[0]) / segment_length + 1e-9)) + 1)
            idx = np.unique(np.searchsorted(tb, targets - 1e-9))
            idx = idx[idx < len(tb)]
        else:
            idx = np.arange(len(tb))
        if len(idx) >= 2:
            pairs.append(np.stack([block[idx[:-1]], block[idx[1:]]], axis=1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=np.intp)


def build_segments(recordings, segment_length: float | None = 1.0,
                   max_gap: float | None = None) -> Segments:
    """
    Cut recordings into segments between ground-truth samples, skipping gaps.

    Parameters
    ----------
    recordings : sequence of Recording
        The logs.
    segment_length : float or None
        Target duration, s: each segment runs from a ground-truth sample to the first one
        at least this much later (measured from the start of its gap-free stretch, so
        segments tile it). None or 0: every pair of consecutive ground-truth samples. A
        last segment shorter than half the target is dropped.
    max_gap : float, optional
        Longest interval between two encoder samples, or two ground-truth samples, inside a
        segment, s. Default :func:`gap_threshold` of each stream. Segments over a longer
        interval are skipped (the travel over it is known, its timing is not).

    Returns
    -------
    Segments

    """
    parts = []
    for index, rec in enumerate(recordings):
        if len(rec.enc_t) < 2 or len(rec.gt_t) < 2:
            continue
        inside = np.flatnonzero((rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1]))
        if len(inside) < 2:
            continue
        t = rec.gt_t[inside]
        pairs = _boundaries(t, segment_length, max_gap or gap_threshold(t))
        if len(pairs) == 0:
            continue
        ta, tb = t[pairs[:, 0]], t[pairs[:, 1]]
        keep = np.ones(len(pairs), dtype=bool)
        if segment_length:
            keep &= (tb - ta) >= 0.5 * segment_length
        # Skip segments that contain an encoder gap.
        enc_gap = max_gap or gap_threshold(rec.enc_t)
        gap_at = np.flatnonzero(np.diff(rec.enc_t) > enc_gap)
        if len(gap_at):
            g0, g1 = rec.enc_t[gap_at], rec.enc_t[gap_at + 1]
            last = np.searchsorted(g0, tb, side='left') - 1
            keep &= ~((last >= 0) & (g1[np.maximum(last, 0)] > ta))
        pairs, ta, tb = pairs[keep], ta[keep], tb[keep]
        if len(pairs) == 0:
            continue
        # Steps: encoder times and segment boundaries, one grid.
        lo, hi = np.searchsorted(rec.enc_t, [ta[0], tb[-1]])
        grid = np.union1d(rec.enc_t[lo:hi], np.concatenate([ta, tb]))
        cum_left = np.interp(grid, rec.enc_t, rec.left)
        cum_right = np.interp(grid, rec.enc_t, rec.right)
        first = np.searchsorted(grid, ta)
        last = np.searchsorted(grid, tb)
        lengths = last - first
        steps = np.repeat(first - np.cumsum(np.concatenate([[0], lengths[:-1]])), lengths) \
            + np.arange(lengths.sum())
        gi = inside[pairs]
        truth = np.stack(relative_pose(
            rec.gt_x[gi[:, 0]], rec.gt_y[gi[:, 0]], rec.gt_yaw[gi[:, 0]],
            rec.gt_x[gi[:, 1]], rec.gt_y[gi[:, 1]], rec.gt_yaw[gi[:, 1]]), axis=1)
        parts.append(Segments(
            np.diff(cum_left)[steps], np.diff(cum_right)[steps], np.diff(grid)[steps],
            np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp), truth, ta, tb,
            np.full(len(ta), index, dtype=np.intp)))
    return Segments.concatenate(parts) if parts else _empty_segments()


# The problem ------------------------------------------------------------------------------


def _chord_coefficients(dtheta):
    """
    ``S``, ``C`` of :func:`..integration.arc_chord` and their derivatives in ``dtheta``.

    ``S = sin(t)/t``, ``C = (1 - cos t)/t``; near 0 the derivatives use their series.
    """
    t = np.asarray(dtheta, dtype=float)
    s = np.sinc(t / np.pi)
    c = 0.5 * t * np.sinc(t / (2.0 * np.pi)) ** 2
    small = np.abs(t) < 1e-3
    t_safe = np.where(small, 1.0, t)
    t2 = t * t
    ds = np.where(small, -t / 3.0 + t2 * t / 30.0,
                  (t_safe * np.cos(t_safe) - np.sin(t_safe)) / t_safe ** 2)
    one_minus_cos = 2.0 * np.sin(0.5 * t_safe) ** 2
    dc = np.where(small, 0.5 - t2 / 8.0 + t2 * t2 / 144.0,
                  (t_safe * np.sin(t_safe) - one_minus_cos) / t_safe ** 2)
    return s, c, ds, dc


class SegmentProblem:
    """
    Residuals of Martinez eq. (17) over a set of segments, and their Jacobian.

    Parameters
    ----------
    model : MotionModel
        The motion model whose parameters are fitted.
    segments : Segments
        Steps and measured increments.
    heading_weight : float
        ``lambda`` of eq. (17) as written above, m/rad: a heading residual of 1 rad counts
        as much as a position residual of ``lambda`` metres.

    Notes
    -----
    Residuals are ordered ``[dx_0, dy_0, lambda dphi_0, dx_1, ...]`` (measured minus
    predicted); the heading residual is wrapped to [-pi, pi).

    """

    def __init__(self, model: MotionModel, segments: Segments, heading_weight: float = 1.0):
        if len(segments) == 0:
            raise ValueError('no segments')
        self.model = model
        self.segments = segments
        self.heading_weight = float(heading_weight)
        self._start = segments.start
        self._last = segments.stop - 1
        if not model.linear:
            self._v_left = segments.d_left / segments.dt
            self._v_right = segments.d_right / segments.dt

    def _increments(self, p, with_jacobian):
        """Body increments of every step (K, 3) and, if asked, their Jacobian (K, 3, P)."""
        seg = self.segments
        if self.model.linear:
            if not with_jacobian:
                return np.stack(self.model.twist(p, seg.d_left, seg.d_right), axis=-1), None
            return self.model.twist_and_jacobian(p, seg.d_left, seg.d_right)
        dt = seg.dt
        if not with_jacobian:
            twist = np.stack(self.model.twist(p, self._v_left, self._v_right), axis=-1)
            return twist * dt[:, None], None
        twist, jac = self.model.twist_and_jacobian(p, self._v_left, self._v_right)
        return twist * dt[:, None], jac * dt[:, None, None]

    def predict(self, p) -> np.ndarray:
        """Predicted pose increment of every segment, shape (S, 3), heading unwrapped."""
        u, _ = self._increments(np.asarray(p, float), False)
        x, y, th = (np.concatenate([[0.0], v]) for v in integrate(u[:, 0], u[:, 1], u[:, 2]))
        a, b = self._start, self._last + 1
        dx, dy, _ = relative_pose(x[a], y[a], th[a], x[b], y[b], th[b])
        return np.stack([dx, dy, th[b] - th[a]], axis=1)

    def _weigh(self, diff):
        diff = diff.copy()
        diff[:, 2] = self.heading_weight * wrap_angle(diff[:, 2])
        return diff.ravel()

    def residuals(self, p) -> np.ndarray:
        """Weighted residuals, shape (3 S,)."""
        return self._weigh(self.segments.truth - self.predict(p))

    def jacobian(self, p) -> np.ndarray:
        """
        Jacobian of :meth:`residuals`, shape (3 S, P): Fink & Stump eq. (4), per segment.

        For a segment of steps ``k = a..b`` with body increments ``u_k``, chords ``c_k`` and
        world headings ``th_k`` (before step ``k``), the end position relative to the start
        is ``sum_k R(th_k) c_k`` and the heading change ``sum_k dth_k``. Differentiating,

            d pos / dp = sum_k R(th_k) (dc_k/du_k) (du_k/dp)
                         + J sum_k (P_b - P_k) d(dth_k)/dp,        J = rot(90 deg)

        (a heading change at step ``k`` turns the rest of the segment about ``P_k``, the
        position after it). Expressed in the frame of the segment start.
        """
        p = np.asarray(p, float)
        u, du = self._increments(p, True)
        x, y, th = integrate(u[:, 0], u[:, 1], u[:, 2])
        s, c, ds, dc = _chord_coefficients(u[:, 2])
        heading = th - u[:, 2]
        cos_h, sin_h = np.cos(heading), np.sin(heading)
        # World-frame chord derivative R(th_k) dc_k/du_k, as coefficients of du_k/dp.
        a_th = ds * u[:, 0] - dc * u[:, 1]
        b_th = dc * u[:, 0] + ds * u[:, 1]
        coef = np.stack([cos_h * s - sin_h * c, -cos_h * c - sin_h * s,
                         cos_h * a_th - sin_h * b_th, sin_h * s + cos_h * c,
                         -sin_h * c + cos_h * s, sin_h * a_th + cos_h * b_th, x, y],
                        axis=1)[:, :, None]
        du_x, du_y, g = du[:, 0, :], du[:, 1, :], du[:, 2, :]
        terms = np.empty((len(u), 5, len(p)))
        terms[:, 0] = coef[:, 0] * du_x + coef[:, 1] * du_y + coef[:, 2] * g
        terms[:, 1] = coef[:, 3] * du_x + coef[:, 4] * du_y + coef[:, 5] * g
        terms[:, 2] = g
        terms[:, 3] = coef[:, 6] * g
        terms[:, 4] = coef[:, 7] * g
        w_x, w_y, g_sum, xg, yg = np.moveaxis(self.segments.per_segment(terms), 1, 0)
        b = self._last
        # J (P_b G - sum P_k g_k), J (v_x, v_y) = (-v_y, v_x)
        d_x = w_x - (y[b][:, None] * g_sum - yg)
        d_y = w_y + (x[b][:, None] * g_sum - xg)
        th_a = heading[self._start][:, None]
        cos_a, sin_a = np.cos(th_a), np.sin(th_a)
        jac = np.empty((len(b), 3, len(p)))
        jac[:, 0] = -(cos_a * d_x + sin_a * d_y)
        jac[:, 1] = -(-sin_a * d_x + cos_a * d_y)
        jac[:, 2] = -self.heading_weight * g_sum
        return jac.reshape(-1, len(p))


def robust_cost(residuals, loss: str = 'linear', f_scale: float = 1.0) -> float:
    """
    Cost ``0.5 sum f^2 rho((r / f)^2)`` exactly as ``scipy.optimize.least_squares`` defines it.

    Parameters
    ----------
    residuals : array_like
        Residual vector.
    loss : str
        One of :data:`LOSSES`.
    f_scale : float
        Soft margin between inlier and outlier residuals.

    """
    z = (np.asarray(residuals, dtype=float) / f_scale) ** 2
    if loss == 'linear':
        rho = z
    elif loss == 'soft_l1':
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == 'huber':
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    elif loss == 'cauchy':
        rho = np.log1p(z)
    else:
        raise ValueError(f'loss must be one of {", ".join(LOSSES)}, got {loss!r}')
    return float(0.5 * f_scale ** 2 * np.sum(rho))


# Models, bounds, starting points -------------------------------------------------------


def build_model(name: str, track_width: float, scales=(1.0, 1.0)) -> MotionModel:
    """
    Motion model by name; the ``icr`` model uses the fixed ``scales`` given.

    Parameters
    ----------
    name : str
        A name of :data:`..models.MODEL_NAMES`.
    track_width : float
        m.
    scales : tuple of float
        Encoder scales of a model that does not fit them (``icr``).

    """
    if name == 'icr':
        return ConstantIcr(track_width, with_scales=False, scales=scales)
    return make_model(name, track_width)


def bounds(model: MotionModel):
    """
    Physical bounds for least squares: ``(lower, upper)`` arrays.

    Tread ICRs lie outside the track centrelines (Martinez sec. 3: slip only moves them
    outwards), which keeps ``0 < chi <= 1`` whatever the eccentricity; scales lie in
    [0.5, 2]; the effective wheel-base factor (Fink & Stump) in [0.05, 1]; the adaptive
    model's outward ICR terms ``p1..p4`` are >= 0. General slip is unbounded.
    """
    half = 0.5 * model.track_width
    lo, hi = [], []
    for name in model.param_names:
        lo_hi = {'alpha': (0.05, 1.0), 'y_left': (half, 20 * half), 'y_right': (-20 * half, -half),
                 'x': (-10 * half, 10 * half), 'scale_left': (0.5, 2.0),
                 'scale_right': (0.5, 2.0), 'p1': (0.0, np.inf), 'p2': (0.0, np.inf),
                 'p3': (0.0, np.inf), 'p4': (0.0, np.inf)}.get(name, (-np.inf, np.inf))
        lo.append(lo_hi[0])
        hi.append(lo_hi[1])
    return np.array(lo, float), np.array(hi, float)


def search_box(model: MotionModel):
    """
    Finite search box for a global method (differential evolution): ``(lower, upper)``.

    The physical :func:`bounds`, narrowed to what a tracked vehicle shows: ICRs within
    ``2 B`` of the centre and 1 B ahead or behind, scales within 20 %, general-slip
    coefficients within +-1, adaptive coefficients within 2 B.
    """
    lo, hi = bounds(model)
    b = model.track_width
    box = {'y_left': (0.5 * b, 2 * b), 'y_right': (-2 * b, -0.5 * b), 'x': (-b, b),
           'scale_left': (0.8, 1.2), 'scale_right': (0.8, 1.2),
           'p1': (0.0, 2 * b), 'p2': (0.0, 2 * b), 'p3': (0.0, 2 * b), 'p4': (0.0, 2 * b),
           'p5': (-2 * b, 2 * b), 'p6': (-2 * b, 2 * b)}
    for i, name in enumerate(model.param_names):
        if name in box:
            lo[i], hi[i] = box[name]
        elif not np.isfinite(lo[i]) or not np.isfinite(hi[i]):
            lo[i], hi[i] = -1.0, 1.0
    return lo, hi


def steering_efficiency_guess(segments: Segments, track_width: float) -> float:
    """
    Least-squares ratio of measured to ideal heading change, clipped to [0.2, 1].

    The data's steering efficiency in the sense of Martinez eq. (16), over every segment
    rather than spins only: a starting point for the fit.
    """
    ideal = segments.ideal_turn / track_width
    denom = float(np.dot(ideal, ideal))
    if denom <= 0.0:
        return 1.0
    chi = float(np.dot(segments.truth[:, 2], ideal)) / denom
    return float(np.clip(chi, 0.2, 1.0))


def initial_guess(model: MotionModel, segments: Segments) -> np.ndarray:
    """Start of the fit: ideal drive, with the turning rate scaled to the data's."""
    p = model.initial().astype(float)
    chi = steering_efficiency_guess(segments, model.track_width)
    names = model.param_names
    if 'alpha' in names:
        p[names.index('alpha')] = chi
    if 'y_left' in names:
        half = 0.5 * model.track_width / chi
        p[names.index('y_left')] = half
        p[names.index('y_right')] = -half
    if 'p2' in names and len(segments.dt):
        # Adaptive ICRs: the curvature terms put them where the efficiency guess does, at the
        # median curvature of the turning steps.
        _, curv = model.features(segments.d_left / segments.dt, segments.d_right / segments.dt)
        turning = curv[curv > 1e-3]
        if len(turning):
            outward = 0.5 * model.track_width * (1.0 / chi - 1.0) / float(np.median(turning))
            p[names.index('p2')] = p[names.index('p4')] = outward
    return p


# Excitation --------------------------------------------------------------------------


@dataclass(frozen=True)
class Excitation:
    """
    How much the data move, turn and drive straight.

    Attributes
    ----------
    segments, moving : int
        Segments, and those whose tracks travel at least ``min_travel``.
    distance : float
        Ground-truth distance over moving segments, m.
    turning : float
        Sum of absolute ground-truth heading changes over moving segments, rad.
    straight : float
        Ground-truth distance over moving segments that are nearly straight (turning
        radius above 5 m), m.

    """

    segments: int
    moving: int
    distance: float
    turning: float
    straight: float

    @classmethod
    def of(cls, segments: Segments, min_travel: float):
        """Measure ``segments``."""
        moving = segments.travel >= min_travel
        dist = np.hypot(segments.truth[:, 0], segments.truth[:, 1])[moving]
        turn = np.abs(segments.truth[:, 2])[moving]
        straight = turn <= 0.2 * dist
        return cls(len(segments), int(moving.sum()), float(dist.sum()), float(turn.sum()),
                   float(dist[straight].sum()))


MIN_MOVING_SEGMENTS = 10
MIN_TURNING = 1.0      # rad, summed over moving segments
MIN_STRAIGHT = 1.0     # m of nearly straight driving


def _ros_names(names):
    return ', '.join(_ROS_NAMES.get(n, n) for n in names)


def check_excitation(model: MotionModel, excitation: Excitation) -> None:
    """
    Raise :class:`ExcitationError` when the data cannot identify the model's parameters.

    Turning identifies the ICRs (and any turn-rate parameter); straight driving identifies
    the encoder scales (the forward-speed parameters). The thresholds are deliberately low
    (:data:`MIN_TURNING` rad in total, :data:`MIN_STRAIGHT` m): the fit's own parameter
    uncertainty is checked afterwards (:func:`fit`).
    """
    if excitation.moving < MIN_MOVING_SEGMENTS:
        raise ExcitationError(
            f'too little motion: {excitation.moving} of {excitation.segments} segments move '
            f'(need {MIN_MOVING_SEGMENTS}); drive longer, or check the encoder topic and '
            'sprocket radius')
    turning = [n for n in model.param_names if n in _TURNING_PARAMS]
    if turning and excitation.turning < MIN_TURNING:
        raise ExcitationError(
            f'too little turning to identify {_ros_names(turning)}: the data turn '
            f'{excitation.turning:.2f} rad in total (need {MIN_TURNING:.1f}); drive curves '
            'and turns in place')
    straight = [n for n in model.param_names if n in _STRAIGHT_PARAMS]
    if straight and excitation.straight < MIN_STRAIGHT:
        raise ExcitationError(
            f'too little straight driving to identify {_ros_names(straight)}: '
            f'{excitation.straight:.2f} m of nearly straight motion (need '
            f'{MIN_STRAIGHT:.1f}); drive straight forwards and backwards too')


# Fitting -------------------------------------------------------------------------------


def _mad_sigma(values) -> float:
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(values - np.median(values))))


def auto_heading_weight(residuals, lo: float = 0.25, hi: float = 4.0) -> float:
    """
    Heading weight that puts position and heading residuals on one noise scale, m/rad.

    ``lambda = sigma_position / sigma_heading`` from robust (median absolute deviation)
    spreads of unweighted residuals (``residuals`` with ``lambda = 1``), clipped to
    [``lo``, ``hi``]: eq. (17) then weighs each residual by its own noise, as maximum
    likelihood would. Martinez's unweighted sum is ``lambda = 1``.
    """
    r = np.asarray(residuals, dtype=float).reshape(-1, 3)
    sigma_pos = _mad_sigma(r[:, :2].ravel())
    sigma_head = _mad_sigma(r[:, 2])
    if sigma_pos <= 0.0 or sigma_head <= 0.0:
        return 1.0
    return float(np.clip(sigma_pos / sigma_head, lo, hi))


@dataclass
class FitResult:
    """
    A fitted model and how well it fits.

    Attributes
    ----------
    model : MotionModel
        The model.
    p : ndarray
        Fitted parameters.
    method, loss : str
        Optimiser and loss.
    heading_weight, f_scale : float
        ``lambda`` (m/rad) and the robust loss scale used.
    cost : float
        Final cost (:func:`robust_cost` of the weighted residuals).
    rms_position, rms_heading : float
        Root mean square of the inlier position (m) and heading (rad) residuals.
    segments, inliers : int
        Segments fitted, and those whose residuals are all within 3 ``f_scale``.
    std : ndarray
        Standard errors of the parameters (inf when not identified).
    nfev : int
        Cost evaluations.
    seconds : float
        Wall time of the fit.
    message : str
        The optimiser's last word.

    """

    model: MotionModel
    p: np.ndarray
    method: str = 'lsq'
    loss: str = 'soft_l1'
    heading_weight: float = 1.0
    f_scale: float = 1.0
    cost: float = 0.0
    rms_position: float = 0.0
    rms_heading: float = 0.0
    segments: int = 0
    inliers: int = 0
    std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nfev: int = 0
    seconds: float = 0.0
    message: str = ''

    @property
    def params(self) -> dict[str, float]:
        """Parameters by name."""
        return dict(zip(self.model.param_names, map(float, self.p)))

    @property
    def icr(self) -> IcrParams | None:
        """Return the constant-ICR model equal to the fitted one, or None if there is none."""
        return self.model.as_icr(self.p)


def _standard_errors(jac, residuals, inlier_rows):
    """Compute standard errors from the Jacobian and inlier residuals (inf: unidentified)."""
    n_params = jac.shape[1]
    jac = jac[inlier_rows]
    variance = float(np.sum(residuals[inlier_rows] ** 2)) / max(len(jac) - n_params, 1)
    norms = np.linalg.norm(jac, axis=0)
    std = np.full(n_params, np.inf)
    ok = norms > 0
    while np.any(ok):
        _, sv, vt = np.linalg.svd(jac[:, ok] / norms[ok], full_matrices=False)
        if sv[-1] > 1e-9 * sv[0]:
            cov = (vt.T / sv ** 2) @ vt
            std[ok] = np.sqrt(np.maximum(np.diag(cov) * variance, 0.0)) / norms[ok]
            break
        # Rank deficient: the parameters along the null direction are not identified.
        ok[np.flatnonzero(ok)[np.abs(vt[-1]) > 0.1]] = False
    return std


# Largest standard error that still counts as identified, per parameter kind.
STD_LIMITS = {'icr': 0.1, 'scale': 0.02}   # icr: x track width; scale: absolute


def check_identified(result: FitResult) -> None:
    """Raise :class:`ExcitationError` for an ICR or scale parameter the fit did not pin down."""
    b = result.model.track_width
    for name, std in zip(result.model.param_names, result.std):
        if name in ('y_left', 'y_right', 'x'):
            limit, need = STD_LIMITS['icr'] * b, 'turning'
        elif name in ('scale_left', 'scale_right'):
            limit, need = STD_LIMITS['scale'], 'straight driving'
        elif name == 'alpha':
            limit, need = STD_LIMITS['icr'], 'turning'
        else:
            continue
        if not std <= limit:
            raise ExcitationError(
                f'too little {need} to identify {_ros_names([name])}: its standard error is '
                f'{std:.3g} (limit {limit:.3g}); drive more, and more varied, '
                f'{"curves and turns in place" if need == "turning" else "straight lines"}')


def fit(model: MotionModel, segments: Segments, *, p0=None, method: str = 'lsq',
        heading_weight: float | None = None, loss: str = 'soft_l1',
        f_scale: float | None = None, max_nfev: int | None = None, rounds: int = 2,
        seed: int = 0, check: bool = True) -> FitResult:
    """
    Fit a motion model to segments: robust, bounded least squares of Martinez eq. (17).

    Parameters
    ----------
    model : MotionModel
        What to fit.
    segments : Segments
        The data (stationary segments should already be removed).
    p0 : array_like, optional
        Starting point; default :func:`initial_guess`. Clipped into :func:`bounds`.
    method : {'lsq', 'de'}
        ``'lsq'``: trust-region least squares with the analytic Jacobian
        (:meth:`SegmentProblem.jacobian`). ``'de'``: scipy's differential evolution over
        :func:`search_box`, the derivative-free global search in the spirit of the paper's
        genetic algorithm; much slower, offered for comparison.
    heading_weight : float, optional
        ``lambda``, m/rad. Default: :func:`auto_heading_weight` of the residuals of the
        first round.
    loss : str
        One of :data:`LOSSES`; soft-L1 by default, so that ground-truth glitches do not pull
        the fit.
    f_scale : float, optional
        Loss scale. Default: twice the robust standard deviation of the weighted residuals
        at the start of each round.
    max_nfev : int, optional
        Evaluation budget per round (least squares). Default 100 x (parameters + 1).
    rounds : int
        Rounds of (re)estimating ``lambda`` and ``f_scale`` then fitting, warm-started.
    seed : int
        Seed of the differential evolution.
    check : bool
        Raise :class:`ExcitationError` when a parameter is not identified (its standard
        error is beyond :data:`STD_LIMITS`).

    Raises
    ------
    FitError
        When the optimiser does not converge.
    ExcitationError
        When ``check`` and a parameter is not identified.

    """
    if method not in METHODS:
        raise ValueError(f'method must be one of {", ".join(METHODS)}, got {method!r}')
    if loss not in LOSSES:
        raise ValueError(f'loss must be one of {", ".join(LOSSES)}, got {loss!r}')
    started = time.perf_counter()
    problem = SegmentProblem(model, segments, heading_weight or 1.0)
    lo, hi = bounds(model)
    p = initial_guess(model, segments) if p0 is None else np.asarray(p0, dtype=float)
    p = np.clip(p, lo, hi)
    nfev = 0
    message = 'nothing to fit'
    scale = f_scale or 1.0
    n_rounds = rounds if model.n_params else 1
    for _ in range(n_rounds):
        if heading_weight is None:
            problem.heading_weight = 1.0
            problem.heading_weight = auto_heading_weight(problem.residuals(p))
        r = problem.residuals(p)
        scale = f_scale or max(2.0 * _mad_sigma(r), 1e-9)
        if not model.n_params:
            break
        if method == 'lsq':
            res = optimize.least_squares(
                problem.residuals, p, jac=problem.jacobian, bounds=(lo, hi), loss=loss,
                f_scale=scale, x_scale='jac', method='trf',
                max_nfev=max_nfev or 100 * (model.n_params + 1))
            nfev += res.nfev
            message = res.message
            if res.status <= 0 or not np.all(np.isfinite(res.x)):
                raise FitError(f'the {model.name} fit did not converge: {res.message} '
                               f'({res.nfev} evaluations)')
            p = res.x
        else:
            box_lo, box_hi = search_box(model)
            res = optimize.differential_evolution(
                lambda q: robust_cost(problem.residuals(q), loss, scale),
                list(zip(box_lo, box_hi)), seed=seed, polish=False, tol=1e-8,
                maxiter=max_nfev or 300)
            nfev += res.nfev
            message = res.message
            if not res.success or not np.all(np.isfinite(res.x)):
                raise FitError(f'the {model.name} fit did not converge: {res.message} '
                               f'({res.nfev} evaluations)')
            p = res.x
    r = problem.residuals(p)
    rows = np.abs(r.reshape(-1, 3)) <= 3.0 * scale
    inlier = rows.all(axis=1)
    if not np.any(inlier):
        inlier[:] = True
    r3 = r.reshape(-1, 3)
    result = FitResult(
        model=model, p=p, method=method, loss=loss, heading_weight=problem.heading_weight,
        f_scale=scale, cost=robust_cost(r, loss, scale),
        rms_position=float(np.sqrt(np.mean(r3[inlier, :2] ** 2))),
        rms_heading=float(np.sqrt(np.mean(r3[inlier, 2] ** 2))) / problem.heading_weight,
        segments=len(segments), inliers=int(inlier.sum()), nfev=nfev,
        message=str(message))
    if model.n_params:
        result.std = _standard_errors(problem.jacobian(p), r, np.repeat(inlier, 3))
    result.seconds = time.perf_counter() - started
    if check:
        check_identified(result)
    return result


# Evaluation ------------------------------------------------------------------------------


@dataclass(frozen=True)
class ErrorStats:
    """
    Final-pose errors of a model over segments (or windows).

    Attributes
    ----------
    n : int
        Number of segments.
    position_mean, position_p90 : float
        Mean and 90th percentile of the final position error, m.
    heading_mean, heading_p90 : float
        Mean and 90th percentile of the absolute final heading error, rad.

    """

    n: int
    position_mean: float
    position_p90: float
    heading_mean: float
    heading_p90: float

    @classmethod
    def of(cls, position, heading):
        """Statistics of per-segment errors."""
        position = np.asarray(position, float)
        heading = np.abs(np.asarray(heading, float))
        if len(position) == 0:
            return cls(0, float('nan'), float('nan'), float('nan'), float('nan'))
        return cls(len(position), float(position.mean()), float(np.percentile(position, 90)),
                   float(heading.mean()), float(np.percentile(heading, 90)))

    def improvement_over(self, baseline: ErrorStats) -> dict[str, float]:
        """Percent reduction of the mean errors relative to ``baseline``."""
        def pct(ours, theirs):
            return float(100.0 * (1.0 - ours / theirs)) if theirs > 0 else 0.0
        return {'position': pct(self.position_mean, baseline.position_mean),
                'heading': pct(self.heading_mean, baseline.heading_mean)}


def prediction_errors(model: MotionModel, p, segments: Segments):
    """
    Compute the final position (m) and heading (rad, absolute) error of each prediction.

    Returns
    -------
    position, heading : ndarray, shape (S,)

    """
    if len(segments) == 0:
        return np.zeros(0), np.zeros(0)
    diff = segments.truth - SegmentProblem(model, segments).predict(p)
    return np.hypot(diff[:, 0], diff[:, 1]), np.abs(wrap_angle(diff[:, 2]))


@dataclass(frozen=True)
class HoldOut:
    """
    Time blocks held out of the fit, to measure how well a model predicts unseen data.

    Attributes
    ----------
    blocks : ndarray, shape (B, 3)
        ``(recording, t_start, t_end)`` of each held-out block.
    total_blocks : int
        Blocks the data were cut into.

    """

    blocks: np.ndarray
    total_blocks: int

    @classmethod
    def choose(cls, segments: Segments, fraction: float = 0.2, block_length: float = 30.0):
        """
        Cut the data into blocks of about ``block_length`` s and hold out evenly spaced ones.

        Returns None when there are fewer than 3 blocks (too little data to spare any).
        """
        if len(segments) == 0 or fraction <= 0.0:
            return None
        spans = []
        for rec in np.unique(segments.recording):
            mine = segments.recording == rec
            t0, t1 = float(segments.t0[mine].min()), float(segments.t1[mine].max())
            n = max(1, int(round((t1 - t0) / block_length)))
            edges = np.linspace(t0, t1, n + 1)
            spans += [(rec, edges[i], edges[i + 1]) for i in range(n)]
        if len(spans) < 3:
            return None
        k = min(len(spans) - 1, max(1, int(round(fraction * len(spans)))))
        chosen = np.floor((np.arange(k) + 0.5) * len(spans) / k).astype(int)
        return cls(np.array([spans[i] for i in chosen], dtype=float), len(spans))

    def inside(self, segments: Segments) -> np.ndarray:
        """Segments entirely within a held-out block."""
        mask = np.zeros(len(segments), dtype=bool)
        for rec, t0, t1 in self.blocks:
            mask |= (segments.recording == rec) & (segments.t0 >= t0 - 1e-9) \
                & (segments.t1 <= t1 + 1e-9)
        return mask

    def outside(self, segments: Segments) -> np.ndarray:
        """Segments that do not overlap any held-out block."""
        mask = np.ones(len(segments), dtype=bool)
        for rec, t0, t1 in self.blocks:
            mask &= ~((segments.recording == rec) & (segments.t1 > t0 + 1e-9)
                      & (segments.t0 < t1 - 1e-9))
        return mask


# Spin in place ---------------------------------------------------------------------------


@dataclass(frozen=True)
class SpinResult:
    """
    Steering efficiency from spin-in-place runs, Martinez eq. (16).

    Attributes
    ----------
    chi : float
        Mean of the runs' efficiencies (the paper averages several tests).
    chi_std : float
        Their standard deviation.
    runs : list of dict
        Per run: ``recording``, ``t0``, ``t1`` (s), ``angle`` (rad, ground truth),
        ``travel_difference`` (m, ``int V_r - int V_l``), ``chi``.

    """

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

    ``chi = L phi / (int V_r dt - int V_l dt)``, with ``phi`` the turned angle from ground
    truth and ``V`` the true track speeds (nominal travel times ``scales``). A spin run is a
    stretch where the tracks turn in opposite directions at nearly equal speeds
    (``|V_l + V_r| <= balance |V_r - V_l|``); it is measured between the first and the last
    ground-truth sample inside it, and kept when it turns at least ``min_angle`` rad.

    Raises
    ------
    ExcitationError
        When no spin run is found.
    IdentificationError
        When the result is outside (0, 1] (the track width or sprocket radius is wrong).

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


# Dead reckoning ------------------------------------------------------------------------


def dead_reckoning(model: MotionModel, p, recording: Recording):
    """
    Odometry of a whole recording from its first ground-truth pose, at the ground-truth times.

    The encoder travel is interpolated linearly at the ground-truth times (constant speed
    between encoder samples) and integrated along arcs, through gaps too.

    Returns
    -------
    t, x, y, yaw : ndarray
        Ground-truth times covered by the encoders and the odometry pose at each.

    """
    rec = recording
    inside = np.flatnonzero((rec.gt_t >= rec.enc_t[0]) & (rec.gt_t <= rec.enc_t[-1]))
    if len(inside) == 0:
        empty = np.zeros(0)
        return empty, empty, empty, empty
    t = rec.gt_t[inside]
    lo, hi = np.searchsorted(rec.enc_t, [t[0], t[-1]])
    grid = np.union1d(rec.enc_t[lo:hi], t)
    d_left = np.diff(np.interp(grid, rec.enc_t, rec.left))
    d_right = np.diff(np.interp(grid, rec.enc_t, rec.right))
    g0 = inside[0]
    x, y, yaw = model.integrate(p, d_left, d_right, np.diff(grid),
                                pose0=(rec.gt_x[g0], rec.gt_y[g0], rec.gt_yaw[g0]))
    x = np.concatenate([[rec.gt_x[g0]], x])
    y = np.concatenate([[rec.gt_y[g0]], y])
    yaw = np.concatenate([[rec.gt_yaw[g0]], yaw])
    at = np.searchsorted(grid, t)
    return t, x[at], y[at], yaw[at]


# The whole procedure -----------------------------------------------------------------


@dataclass
class ModelEvaluation:
    """
    One model fitted on the training blocks and measured on the held-out ones.

    Attributes
    ----------
    name : str
        Model name.
    fit : FitResult or None
        The training fit (None for ``ideal``, or when it failed: see ``error``).
    segments, windows : ErrorStats or None
        Errors per held-out segment and per held-out window.
    error : str
        Why the fit failed, or ''.

    """

    name: str
    fit: FitResult | None = None
    segments: ErrorStats | None = None
    windows: ErrorStats | None = None
    error: str = ''


@dataclass
class Identification:
    """
    Result of :func:`identify`.

    Attributes
    ----------
    fit : FitResult
        The requested model, fitted on all moving segments.
    icr : IcrParams
        The terrain model to write: the fitted model itself when it is a constant-ICR model,
        otherwise the ``icr_scales`` fit of the same data (see ``icr_source``).
    icr_source : str
        Name of the model ``icr`` comes from.
    excitation : Excitation
        How much the data move and turn.
    holdout : HoldOut or None
        The held-out blocks (None when the data are too short to spare any).
    evaluations : list of ModelEvaluation
        Every compared model on the held-out blocks, ``ideal`` first.
    segment_length, window : float
        Segment and evaluation window durations, s.
    seconds : dict
        Wall time of each phase, s.

    """

    fit: FitResult
    icr: IcrParams
    icr_source: str
    excitation: Excitation
    holdout: HoldOut | None
    evaluations: list
    segment_length: float | None
    window: float
    seconds: dict

    def evaluation(self, name: str) -> ModelEvaluation | None:
        """Return the evaluation of one model, or None."""
        return next((e for e in self.evaluations if e.name == name), None)


def identify(recordings, model: str = 'icr_scales', track_width: float = 0.42, *,
             base: IcrParams | None = None, method: str = 'lsq',
             segment_length: float | None = 1.0, heading_weight: float | None = 1.0,
             loss: str = 'soft_l1', min_travel: float = 0.01, holdout: float = 0.2,
             holdout_block: float = 30.0, window: float = 10.0, compare=COMPARE_MODELS,
             max_nfev: int | None = None) -> Identification:
    """
    Identify a terrain model from recordings: check, hold out, compare, fit.

    1. Cut the recordings into segments (:func:`build_segments`) and drop stationary ones
       (both tracks travel less than ``min_travel``): they carry no information and would
       shrink the robust scale.
    2. Check the excitation for ``model`` (:func:`check_excitation`).
    3. Fit ``model`` on all moving segments, starting from ``base`` when given.
    4. Hold out time blocks (:class:`HoldOut`), fit every model of ``compare`` on the rest
       with the heading weight of step 3 (one round of robust least squares each) and
       measure each on the held-out segments and on held-out windows of ``window`` s.

    Parameters
    ----------
    recordings : sequence of Recording
        The data.
    model : str
        Model to fit (a name of :data:`FIT_MODELS`, or ``symmetric``).
    track_width : float
        m.
    base : IcrParams, optional
        Starting point, and the fixed scales of the ``icr`` model.
    method, loss, max_nfev
        See :func:`fit`.
    heading_weight : float or None
        ``lambda`` of eq. (17), m/rad; None for :func:`auto_heading_weight`. The default,
        1 m/rad, is the paper's unweighted sum. On simulated data with a model mismatch
        (adaptive ICRs fitted by constant ones) and ground-truth noise, it gave held-out
        odometry as good as any other weight tried (0.3 to 3), while the noise-balancing
        ``auto`` weight dropped to its floor on long segments, where the position residuals
        of the mismatch grow, and cost 10 % of final position accuracy.
    segment_length : float or None
        See :func:`build_segments`.
    min_travel : float
        Stationary threshold, m.
    holdout : float
        Fraction of the time blocks held out; 0 disables the evaluation.
    holdout_block : float
        Block duration, s.
    window : float
        Evaluation window, s.
    compare : sequence of str
        Models evaluated on the held-out blocks.

    Raises
    ------
    ExcitationError, FitError
        See :func:`check_excitation` and :func:`fit`.

    """
    seconds = {}
    started = time.perf_counter()
    scales = (base.scale_left, base.scale_right) if base is not None else (1.0, 1.0)
    target = build_model(model, track_width, scales)
    all_segments = build_segments(recordings, segment_length)
    excitation = Excitation.of(all_segments, min_travel)
    check_excitation(target, excitation)
    segments = all_segments.select(all_segments.travel >= min_travel)
    seconds['segments'] = time.perf_counter() - started

    def start_of(m):
        if base is None or not isinstance(m, ConstantIcr):
            return None
        return m.from_icr(base)

    options = {'method': method, 'loss': loss, 'max_nfev': max_nfev}
    started = time.perf_counter()
    result = fit(target, segments, p0=start_of(target), heading_weight=heading_weight,
                 **options)
    # Every other fit weighs heading as this one does (its loss scale is its own: a worse
    # model has larger residuals, which are not outliers).
    options['heading_weight'] = result.heading_weight
    try:
        icr, source = result.icr, target.name
        if icr is None:
            icr_model = build_model('icr_scales', track_width)
            try:
                icr = fit(icr_model, segments, p0=start_of(icr_model), **options).icr
            except ExcitationError:
                icr_model = build_model('icr', track_width, scales)
                icr = fit(icr_model, segments, p0=start_of(icr_model), **options).icr
            source = icr_model.name
    except ValueError as err:
        if isinstance(err, IdentificationError):
            raise
        raise FitError(f'the fit gave an invalid ICR model: {err}') from None
    seconds['fit'] = time.perf_counter() - started

    started = time.perf_counter()
    held = HoldOut.choose(segments, holdout, holdout_block) if holdout > 0 else None
    evaluations = []
    if held is not None:
        train = segments.select(held.outside(segments))
        test = segments.select(held.inside(segments))
        windows = build_segments(recordings, window)
        windows = windows.select(held.inside(windows) & (windows.travel >= min_travel))
        for name in compare:
            evaluation = ModelEvaluation(name)
            m = build_model(name, track_width, scales)
            try:
                if m.n_params:
                    evaluation.fit = fit(m, train, p0=start_of(m), check=False, rounds=1,
                                         **options)
                    p = evaluation.fit.p
                else:
                    p = m.initial()
                evaluation.segments = ErrorStats.of(*prediction_errors(m, p, test))
                evaluation.windows = ErrorStats.of(*prediction_errors(m, p, windows))
            except IdentificationError as err:
                evaluation.error = str(err)
            evaluations.append(evaluation)
    seconds['holdout'] = time.perf_counter() - started
    return Identification(result, icr, source, excitation, held, evaluations, segment_length,
                          window, seconds)
