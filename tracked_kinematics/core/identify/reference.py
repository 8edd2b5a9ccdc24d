"""
Identification without a ground-truth pose: a gyro for heading, GNSS or a straight for distance.

Most tracked and skid-steer robots carry track encoders and an IMU, few a motion-capture or
lidar pose. A gyro sees the heading, exactly what the ICR spread (chi) and a robot that
veers (the right / left scale ratio) change; it sees nothing of how far the robot went
(the distance scale), where the ICRs lie along it (``icr.x``) or sideways (the offset of the
ICR pair). A position reference (GNSS, a pose) or one straight drive of measured length
gives the distance scale, and ``icr.x`` where its noise allows.

The one function a caller needs
-------------------------------
``fit_from_reference(enc_t, left, right, *, track_width, gyro_t=None, gyro_rate=None,
gyro_yaw=None, pose=None, positions=None, straight_distance=None, base=None,
imu_delay='auto', pose_delay='auto', segment_length=1.0, position_window=None, hold=(),
gnss_antenna=(0, 0)) -> ReferenceFit``

Plain arrays in (one recording; :func:`fit_recordings` takes several
:class:`ReferenceRecording`): encoder times (s) and cumulative nominal track travel (m);
gyro stamps (s) and yaw rates (rad/s, REP-103), or yaw angles from an orientation; an
optional pose ``(t, x, y, yaw)`` and optional positions ``(t, x, y)`` in a local plane
(GNSS, :mod:`tracked_kinematics.core.geodesy`). Out: :class:`ReferenceFit`, with ``.icr``
(the :class:`~tracked_kinematics.core.kinematics.IcrParams` to write), ``.determined`` and
``.held`` (lists of ``chi``, ``scale_ratio``, ``distance_scale``, ``icr.x``, ``icr_offset``),
``.reference`` (``'imu'``, ``'imu+gnss'``, ...) and ``.report`` (a JSON-ready dict).
Errors: :class:`~tracked_kinematics.core.errors.SensorDataError` for unusable sensor data
(a gyro all zero or NaN, saturated), ``ExcitationError`` for data that cannot determine
what is asked (too little turning; a "straight" that turns; positions too noisy for the
distance), ``FitError`` for an invalid result; one line each. A node calls, for example::

    fit = fit_from_reference(enc_t, left, right, track_width=0.42, gyro_t=imu_t,
                             gyro_rate=imu_wz, base=current_icr)
    fit.icr, fit.held, fit.report['imu_delay']['delay']

The model
---------
Constant tread ICRs (Martinez et al. 2005, eqs. 7-9 with the scales of eqs. 20-21): over
any interval the heading change is exactly linear in the nominal travel of the tracks,

    dpsi = (s_r D_r - s_l D_l) / W = u (D_r - D_l) + v (D_r + D_l),

with the spread ``W = y_left - y_right``, the *turn gain* ``u = s / W`` (``s`` the distance
scale, ``(s_l + s_r) / 2``) and the *veer* ``v = (s_r - s_l) / (2 W)``. Heading alone gives
``u`` and ``v``: chi ``= track_width u / s`` at the held distance scale, and the scale ratio
``s_r / s_l = (u + v) / (u - v)``. A gyro reads ``dpsi / dt + b`` with a bias ``b``: over
segments of ``segment_length`` s, ``(u, v, b_1 .. b_R)`` (one bias per recording) are
a linear least-squares problem, solved with Huber weights (iterated, :data:`HUBER_K`
robust standard deviations); stationary segments stay in (they time the bias best). The
noise is taken from the data (the robust spread of the residuals per source), so a gyro
and a pose heading are weighted by it when both are given. Veer needs straight driving and
turns; without enough of both (standard error of the ratio above
:data:`RATIO_STD_LIMIT`) the ratio is held.

With positions (GNSS or a pose), the body step over each short interval is
``(s m + c dpsi, -x dpsi)`` with ``m = (D_l + rho D_r) / (1 + rho)``, ``rho`` the scale
ratio of the heading fit, ``c`` the ICR offset ``(y_left + y_right) / 2`` and ``x = icr.x``
(the forward kinematics of docs/model.md), rotated by the gyro heading. Positions are
compared in windows of ``position_window`` s, each centred on its mean (the dead reckoning
drifts; a window does not care where it starts), after a rotation ``theta_R + delta_R t``
per recording and source (the gyro's frame is not the reference's, and a residual bias
turns it slowly). ``s`` is fitted, ``x`` (and ``c`` from a pose) when their standard errors
are below :data:`X_STD_LIMIT`; else they are held. ``W = s / u`` then follows.

``straight_distance`` (m): the recordings are one straight drive of that measured length.
The distance scale is that length over the chord the encoders give; a drive that turns by
more than :data:`MAX_STRAIGHT_TURN` is refused.

Delay: the gyro's stamps against the encoders are estimated by :func:`.delay.estimate_delay`
(heading channel) on the integrated gyro, exactly as the pose delay is, and removed;
``imu_delay`` > 0 means the gyro is stamped late (on the Warthog logs of ../shared/realdata
the encoders trail the gyro by about 0.17 s: ``imu_delay`` about -0.17 s).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.optimize import least_squares

from .delay import DelayEstimate, estimate_delay, fixed_delay
from .segments import gap_threshold, Recording
from ..errors import ExcitationError, FitError, SensorDataError
from ..integration import wrap_angle
from ..kinematics import IcrParams

QUANTITIES = ('chi', 'scale_ratio', 'distance_scale', 'icr.x', 'icr_offset')
"""What a calibration determines or holds (``identification.determined`` / ``held``)."""
HUBER_K = 2.0
"""Huber threshold of the heading fit, in robust standard deviations."""
RATIO_STD_LIMIT = 0.01
"""Largest standard error of the scale ratio at which it counts as determined."""
CHI_REL_STD_LIMIT = 0.05
"""Largest relative standard error of the turn gain at which chi counts as determined."""
DISTANCE_STD_LIMIT = 0.05
"""Largest relative standard error of the distance scale from positions."""
X_STD_LIMIT = 0.02
"""Largest standard error, m, at which ``icr.x`` (and the ICR offset) count as determined."""
MAX_STRAIGHT_TURN = math.radians(15.0)
"""Largest heading excursion, rad, of a drive that counts as straight."""
MIN_TURN = 1.0
"""Least total absolute turning, rad, over the moving segments to fit chi."""
SATURATION_SHARE = 0.005
"""Share of gyro readings stuck at the largest magnitude that means saturation."""
MIN_MOVING_SEGMENTS = 10
"""Fewest moving segments for a heading fit."""
POSITION_WINDOW = {'gnss': 120.0, 'pose': 10.0}
"""Default window of the position comparison, s, per source."""
_MIN_TRAVEL = 0.01


@dataclass(frozen=True)
class ReferenceRecording:
    """
    One recording: encoder travel and the references a robot without ground truth has.

    Attributes
    ----------
    enc_t, left, right : ndarray, shape (N,)
        Encoder times (s, increasing) and cumulative nominal travel per track (m).
    gyro_t : ndarray or None
        Gyro stamps, s, on the encoders' clock.
    gyro_rate : ndarray or None
        Yaw rates, rad/s (counter-clockwise positive).
    gyro_yaw : ndarray or None
        Yaw angles of an orientation estimate, rad, instead of ``gyro_rate``.
    pose : tuple of ndarray or None
        ``(t, x, y, yaw)`` of a pose reference.
    positions : tuple of ndarray or None
        ``(t, x, y)``: positions in a local plane (GNSS), m.
    name : str
        Where it came from, for reports.

    """

    enc_t: np.ndarray
    left: np.ndarray
    right: np.ndarray
    gyro_t: np.ndarray | None = None
    gyro_rate: np.ndarray | None = None
    gyro_yaw: np.ndarray | None = None
    pose: tuple | None = None
    positions: tuple | None = None
    name: str = ''

    def __post_init__(self):
        def arrays(group, names):
            out = [np.asarray(a, dtype=float) for a in group]
            if any(a.ndim != 1 or a.shape != out[0].shape for a in out):
                raise ValueError(f'{", ".join(names)} must be 1-D arrays of one length')
            if np.any(np.diff(out[0]) <= 0) or not np.all(np.isfinite(out[0])):
                raise ValueError(f'{names[0]} must be finite and strictly increasing')
            return out

        enc = arrays((self.enc_t, self.left, self.right), ('enc_t', 'left', 'right'))
        for a, n in zip(enc[1:], ('left', 'right')):
            if not np.all(np.isfinite(a)):
                raise ValueError(f'{n} has non-finite values')
        for n, a in zip(('enc_t', 'left', 'right'), enc):
            object.__setattr__(self, n, a)
        if self.gyro_t is not None:
            if (self.gyro_rate is None) == (self.gyro_yaw is None):
                raise ValueError('give gyro_rate or gyro_yaw with gyro_t')
            values = self.gyro_rate if self.gyro_rate is not None else self.gyro_yaw
            t, v = arrays((self.gyro_t, values), ('gyro_t', 'gyro values'))
            object.__setattr__(self, 'gyro_t', t)
            object.__setattr__(self, 'gyro_rate' if self.gyro_rate is not None
                               else 'gyro_yaw', v)
        if self.pose is not None:
            pose = arrays(self.pose, ('pose t', 'x', 'y', 'yaw'))
            if not all(np.all(np.isfinite(a)) for a in pose):
                raise ValueError('the pose has non-finite values')
            object.__setattr__(self, 'pose', tuple(pose))
        if self.positions is not None:
            pos = arrays(self.positions, ('positions t', 'x', 'y'))
            if not all(np.all(np.isfinite(a)) for a in pos):
                raise ValueError('the positions have non-finite values')
            object.__setattr__(self, 'positions', tuple(pos))


@dataclass
class ReferenceFit:
    """
    Result of :func:`fit_from_reference` / :func:`fit_recordings`.

    Attributes
    ----------
    icr : IcrParams
        The terrain model: fitted where determined, the base values where held.
    reference : str
        ``imu``, ``pose``, ``gnss``, ``straight`` joined by ``+``.
    determined, held : list of str
        Quantities of :data:`QUANTITIES` the references determine / that are held.
    distance_scale, scale_ratio, turn_gain : float
        ``(s_l + s_r) / 2``, ``s_r / s_l``, ``u = s / W`` (rad per m of track difference).
    imu_delay, pose_delay : DelayEstimate
        Delays of the gyro / pose stamps behind the encoders (removed).
    biases : list of float
        Gyro bias per recording, rad/s.
    report : dict
        Everything above and the noise and fit statistics, JSON-ready.

    """

    icr: IcrParams
    reference: str
    determined: list
    held: list
    distance_scale: float
    scale_ratio: float
    turn_gain: float
    imu_delay: DelayEstimate = field(default_factory=lambda: fixed_delay(0.0))
    pose_delay: DelayEstimate = field(default_factory=lambda: fixed_delay(0.0))
    biases: list = field(default_factory=list)
    report: dict = field(default_factory=dict)


# Checks of the sensor data -----------------------------------------------------------------

def check_gyro(rates, what: str = 'the gyro') -> None:
    """
    Refuse yaw rates that cannot be a gyro's: none, or all zero or non-finite.

    Raises
    ------
    SensorDataError
        Naming the problem, one line.

    """
    rates = np.asarray(rates, dtype=float)
    finite = rates[np.isfinite(rates)]
    if rates.size == 0:
        raise SensorDataError(f'{what}: no readings')
    if finite.size < 0.5 * rates.size or not np.any(finite != 0.0):
        raise SensorDataError(f'{what}: no angular velocity (the readings are all zero or '
                              'NaN): is angular_velocity.z filled?')


def check_saturation(gyro_t, rates, enc_t, left, right, track_width: float,
                     what: str = 'the gyro') -> None:
    """
    Refuse a saturated gyro: readings stuck at their top while the tracks turn faster.

    A pile-up of readings at exactly the largest magnitude is a saturation when, at those
    readings, the tracks turn markedly faster (the 90th percentile of the turn rate they
    give, through the gyro-to-track ratio of the other readings, above 1.15 x the limit): a
    robot that merely holds a constant turn rate reads the same ratio.

    Raises
    ------
    SensorDataError
        With the number of readings and the limit, one line.

    """
    rates = np.asarray(rates, dtype=float)
    ok = np.isfinite(rates)
    gyro_t, rates = np.asarray(gyro_t, dtype=float)[ok], rates[ok]
    top = float(np.max(np.abs(rates))) if rates.size else 0.0
    if top <= 0:
        return
    stuck = np.abs(np.abs(rates) - top) <= 1e-9 * max(top, 1.0)
    if np.count_nonzero(stuck) < max(3, SATURATION_SHARE * rates.size):
        return
    half = 0.25
    turn = (np.interp(gyro_t + half, enc_t, right - left)
            - np.interp(gyro_t - half, enc_t, right - left)) / (2 * half * track_width)
    strong = np.abs(turn) > 1e-3
    others = ~stuck & strong & (np.abs(rates) > 0.3 * top)
    at_top = stuck & strong
    if np.count_nonzero(at_top) < 3 or np.count_nonzero(others) < 3:
        return
    gain = float(np.median(np.abs(rates[others]) / np.abs(turn[others])))
    expected = float(np.percentile(gain * np.abs(turn[at_top]), 90))
    if expected > 1.15 * top:
        raise SensorDataError(f'{what}: saturated: {np.count_nonzero(stuck)} readings at '
                              f'{top:.4g} rad/s, its limit, while the tracks turn up to '
                              f'{expected:.3g} rad/s; '
                              'turn slower or set a wider gyro range')


# Heading -------------------------------------------------------------------------------------

def _gyro_heading(rec: ReferenceRecording, delay: float):
    """Stamps (delay removed) and continuous heading of the gyro, rad, and the gap limit."""
    t = rec.gyro_t - delay
    if rec.gyro_rate is not None:
        w = rec.gyro_rate
        heading = np.r_[0.0, np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))]
    else:
        heading = np.unwrap(rec.gyro_yaw)
    return t, heading


def _clean_gyro(rec: ReferenceRecording) -> ReferenceRecording:
    """Drop non-finite readings (a few; :func:`check_gyro` refuses many)."""
    values = rec.gyro_rate if rec.gyro_rate is not None else rec.gyro_yaw
    ok = np.isfinite(values)
    if np.all(ok):
        return rec
    key = 'gyro_rate' if rec.gyro_rate is not None else 'gyro_yaw'
    return ReferenceRecording(rec.enc_t, rec.left, rec.right, rec.gyro_t[ok],
                              **{key: values[ok]}, pose=rec.pose, positions=rec.positions,
                              name=rec.name)


def _bad_spans(t, lo, hi):
    """Mask of intervals ``[lo, hi]`` that straddle a gap of the stream ``t``."""
    gap = gap_threshold(t)
    steps = np.diff(t)
    starts, ends = t[:-1][steps > gap], t[1:][steps > gap]
    bad = np.zeros(len(lo), dtype=bool)
    for a, b in zip(starts, ends):
        bad |= (hi > a) & (lo < b)
    return bad | (lo < t[0]) | (hi > t[-1])


@dataclass
class _Segments:
    """Heading segments of all recordings, one source."""

    d_left: np.ndarray
    d_right: np.ndarray
    dt: np.ndarray
    dpsi: np.ndarray
    recording: np.ndarray
    t0: np.ndarray


def _segments(recordings, series, length):
    """Cut the encoders and a heading series per recording into segments of ``length`` s."""
    parts = []
    for r, (rec, s) in enumerate(zip(recordings, series)):
        if s is None:
            continue
        ht, heading = s
        start = max(rec.enc_t[0], ht[0])
        stop = min(rec.enc_t[-1], ht[-1])
        if stop - start < length:
            continue
        edges = start + length * np.arange(int((stop - start) // length) + 1)
        lo, hi = edges[:-1], edges[1:]
        bad = _bad_spans(rec.enc_t, lo, hi) | _bad_spans(ht, lo, hi)
        left, right, psi = (np.interp(edges, x, y) for x, y in
                            ((rec.enc_t, rec.left), (rec.enc_t, rec.right), (ht, heading)))
        keep = ~bad
        parts.append((np.diff(left)[keep], np.diff(right)[keep], (hi - lo)[keep],
                      np.diff(psi)[keep], np.full(int(keep.sum()), r), lo[keep]))
    if not parts:
        empty = np.zeros(0)
        return _Segments(empty, empty, empty, empty, np.zeros(0, dtype=int), empty)
    cols = [np.concatenate(c) for c in zip(*parts)]
    return _Segments(*cols[:4], cols[4].astype(int), cols[5])


def _robust_std(r):
    r = np.asarray(r)
    if r.size == 0:
        return math.inf
    return float(max(1.4826 * np.median(np.abs(r - np.median(r))), 1e-12))


def _heading_fit(sources, n_rec, hold_u=None, hold_ratio=None):
    """
    Weighted robust least squares of the heading: ``(u, v)`` and one bias per gyro recording.

    ``sources``: list of (name, _Segments, has_bias). ``hold_u``: fixed turn gain;
    ``hold_ratio``: fixed ``v / u``. Returns the parameters, their covariance and per-source
    residual statistics.
    """
    rows, ys, src = [], [], []
    n_bias = n_rec
    for k, (name, seg, has_bias) in enumerate(sources):
        diff = seg.d_right - seg.d_left
        total = seg.d_right + seg.d_left
        a = np.zeros((len(seg.dt), 2 + n_bias))
        a[:, 0], a[:, 1] = diff, total
        if has_bias:
            a[np.arange(len(seg.dt)), 2 + seg.recording] = seg.dt
        rows.append(a)
        ys.append(seg.dpsi)
        src.append(np.full(len(seg.dt), k))
    a, y, src = np.vstack(rows), np.concatenate(ys), np.concatenate(src)
    # Hold: u fixed -> move its column to the right-hand side; ratio fixed -> merge columns.
    if hold_u is not None and hold_ratio is not None:
        y = y - hold_u * (a[:, 0] + hold_ratio * a[:, 1])
        design, expand = a[:, 2:], lambda p: np.r_[hold_u, hold_u * hold_ratio, p]
    elif hold_u is not None:
        y = y - hold_u * a[:, 0]
        design, expand = a[:, 1:], lambda p: np.r_[hold_u, p]
    elif hold_ratio is not None:
        design = np.column_stack([a[:, 0] + hold_ratio * a[:, 1], a[:, 2:]])
        expand = lambda p: np.r_[p[0], p[0] * hold_ratio, p[1:]]   # noqa: E731
    else:
        design, expand = a, lambda p: p   # noqa: E731
    used = np.any(design != 0.0, axis=0)
    design = design[:, used]
    weights = np.ones(len(y))
    sigma = np.ones(len(sources))
    for _ in range(6):
        sw = np.sqrt(weights)
        p, *_ = np.linalg.lstsq(design * sw[:, None], y * sw, rcond=None)
        res = y - design @ p
        for k in range(len(sources)):
            sigma[k] = _robust_std(res[src == k])
        z = np.abs(res) / sigma[src]
        weights = np.minimum(1.0, HUBER_K / np.maximum(z, 1e-12)) / sigma[src] ** 2
    cov = np.linalg.pinv(design.T @ (design * weights[:, None]))
    full = np.zeros(used.size)
    full[used] = p
    cov_full = np.zeros((used.size, used.size))
    cov_full[np.ix_(used, used)] = cov
    stats = {name: {'segments': int(np.count_nonzero(src == k)),
                    'residual_std_rad': float(sigma[k]),
                    'rms_rad': float(np.sqrt(np.mean(res[src == k] ** 2)))
                    if np.any(src == k) else None}
             for k, (name, _, _) in enumerate(sources)}
    return expand(full), cov_full, used, stats


def _param_std(cov, used, index):
    """Return the standard error of a design column (NaN when it was not fitted)."""
    if not used[index]:
        return math.nan
    return float(math.sqrt(max(cov[index, index], 0.0)))


# Positions --------------------------------------------------------------------------------

def _dead_reckoning_basis(rec, heading_series, bias, rho, dt=0.05):
    """
    Cumulative sums ``P_A, P_B, P_C`` on a grid: model position = s P_A + c P_B + x P_C.

    In the gyro's frame; heading from the gyro with its bias removed.
    """
    ht, heading = heading_series
    start, stop = max(rec.enc_t[0], ht[0]), min(rec.enc_t[-1], ht[-1])
    grid = np.arange(start, stop + 1e-9, dt)
    if grid.size < 3:
        return None
    left, right = np.interp(grid, rec.enc_t, rec.left), np.interp(grid, rec.enc_t, rec.right)
    psi = np.interp(grid, ht, heading) - bias * (grid - grid[0])
    d_l, d_r, d_psi = np.diff(left), np.diff(right), np.diff(psi)
    m = (d_l + rho * d_r) / (1.0 + rho)
    mid = 0.5 * (psi[1:] + psi[:-1])
    c, s = np.cos(mid), np.sin(mid)
    zero = np.zeros((1, 2))
    pa = np.vstack([zero, np.cumsum(np.column_stack([c * m, s * m]), axis=0)])
    pb = np.vstack([zero, np.cumsum(np.column_stack([c * d_psi, s * d_psi]), axis=0)])
    pc = np.vstack([zero, np.cumsum(np.column_stack([s * d_psi, -c * d_psi]), axis=0)])
    return grid, psi, pa, pb, pc, np.abs(m)


@dataclass
class _PositionBlock:
    """One recording and one position source: basis at the reference samples, windows."""

    source: str
    t: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    g: np.ndarray
    window: np.ndarray
    t0: float
    lever: np.ndarray


def _position_block(source, rec, basis, ref_t, ref_x, ref_y, window_s, antenna=(0.0, 0.0)):
    grid, psi, pa, pb, pc, _ = basis
    inside = (ref_t >= grid[0]) & (ref_t <= grid[-1])
    t = ref_t[inside]
    if t.size < 3:
        return None
    interp = [np.column_stack([np.interp(t, grid, p[:, 0]), np.interp(t, grid, p[:, 1])])
              for p in (pa, pb, pc)]
    g = np.column_stack([ref_x[inside], ref_y[inside]])
    window = np.floor((t - t[0]) / window_s).astype(int)
    # Windows with fewer than 3 samples carry little; merge them into their neighbour.
    counts = np.bincount(window)
    if counts[-1] < 3 and len(counts) > 1:
        window[window == len(counts) - 1] = len(counts) - 2
    # The antenna (or tracked body) sits at ``antenna`` in base_link: it turns with the robot.
    heading = np.interp(t, grid, psi)
    ax, ay = antenna
    lever = np.column_stack([np.cos(heading) * ax - np.sin(heading) * ay,
                             np.sin(heading) * ax + np.cos(heading) * ay])
    return _PositionBlock(source, t, *interp, g, window, float(t[0]), lever)


def _centred(values, window):
    """Subtract each window's mean from ``values`` (shape (n, 2))."""
    n = np.bincount(window).astype(float)
    means = np.column_stack([np.bincount(window, values[:, k]) / np.maximum(n, 1)
                             for k in range(2)])
    return values - means[window]


def _position_fit(blocks, free, fixed, sigma):
    """
    Least squares of the windowed positions: shared ``(s, c, x)``, rotation per block.

    ``free``: names among ('s', 'c', 'x') to fit; ``fixed``: values of the others.
    ``sigma``: noise scale per source (robust loss scale). Returns values, std, residuals.
    """
    names = [n for n in ('s', 'c', 'x') if n in free]
    n_shared = len(names)

    def unpack(p):
        vals = dict(fixed)
        vals.update(zip(names, p[:n_shared]))
        return vals

    def residuals(p):
        vals = unpack(p)
        out = []
        for k, blk in enumerate(blocks):
            theta = p[n_shared + 2 * k] + p[n_shared + 2 * k + 1] * (blk.t - blk.t0)
            model = vals['s'] * blk.a + vals['c'] * blk.b + vals['x'] * blk.c + blk.lever
            co, si = np.cos(theta), np.sin(theta)
            rotated = np.column_stack([co * model[:, 0] - si * model[:, 1],
                                       si * model[:, 0] + co * model[:, 1]])
            r = _centred(rotated - blk.g, blk.window) / sigma[blk.source]
            out.append(r.ravel())
        return np.concatenate(out)

    # Start: each block's rotation from the centred first windows (Procrustes, s = 1).
    p0 = [fixed.get(n, 1.0 if n == 's' else 0.0) for n in names]
    for blk in blocks:
        m = _centred(blk.a * fixed.get('s', 1.0), blk.window)
        g = _centred(blk.g, blk.window)
        theta = math.atan2(float(np.sum(m[:, 0] * g[:, 1] - m[:, 1] * g[:, 0])),
                           float(np.sum(m[:, 0] * g[:, 0] + m[:, 1] * g[:, 1])))
        p0 += [theta, 0.0]
    p0 = np.array(p0, dtype=float)
    sol = least_squares(residuals, p0, loss='soft_l1', f_scale=HUBER_K, x_scale='jac')
    if not sol.success:
        raise FitError(f'the position fit did not converge: {sol.message}')
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac)
    except np.linalg.LinAlgError:
        cov = np.full((len(p0), len(p0)), np.inf)
    # Scale the covariance by the residual spread (the sigma given is a first guess).
    res = sol.fun
    spread = _robust_std(res) ** 2
    std = np.sqrt(np.maximum(np.diag(cov), 0.0) * spread)
    raw = residuals(sol.x)
    per_source = {}
    offset = 0
    for blk in blocks:
        n = 2 * blk.t.size
        per_source.setdefault(blk.source, []).append(raw[offset:offset + n] * sigma[blk.source])
        offset += n
    noise = {k: _robust_std(np.concatenate(v)) for k, v in per_source.items()}
    return unpack(sol.x), dict(zip(names, std[:n_shared])), noise


# The whole calibration -----------------------------------------------------------------

def _delay_of_gyro(rec_list, imu_delay):
    """Estimate (or take) the gyro's delay behind the encoders, as the pose delay is."""
    if not isinstance(imu_delay, str):
        return fixed_delay(float(imu_delay or 0.0))
    if imu_delay != 'auto':
        raise ValueError(f"imu_delay must be seconds or 'auto', got {imu_delay!r}")
    fake = []
    for rec in rec_list:
        t, heading = _gyro_heading(rec, 0.0)
        # Headings every ~0.1 s: the estimator regresses increments between samples.
        step = max(1, int(round(0.1 / max(float(np.median(np.diff(t))), 1e-6))))
        t, heading = t[::step], heading[::step]
        zeros = np.zeros(t.size)
        fake.append(Recording(rec.enc_t, rec.left, rec.right, t, zeros, zeros,
                              wrap_angle(heading), name=rec.name))
    return estimate_delay(fake, channels=('heading',))


def _delay_of_pose(rec_list, pose_delay):
    if not isinstance(pose_delay, str):
        return fixed_delay(float(pose_delay or 0.0))
    if pose_delay != 'auto':
        raise ValueError(f"pose_delay must be seconds or 'auto', got {pose_delay!r}")
    return estimate_delay([Recording(r.enc_t, r.left, r.right, *r.pose, name=r.name)
                           for r in rec_list])


def fit_recordings(recordings, track_width: float, *, base: IcrParams | None = None,
                   imu_delay='auto', pose_delay='auto', segment_length: float = 1.0,
                   straight_distance: float | None = None,
                   position_window: float | None = None, hold=(),
                   gnss_antenna=(0.0, 0.0)) -> ReferenceFit:
    """
    Calibrate from gyro, pose and/or positions over several recordings (module notes).

    Parameters
    ----------
    recordings : sequence of ReferenceRecording
        On one vehicle and terrain; each needs a gyro or a pose (a heading reference).
    track_width : float
        m.
    base : IcrParams, optional
        Values of what is held (default: ideal drive of ``track_width``).
    imu_delay, pose_delay : float or 'auto'
        s of gyro / pose stamps behind the encoders to remove, or 'auto' to estimate.
    segment_length : float
        Heading segments, s.
    straight_distance : float, optional
        The recordings are one straight drive of this many metres.
    position_window : float, optional
        s; default :data:`POSITION_WINDOW` per source.
    hold : sequence of str
        Quantities of :data:`QUANTITIES` to hold at ``base`` even where the data determine
        them (``('scale_ratio',)``: the plain gyro fit of symmetric scales).
    gnss_antenna : pair of float
        Position of the GNSS antenna in base_link, m. It matters: an antenna ``a`` ahead of
        base_link moves with the heading exactly as ICRs ``a`` behind it would
        (``icr.x = -a``), so an unknown lever arm would be fitted as ``icr.x``.

    Returns
    -------
    ReferenceFit

    Raises
    ------
    SensorDataError, ExcitationError, FitError
        See the module notes.

    """
    recs = list(recordings)
    if not recs:
        raise ValueError('no recordings')
    hold = tuple(hold)
    if any(q not in QUANTITIES for q in hold):
        raise ValueError(f'hold must name some of {", ".join(QUANTITIES)}, got {hold!r}')
    if not (math.isfinite(track_width) and track_width > 0):
        raise ValueError(f'track_width must be > 0, got {track_width!r}')
    gnss_antenna = tuple(float(a) for a in gnss_antenna)
    if len(gnss_antenna) != 2 or not all(math.isfinite(a) for a in gnss_antenna):
        raise ValueError(f'gnss_antenna must be two finite numbers (m), got {gnss_antenna!r}')
    if not segment_length > 0:
        raise ValueError(f'segment_length must be > 0, got {segment_length!r}')
    base = base or IcrParams.ideal(track_width)
    has_gyro = [r.gyro_t is not None for r in recs]
    has_pose = [r.pose is not None for r in recs]
    has_pos = [r.positions is not None for r in recs]
    if not all(g or p for g, p in zip(has_gyro, has_pose)):
        raise ValueError('every recording needs a heading reference: a gyro or a pose')
    for r, g in zip(recs, has_gyro):
        if g:
            if r.gyro_rate is not None:
                what = f'{r.name or "recording"}: the gyro'
                check_gyro(r.gyro_rate, what)
                check_saturation(r.gyro_t, r.gyro_rate, r.enc_t, r.left, r.right,
                                 track_width, what)
            elif not np.any(np.isfinite(r.gyro_yaw)):
                raise SensorDataError(f'{r.name or "recording"}: the orientation has no yaw')
    recs = [_clean_gyro(r) if g else r for r, g in zip(recs, has_gyro)]
    if straight_distance is not None and not (math.isfinite(straight_distance)
                                              and straight_distance > 0):
        raise ValueError(f'straight_distance must be > 0 m, got {straight_distance!r}')

    base_s = 0.5 * (base.scale_left + base.scale_right)
    base_rho = base.scale_right / base.scale_left
    base_w = base.y_left - base.y_right
    base_c = 0.5 * (base.y_left + base.y_right)

    # Delays.
    gyro_recs = [r for r, g in zip(recs, has_gyro) if g]
    imu = _delay_of_gyro(gyro_recs, imu_delay) if gyro_recs else fixed_delay(0.0)
    pose_recs = [r for r, p in zip(recs, has_pose) if p]
    pose_d = _delay_of_pose(pose_recs, pose_delay) if pose_recs else fixed_delay(0.0)

    gyro_series = [_gyro_heading(r, imu.delay) if g else None for r, g in zip(recs, has_gyro)]
    pose_series = [(r.pose[0] - pose_d.delay, np.unwrap(r.pose[3])) if p else None
                   for r, p in zip(recs, has_pose)]
    sources = []
    if any(has_gyro):
        sources.append(('imu', _segments(recs, gyro_series, segment_length), True))
    if any(has_pose):
        sources.append(('pose', _segments(recs, pose_series, segment_length), False))
    moving = np.concatenate([0.5 * (np.abs(s.d_left) + np.abs(s.d_right)) >= _MIN_TRAVEL
                             for _, s, _ in sources])
    if np.count_nonzero(moving) < MIN_MOVING_SEGMENTS:
        raise ExcitationError(f'{np.count_nonzero(moving)} moving segments of '
                              f'{segment_length:g} s with a heading reference (need '
                              f'{MIN_MOVING_SEGMENTS}): drive more')
    turned = float(sum(np.sum(np.abs(s.dpsi[0.5 * (np.abs(s.d_left) + np.abs(s.d_right))
                                            >= _MIN_TRAVEL]))
                       for _, s, _ in sources[:1]))
    driven = float(sum(np.sum(0.5 * np.abs(s.d_left + s.d_right)) for _, s, _ in sources[:1]))

    if straight_distance is not None:
        _check_straight(sources[0][1])

    # 1. Heading: u, v and the biases.
    determined, held = [], []
    hold_u = None
    if 'chi' in hold:
        hold_u = base_s / base_w
    elif turned < MIN_TURN:
        if straight_distance is None:
            raise ExcitationError(f'the heading reference turns {turned:.2f} rad in all over '
                                  f'the moving segments (need {MIN_TURN:g}): drive turns too')
        hold_u = base_s / base_w
    p, cov, used, heading_stats = _heading_fit(sources, len(recs), hold_u=hold_u)
    u, v = float(p[0]), float(p[1])
    std_u = _param_std(cov, used, 0) if hold_u is None else 0.0
    hold_ratio = None
    if u <= 0:
        raise FitError(f'the heading fit gives a turn gain {u:.4g} <= 0: are the tracks or '
                       'the gyro sign swapped?')
    rho = (u + v) / (u - v) if u > abs(v) else math.inf
    # Delta method: rho = (u+v)/(u-v); d rho/du = -2v/(u-v)^2, d rho/dv = 2u/(u-v)^2.
    if math.isfinite(rho) and hold_u is None:
        g = np.zeros(len(used))
        g[0], g[1] = -2 * v / (u - v) ** 2, 2 * u / (u - v) ** 2
        std_rho = float(math.sqrt(max(g @ cov @ g, 0.0)))
    elif math.isfinite(rho):
        std_rho = (_param_std(cov, used, 0) * 2 * u / (u - v) ** 2)
    else:
        std_rho = math.inf
    if 'scale_ratio' in hold or not (std_rho <= RATIO_STD_LIMIT) or not math.isfinite(rho) \
            or rho <= 0:
        hold_ratio = (base_rho - 1.0) / (base_rho + 1.0)
        p, cov, used, heading_stats = _heading_fit(sources, len(recs), hold_u=hold_u,
                                                   hold_ratio=hold_ratio)
        u, v = float(p[0]), float(p[1])
        rho = base_rho
        std_u = _param_std(cov, used, 0) if hold_u is None else 0.0
        held.append('scale_ratio')
    else:
        determined.append('scale_ratio')
    if hold_u is None:
        if std_u > CHI_REL_STD_LIMIT * u:
            raise ExcitationError(f'the turns do not determine chi: turn gain {u:.4g} +- '
                                  f'{std_u:.2g} rad/m (need {CHI_REL_STD_LIMIT:.0%}); '
                                  'drive more turns')
        determined.insert(0, 'chi')
    else:
        held.insert(0, 'chi')
    n_rec = len(recs)
    bias_cols = [2 + k for k in range(n_rec)]
    biases = [float(p[c]) if has_gyro[k] else None for k, c in enumerate(bias_cols)]

    # 2. Distance: positions, a straight drive, or held.
    s, c, x = base_s, base_c, base.x
    position_stats = {}
    straight = None
    std_s = std_x = std_c = None
    heading_for_pos = [gyro_series[k] if has_gyro[k] else pose_series[k] for k in range(n_rec)]
    bias_for_pos = [biases[k] if has_gyro[k] else 0.0 for k in range(n_rec)]
    bases = [_dead_reckoning_basis(r, hs, b, rho) for r, hs, b in
             zip(recs, heading_for_pos, bias_for_pos)]
    if straight_distance is not None:
        chords, excursions = [], []
        for k, basis in enumerate(bases):
            if basis is None:
                continue
            grid, psi, pa, pb, pc, m = basis
            moving_steps = m > 1e-4
            if not np.any(moving_steps):
                continue
            first = int(np.argmax(moving_steps))
            last = len(moving_steps) - int(np.argmax(moving_steps[::-1]))
            chords.append(float(np.hypot(*(pa[last] - pa[first]))))
            seg_psi = psi[first:last + 1]
            excursions.append(float(np.max(np.abs(seg_psi - seg_psi[0]))))
        if not chords or sum(chords) <= 0.1:
            raise ExcitationError('straight drive: the encoders do not move')
        turn = max(excursions)
        if turn > MAX_STRAIGHT_TURN:
            raise ExcitationError(f'not a straight drive: the heading turns by '
                                  f'{math.degrees(turn):.1f} deg (at most '
                                  f'{math.degrees(MAX_STRAIGHT_TURN):.0f} for '
                                  '--straight-distance)')
        s = straight_distance / sum(chords)
        straight = {'distance_m': straight_distance, 'encoder_chord_m': sum(chords),
                    'max_heading_excursion_rad': turn}
        determined.append('distance_scale')
    blocks = []
    for k, (r, basis) in enumerate(zip(recs, bases)):
        if basis is None:
            continue
        for source, data in (('gnss', r.positions), ('pose', r.pose)):
            if data is None:
                continue
            t = data[0] - (pose_d.delay if source == 'pose' else 0.0)
            window = position_window or POSITION_WINDOW[source]
            blk = _position_block(source, r, basis, t, data[1], data[2], window,
                                  gnss_antenna if source == 'gnss' else (0.0, 0.0))
            if blk is not None:
                blocks.append(blk)
    if blocks and straight_distance is None and 'distance_scale' not in hold:
        sigma = dict.fromkeys({b.source for b in blocks}, 1.0)
        pose_grade = any(b.source == 'pose' for b in blocks)
        free = [n for n, q in (('s', 'distance_scale'), ('x', 'icr.x'), ('c', 'icr_offset'))
                if q not in hold and (n != 'c' or pose_grade)]
        fixed = {'s': base_s, 'c': base_c, 'x': base.x}
        for attempt in range(3):
            vals, std, noise = _position_fit(blocks, free, fixed, sigma)
            sigma = {k: max(v, 1e-4) for k, v in noise.items()}
            vals, std, noise = _position_fit(blocks, free, fixed, sigma)
            drop = [n for n in ('x', 'c') if n in free and not std[n] <= X_STD_LIMIT]
            if not drop:
                break
            free = [n for n in free if n not in drop]
        s, c, x = float(vals['s']), float(vals['c']), float(vals['x'])
        std_s, std_x, std_c = (None if std.get(n) is None else float(std[n])
                               for n in ('s', 'x', 'c'))
        if not std_s <= DISTANCE_STD_LIMIT * s:
            raise ExcitationError(f'the positions do not determine the distance scale: {s:.3f} '
                                  f'+- {std_s:.2g} (need {DISTANCE_STD_LIMIT:.0%}): drive '
                                  'farther')
        determined.append('distance_scale')
        if 'x' in free:
            determined.append('icr.x')
        if 'c' in free:
            determined.append('icr_offset')
        position_stats = {k: {'residual_std_m': float(v)} for k, v in sigma.items()}
        for k in position_stats:
            position_stats[k]['samples'] = int(sum(b.t.size for b in blocks if b.source == k))
    for q in ('distance_scale', 'icr.x', 'icr_offset'):
        if q not in determined:
            held.append(q)

    # 3. The model.
    width = s / u if 'chi' in determined else base_w
    s_left, s_right = 2.0 * s / (1.0 + rho), 2.0 * s * rho / (1.0 + rho)
    try:
        icr = IcrParams(track_width, c + 0.5 * width, c - 0.5 * width, x, s_left, s_right)
    except ValueError as err:
        raise FitError(f'the calibration gives an invalid ICR model: {err}') from None
    names = ['imu'] if any(has_gyro) else []
    names += ['pose'] if any(has_pose) else []
    names += ['gnss'] if any(has_pos) else []
    names += ['straight'] if straight_distance is not None else []
    reference = '+'.join(names)
    order = {q: i for i, q in enumerate(QUANTITIES)}
    determined.sort(key=order.get)
    held.sort(key=order.get)
    gyro_seg = next((sg for n, sg, _ in sources if n == 'imu'), None)
    report = {
        'reference': reference, 'determined': determined, 'held': held,
        'icr': {'track_width': icr.track_width, 'y_left': icr.y_left, 'y_right': icr.y_right,
                'x': icr.x, 'scale_left': icr.scale_left, 'scale_right': icr.scale_right,
                'chi': icr.chi, 'eccentricity': icr.eccentricity + 0.0},
        'distance_scale': s, 'scale_ratio': rho, 'turn_gain': u, 'icr_offset': c,
        'standard_errors': {'turn_gain': std_u, 'scale_ratio': std_rho if 'scale_ratio'
                            in determined else None, 'distance_scale': std_s,
                            'icr.x': std_x if 'icr.x' in determined else None,
                            'icr_offset': std_c if 'icr_offset' in determined else None},
        'segment_length': segment_length,
        'heading': heading_stats, 'positions': position_stats,
        'gyro': None if gyro_seg is None else {
            'bias_rad_s': [b for b in biases if b is not None],
            'noise_rad_per_sqrt_s': heading_stats['imu']['residual_std_rad']
            / math.sqrt(segment_length),
        },
        'imu_delay': _delay_report(imu) if any(has_gyro) else None,
        'pose_delay': _delay_report(pose_d) if any(has_pose) else None,
        'straight': straight,
        'data': {'recordings': n_rec, 'moving_segments': int(np.count_nonzero(moving)),
                 'turned_rad': turned, 'driven_m': driven},
    }
    return ReferenceFit(icr, reference, determined, held, s, rho, u, imu, pose_d,
                        [b for b in biases if b is not None], report)


def _check_straight(seg: _Segments) -> None:
    """Refuse a 'straight' drive whose heading (bias from the standstill) turns too much."""
    travel = 0.5 * (np.abs(seg.d_left) + np.abs(seg.d_right))
    still = travel < 1e-3
    bias = float(np.sum(seg.dpsi[still]) / np.sum(seg.dt[still])) \
        if np.sum(seg.dt[still]) >= 2.0 else 0.0
    for r in np.unique(seg.recording):
        mine = seg.recording == r
        moving = np.flatnonzero(mine & ~still)
        if moving.size == 0:
            continue
        span = slice(moving[0], moving[-1] + 1)
        heading = np.cumsum(seg.dpsi[span] - bias * seg.dt[span])
        turn = float(np.max(np.abs(heading)))
        if turn > MAX_STRAIGHT_TURN:
            raise ExcitationError(f'not a straight drive: the heading turns by '
                                  f'{math.degrees(turn):.1f} deg (at most '
                                  f'{math.degrees(MAX_STRAIGHT_TURN):.0f} for a straight drive '
                                  'of measured length)')


def _delay_report(d: DelayEstimate) -> dict:
    std = float(d.std)
    return {'delay': float(d.delay), 'std': std if math.isfinite(std) else None,
            'determined': bool(d.determined), 'problem': d.problem,
            'uncertainty': d.uncertainty}


def fit_from_reference(enc_t, left, right, *, track_width: float, gyro_t=None, gyro_rate=None,
                       gyro_yaw=None, pose=None, positions=None,
                       straight_distance: float | None = None, base: IcrParams | None = None,
                       imu_delay='auto', pose_delay='auto', segment_length: float = 1.0,
                       position_window: float | None = None, hold=(),
                       gnss_antenna=(0.0, 0.0)) -> ReferenceFit:
    """
    Calibrate one recording from plain arrays: the entry point of nodes (module notes).

    Parameters
    ----------
    enc_t, left, right : array_like, shape (N,)
        Encoder times (s, increasing) and cumulative nominal track travel (m).
    track_width : float
        m.
    gyro_t, gyro_rate : array_like, optional
        Gyro stamps (s, same clock) and yaw rates (rad/s, counter-clockwise positive).
    gyro_yaw : array_like, optional
        Yaw angles (rad) of an orientation estimate, instead of ``gyro_rate``.
    pose : tuple of array_like, optional
        ``(t, x, y, yaw)`` of a pose reference (s, m, m, rad).
    positions : tuple of array_like, optional
        ``(t, x, y)`` positions in a local plane (GNSS), s, m, m.
    straight_distance : float, optional
        The recording is one straight drive of this many metres.
    base : IcrParams, optional
        Held values (default: ideal drive).
    imu_delay, pose_delay : float or 'auto'
        Delays of the gyro / pose stamps behind the encoders, s, or estimated.
    segment_length : float
        Heading segments, s.
    position_window, hold, gnss_antenna
        As :func:`fit_recordings`.

    Returns
    -------
    ReferenceFit
        ``.icr`` and ``.report`` (JSON-ready dict) among others.

    """
    rec = ReferenceRecording(enc_t, left, right, gyro_t, gyro_rate, gyro_yaw, pose, positions)
    return fit_recordings([rec], track_width, base=base, imu_delay=imu_delay,
                          pose_delay=pose_delay, segment_length=segment_length,
                          straight_distance=straight_distance,
                          position_window=position_window, hold=hold,
                          gnss_antenna=gnss_antenna)


def heading_reference(rec: ReferenceRecording, delay: float, bias: float,
                      rate: float = 10.0) -> Recording:
    """
    Return a Recording whose ground truth is the gyro's heading: to score heading only.

    The gyro heading (``delay`` removed from its stamps, ``bias`` rad/s taken off its rates)
    at ``rate`` Hz, positions all zero (not measured: a scorer must not report them).

    Parameters
    ----------
    rec : ReferenceRecording
        With a gyro.
    delay : float
        s of gyro stamps behind the encoders (:attr:`ReferenceFit.imu_delay`).
    bias : float
        rad/s (:attr:`ReferenceFit.biases`).
    rate : float
        Samples per second of the reference, Hz.

    """
    if rec.gyro_t is None:
        raise ValueError('the recording has no gyro')
    rec = _clean_gyro(rec)
    t, heading = _gyro_heading(rec, delay)
    heading = heading - bias * (t - t[0])
    grid = np.arange(t[0], t[-1], 1.0 / rate)
    # Only inside gap-free gyro stretches: a gap leaves the heading unknown.
    gap = gap_threshold(t)
    k = np.clip(np.searchsorted(t, grid, side='right'), 1, len(t) - 1)
    ok = (t[k] - t[k - 1]) <= gap
    grid = grid[ok]
    zeros = np.zeros(grid.size)
    return Recording(rec.enc_t, rec.left, rec.right, grid, zeros, zeros,
                     wrap_angle(np.interp(grid, t, heading)), name=rec.name)
