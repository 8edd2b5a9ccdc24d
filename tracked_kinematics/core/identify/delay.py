"""
Time offset between ground truth and encoders, estimated without a motion model.

Regresses the ground truth's heading change and forward displacement per interval on the track
travel over the interval shifted by a candidate delay (a cross-correlation of increments, our
reconstruction, in no paper); robust to bursts and jumps, with a jackknife error. See
docs/tools/identify_icr.md, "What latency does, and how it is removed".
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import math

import numpy as np

from .segments import JUMP_MARGIN, MAX_HEADING_STEP, stretches
from ..integration import wrap_angle
from ..recording import Recording

CHANNELS = ('heading', 'forward')
"""Channels correlated: heading changes and forward displacements."""
MIN_DELAY, MAX_DELAY = -0.5, 1.0
"""Default search range, s (a negative delay: the ground truth is stamped early)."""
RESOLUTION = 0.005
"""Grid of the search, s; the minimum is refined between grid points."""
COARSE = 4
"""The whole range is searched on every COARSE-th point of the grid first."""
LOCAL = 0.1
"""s either side of the coarse minimum searched on the full grid."""
WINDOW = 20.0
"""Seconds of kept intervals per jackknife window."""
MIN_JACKKNIFE_WINDOWS = 5
"""Fewest windows for a jackknife standard error; fewer: the curvature of the profile."""
IRREGULAR = 2.0
"""An interval longer than this multiple of the median ground-truth interval is irregular."""
HUBER_K = 2.0
"""Huber threshold of the robust pass, in robust standard deviations of the residuals."""
MIN_INTERVALS = 20
"""Fewest usable intervals for an estimate."""
MIN_CORRELATION = 0.3
"""Smallest peak correlation (of the best channel) that counts as a timing signal."""
PER_RECORDING_STD = 0.02
"""Largest standard error, s, at which each recording's own delay is used.

:func:`estimate_delays`.
"""

_STILL = 1e-4   # m: encoder travel below this over a padded interval is no motion


@dataclass(frozen=True)
class DelayEstimate:
    """
    The delay of the ground-truth stamps behind the encoders, with its uncertainty.

    Attributes
    ----------
    delay, std : float
        s, to subtract from the ground-truth stamps (:func:`correct_ground_truth`); 0 and inf
        when not ``determined`` (then ``problem`` says why).
    uncertainty : str
        ``'jackknife'`` (over ``windows`` windows), ``'curvature'`` (of the profile) or ``''``.
    correlation : dict
        Multiple correlation ``R`` of each channel (``heading``, ``forward``) at ``delay``.
    excluded : dict
        Intervals left out, by reason: ``irregular``, ``jumps``, ``still``, ``coverage``.
    shifts, cost : ndarray
        The coarse search grid (s) and the profile cost on it (lower is better).

    """

    delay: float
    std: float
    uncertainty: str = ''
    determined: bool = True
    problem: str = ''
    correlation: dict = field(default_factory=dict)
    intervals: int = 0
    excluded: dict = field(default_factory=dict)
    windows: int = 0
    window_delays: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    shifts: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    cost: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    search: tuple = (MIN_DELAY, MAX_DELAY)

    def describe(self) -> str:
        """One line for a report: the delay and its standard error, or why there is none."""
        if not self.determined:
            return f'not determined ({self.problem})'
        if self.uncertainty == 'given':
            return f'{self.delay:.3f} s (given)'
        how = (f'jackknife over {self.windows} windows' if self.uncertainty == 'jackknife'
               else 'curvature of the correlation peak')
        corr = ', '.join(f'{k} r {v:.2f}' for k, v in self.correlation.items())
        return (f'{self.delay:.3f} s +- {self.std:.3f} s ({how}; {corr}; '
                f'{self.intervals} intervals)')


def fixed_delay(delay: float) -> DelayEstimate:
    """Return a :class:`DelayEstimate` for a delay the user gives (no uncertainty)."""
    delay = float(delay)
    if not math.isfinite(delay):
        raise ValueError(f'the ground-truth delay must be a finite number of seconds, '
                         f'got {delay!r}')
    return DelayEstimate(delay, 0.0, uncertainty='given')


def correct_ground_truth(recordings, delay: float) -> list[Recording]:
    """Return the recordings with their ground-truth stamps moved ``delay`` s earlier."""
    recordings = list(recordings)
    if not delay:
        return recordings
    return [replace(r, gt_t=r.gt_t - float(delay)) for r in recordings]


@dataclass
class _Intervals:
    """The kept ground-truth intervals of all recordings, end to end."""

    enc_t: list      # per recording: encoder times
    left: list       # per recording: cumulative travel of each track
    right: list
    starts: list     # per recording: start and end times of its gap-free encoder stretches
    ends: list
    rec: np.ndarray  # recording of each interval
    ta: np.ndarray
    tb: np.ndarray
    y: dict          # channel -> ground-truth increment of each interval
    window: np.ndarray
    excluded: dict


def _covered(starts, ends, a, b):
    """Whether each span ``[a, b]`` lies inside one gap-free stretch."""
    block = np.maximum(np.searchsorted(starts, a, side='right') - 1, 0)
    return (a >= starts[block]) & (b <= ends[block])


def _intervals(recordings, lo, hi, window) -> _Intervals:
    """Ground-truth intervals that can time the ground truth, with their increments."""
    enc_ts, lefts, rights, all_starts, all_ends = [], [], [], [], []
    keep_rec, keep_ta, keep_tb, keep_y = [], [], [], {c: [] for c in CHANNELS}
    excluded = {'coverage': 0, 'irregular': 0, 'jumps': 0, 'still': 0}
    for index, rec in enumerate(recordings):
        enc_ts.append(rec.enc_t)
        lefts.append(rec.left)
        rights.append(rec.right)
        if len(rec.enc_t) < 2 or len(rec.gt_t) < 2:
            all_starts.append(np.zeros(0))
            all_ends.append(np.zeros(0))
            continue
        starts, ends = stretches(rec.enc_t)
        all_starts.append(starts)
        all_ends.append(ends)
        ta, tb = rec.gt_t[:-1], rec.gt_t[1:]
        dt = tb - ta
        # Inside a gap-free stretch of encoder samples at one delay of the search at least.
        covered = _covered(starts, ends, ta - hi, tb - hi) | _covered(starts, ends, ta - lo,
                                                                      tb - lo)
        covered |= _covered(starts, ends, ta - 0.5 * (lo + hi), tb - 0.5 * (lo + hi))
        irregular = dt > IRREGULAR * np.median(dt)
        irregular |= np.append(False, irregular[:-1]) | np.append(irregular[1:], False)
        dx, dy = np.diff(rec.gt_x), np.diff(rec.gt_y)
        dyaw = wrap_angle(np.diff(rec.gt_yaw))
        # Travel over the interval stretched by the search range.
        fastest = np.maximum(*(np.abs(np.interp(tb - lo, rec.enc_t, side)
                                      - np.interp(ta - hi, rec.enc_t, side))
                               for side in (rec.left, rec.right)))
        jumps = (np.hypot(dx, dy) > JUMP_MARGIN + fastest) | (np.abs(dyaw) > MAX_HEADING_STEP)
        still = fastest < _STILL
        ok = covered.copy()
        excluded['coverage'] += int(np.count_nonzero(~covered))
        for name, bad in (('irregular', irregular), ('jumps', jumps), ('still', still)):
            excluded[name] += int(np.count_nonzero(ok & bad))
            ok &= ~bad
        cos, sin = np.cos(rec.gt_yaw[:-1]), np.sin(rec.gt_yaw[:-1])
        keep_rec.append(np.full(np.count_nonzero(ok), index))
        keep_ta.append(ta[ok])
        keep_tb.append(tb[ok])
        keep_y['heading'].append(dyaw[ok])
        keep_y['forward'].append((cos * dx + sin * dy)[ok])

    def cat(parts):
        return np.concatenate(parts) if parts else np.zeros(0)

    ta, tb = cat(keep_ta), cat(keep_tb)
    # Windows of `window` seconds of kept intervals, in recording then time order.
    elapsed = np.cumsum(tb - ta) - (tb - ta)
    return _Intervals(enc_ts, lefts, rights, all_starts, all_ends, cat(keep_rec).astype(np.intp),
                      ta, tb, {c: cat(v) for c, v in keep_y.items()},
                      np.floor(elapsed / window).astype(np.intp), excluded)


def _increments(data: _Intervals, shifts):
    """Travel (m, (S, M)) of each track over every interval shifted by each delay, and validity."""
    shape = (len(shifts), len(data.ta))
    d_left, d_right = np.empty(shape), np.empty(shape)
    valid = np.empty(shape, dtype=bool)
    d = np.asarray(shifts, dtype=float)[:, None]
    # The intervals are in recording order: one slice per recording.
    edges = np.flatnonzero(np.diff(np.concatenate([[-1], data.rec, [-1]])))
    for lo, hi in zip(edges[:-1], edges[1:]):
        index, mine = data.rec[lo], slice(lo, hi)
        t = data.enc_t[index]
        a, b = data.ta[mine] - d, data.tb[mine] - d
        valid[:, mine] = _covered(data.starts[index], data.ends[index], a, b)
        for out, cum in ((d_left, data.left[index]), (d_right, data.right[index])):
            out[:, mine] = np.interp(b, t, cum) - np.interp(a, t, cum)
    return d_left, d_right, valid


def _window_sums(data: _Intervals, shifts, weights, chunk=32):
    """Per-window weighted sums (10, S, W) of each channel's regression, per shift."""
    n_windows = int(data.window.max()) + 1
    first = np.flatnonzero(np.diff(np.concatenate([[-1], data.window])))
    present = data.window[first]
    sums = {c: np.zeros((10, len(shifts), n_windows)) for c in CHANNELS}
    for c0 in range(0, len(shifts), chunk):
        xl, xr, valid = _increments(data, shifts[c0:c0 + chunk])
        for channel in CHANNELS:
            w = weights[channel] * valid
            y = data.y[channel]
            wy = w * y
            out = sums[channel][:, c0:c0 + chunk]
            terms = (w, w * xl, w * xr, w * xl * xl, w * xl * xr, w * xr * xr, wy * xl,
                     wy * xr, wy, wy * y)
            for k, values in enumerate(terms):
                out[k][:, present] = np.add.reduceat(values, first, axis=1)
    return sums


def _profile(sums, mask, channels):
    """Profile cost ``sum_c n_c log(1 - R_c^2)`` over the windows of ``mask``, and the R_c."""
    n_shifts = sums[channels[0]].shape[1]
    cost = np.zeros(n_shifts)
    corr = {}
    for channel in channels:
        sw, sl, sr, sll, slr, srr, sly, sry, sy, syy = sums[channel][:, :, mask].sum(axis=2)
        n_ref = float(sw.max())
        if n_ref <= 0:
            continue
        n = np.maximum(sw, 1e-300)
        cov = np.empty((n_shifts, 2, 2))
        cov[:, 0, 0] = sll - sl * sl / n
        cov[:, 0, 1] = cov[:, 1, 0] = slr - sl * sr / n
        cov[:, 1, 1] = srr - sr * sr / n
        cxy = np.stack([sly - sl * sy / n, sry - sr * sy / n], axis=1)
        vy = syy - sy * sy / n
        explained = np.einsum('si,sij,sj->s', cxy, np.linalg.pinv(cov, rcond=1e-9), cxy)
        enough = (sw >= 0.5 * n_ref) & (vy > 0)
        r2 = np.where(enough, np.clip(explained / np.where(enough, vy, 1.0), 0.0, 1.0), 0.0)
        corr[channel] = np.sqrt(r2)
        cost += n_ref * np.log(np.maximum(1.0 - r2, 1e-12))
    return cost, corr


def _argmin(shifts, cost):
    """Minimum of a sampled cost, refined by the parabola through its neighbours."""
    i = int(np.argmin(cost))
    if 0 < i < len(cost) - 1:
        a, b, c = cost[i - 1], cost[i], cost[i + 1]
        curvature = a - 2.0 * b + c
        if curvature > 0:
            step = shifts[1] - shifts[0]
            offset = float(np.clip(0.5 * (a - c) / curvature, -0.5, 0.5))
            return float(shifts[i] + offset * step), curvature / step ** 2
    return float(shifts[i]), 0.0


def _residual_weights(data: _Intervals, delay, channels):
    """Huber weights of each channel's regression residuals at ``delay``."""
    xl, xr, valid = (v[0] for v in _increments(data, [delay]))
    design = np.stack([xl, xr, np.ones_like(xl)], axis=1)
    weights = {}
    for channel in CHANNELS:
        y = data.y[channel]
        weights[channel] = np.ones(len(y))
        if channel not in channels or np.count_nonzero(valid) < 4:
            continue
        coef = np.linalg.lstsq(design[valid], y[valid], rcond=None)[0]
        r = y - design @ coef
        sigma = 1.4826 * np.median(np.abs(r[valid] - np.median(r[valid])))
        if sigma > 0:
            u = np.abs(r) / (HUBER_K * sigma)
            weights[channel] = np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-12))
    return weights


def estimate_delay(recordings, *, min_delay: float = MIN_DELAY, max_delay: float = MAX_DELAY,
                   resolution: float = RESOLUTION, window: float = WINDOW,
                   channels=CHANNELS) -> DelayEstimate:
    """
    Estimate the delay of the ground-truth stamps behind the encoders, without a model.

    One delay for all ``recordings`` (one vehicle, one logging set-up), searched in ``[min_delay,
    max_delay]`` (s) on a ``resolution`` grid, with jackknife windows of ``window`` s.
    ``determined`` is False (delay 0) when the data do not time the ground truth. Raises ValueError
    for an invalid range, resolution, window or channel.
    """
    for name, value in (('min_delay', min_delay), ('max_delay', max_delay),
                        ('resolution', resolution), ('window', window)):
        if not (isinstance(value, (int, float)) and math.isfinite(value)):
            raise ValueError(f'{name} must be a finite number, got {value!r}')
    if not min_delay < max_delay:
        raise ValueError(f'min_delay must be < max_delay, got {min_delay} and {max_delay}')
    if resolution <= 0 or window <= 0:
        raise ValueError(f'resolution and window must be > 0, got {resolution} and {window}')
    channels = tuple(channels)
    if not channels or any(c not in CHANNELS for c in channels):
        raise ValueError(f'channels must be some of {", ".join(CHANNELS)}, got {channels!r}')
    recordings = list(recordings)
    n_steps = int(math.ceil((max_delay - min_delay) / resolution - 1e-9))
    shifts = min_delay + resolution * np.arange(n_steps + 1)
    search = (float(min_delay), float(min_delay + resolution * n_steps))
    data = _intervals(recordings, search[0], search[1], window)
    n = len(data.ta)

    def undetermined(problem, **more):
        more.setdefault('shifts', shifts)
        return DelayEstimate(0.0, math.inf, determined=False, problem=problem, intervals=n,
                             excluded=data.excluded, search=search, **more)

    if n < MIN_INTERVALS:
        return undetermined(f'{n} usable ground-truth intervals while the encoders move '
                            f'(need {MIN_INTERVALS})')
    # Two passes over the whole range on a coarse grid (plain, then robust weights), then
    # the search resolution around the minimum (estimate, curvature, jackknife), then a grid
    # ten times finer (the peak is not a parabola).
    coarse = shifts[::COARSE] if len(shifts) > 4 * COARSE else shifts
    weights = {c: np.ones(n) for c in CHANNELS}
    all_windows = np.ones(int(data.window.max()) + 1, dtype=bool)
    delay = None
    for robust in (False, True):
        if robust:
            weights = _residual_weights(data, delay, channels)
        cost, corr = _profile(_window_sums(data, coarse, weights), all_windows, channels)
        delay = _argmin(coarse, cost)[0]
    i = int(np.argmin(cost))
    best = {c: float(np.interp(delay, coarse, r)) for c, r in corr.items()}
    more = {'correlation': best, 'cost': cost, 'shifts': coarse}
    if not best or max(abs(v) for v in best.values()) < MIN_CORRELATION:
        return undetermined(f'no channel correlates with the encoders (best r '
                            f'{max((abs(v) for v in best.values()), default=0):.2f}, need '
                            f'{MIN_CORRELATION})', **more)
    if i in (0, len(coarse) - 1):
        return undetermined(f'the best delay is on the bound of the search, {coarse[i]:+.3f} s',
                            **more)
    local = shifts[(shifts >= coarse[i] - LOCAL) & (shifts <= coarse[i] + LOCAL)]
    sums = _window_sums(data, local, weights)
    local_cost, corr = _profile(sums, all_windows, channels)
    delay, curvature = _argmin(local, local_cost)
    j = int(np.argmin(local_cost))
    if 0 < j < len(local) - 1:
        fine = local[j] + 0.1 * resolution * np.arange(-15, 16)
        fine_cost, _ = _profile(_window_sums(data, fine, weights), all_windows, channels)
        delay = _argmin(fine, fine_cost)[0]
    more['correlation'] = {c: float(np.interp(delay, local, r)) for c, r in corr.items()}
    occupied = np.flatnonzero(sums[channels[0]][0].max(axis=0) > 0)
    if len(occupied) >= MIN_JACKKNIFE_WINDOWS:
        loo = []
        for k in occupied:
            mask = all_windows.copy()
            mask[k] = False
            loo.append(_argmin(local, _profile(sums, mask, channels)[0])[0])
        loo = np.array(loo)
        m = len(loo)
        std = float(math.sqrt((m - 1) / m * np.sum((loo - loo.mean()) ** 2)))
        how = 'jackknife'
    else:
        loo = np.zeros(0)
        std = math.sqrt(2.0 / curvature) if curvature > 0 else math.inf
        how = 'curvature'
    return DelayEstimate(delay, std, uncertainty=how, intervals=n, excluded=data.excluded,
                         windows=len(occupied), window_delays=loo, search=search, **more)


def estimate_delays(recordings, **options) -> tuple[DelayEstimate, list[DelayEstimate]]:
    """
    Estimate the delay of all recordings together, and of each one when each can.

    Returns ``(pooled, each)``: ``each`` has one estimate per recording when every one is within
    :data:`PER_RECORDING_STD` (latency varies by bag: 0.19-0.26 s on the Warthog), else is empty.
    """
    recordings = list(recordings)
    pooled = estimate_delay(recordings, **options)
    if len(recordings) < 2:
        return pooled, []
    each = [estimate_delay([r], **options) for r in recordings]
    if all(e.determined and e.std <= PER_RECORDING_STD for e in each):
        return pooled, each
    return pooled, []


def estimate_delay_arrays(enc_t, left, right, gt_t, gt_x, gt_y, gt_yaw,
                          **options) -> DelayEstimate:
    """:func:`estimate_delay` on one recording's arrays (times, cumulative travel, poses)."""
    return estimate_delay([Recording(enc_t, left, right, gt_t, gt_x, gt_y, gt_yaw)], **options)
