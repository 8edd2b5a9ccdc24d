"""
The distance: positions (GNSS, a pose) or a measured straight give the distance scale.

With positions, the body step over each short interval is ``(s m + c dpsi, -x dpsi)`` with
``m = (D_l + rho D_r) / (1 + rho)``: Martinez et al. (2005) eqs. (7)-(8) in the ROS frame,
with the scales of eqs. (20)-(21) (``c`` the ICR offset, ``x = icr.x``), rotated by the gyro
heading. :func:`_dead_reckoning_basis` sums its three parts, so that the dead-reckoned
position is linear in ``(s, c, x)``; :func:`_position_fit` compares it with the positions in
windows, each centred on its mean, after a rotation per recording and source.
:func:`fit_distance` (step 5 of :func:`.calibration.fit_recordings`) takes the scale from a
straight drive of measured length instead, or holds it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from .heading_fit import HeadingFit, HUBER_K, robust_std
from .headings import HeadingData, MAX_STRAIGHT_TURN
from .recordings import calibration_quantities
from ...errors import ExcitationError, FitError

DISTANCE_STD_LIMIT = 0.05
"""Largest relative standard error of the distance scale from positions."""
X_STD_LIMIT = 0.02
"""Largest standard error, m, at which ``icr.x`` (and the ICR offset) count as determined."""
POSITION_WINDOW = {'gnss': 120.0, 'pose': 10.0}
"""Default window of the position comparison, s, per source."""


def _dead_reckoning_basis(rec, heading_series, bias, rho, dt=0.05):
    """Cumulative sums ``P_A, P_B, P_C`` (gyro frame): model position = s P_A + c P_B + x P_C."""
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
    """Fit ``(s, c, x)`` (``free`` ones) to windowed positions with a rotation per block."""
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
    from scipy.optimize import least_squares   # lazily, as every scipy of core
    sol = least_squares(residuals, p0, loss='soft_l1', f_scale=HUBER_K, x_scale='jac')
    if not sol.success:
        raise FitError(f'the position fit did not converge: {sol.message}')
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac)
    except np.linalg.LinAlgError:
        cov = np.full((len(p0), len(p0)), np.inf)
    # Scale the covariance by the residual spread (the sigma given is a first guess).
    res = sol.fun
    spread = robust_std(res) ** 2
    std = np.sqrt(np.maximum(np.diag(cov), 0.0) * spread)
    raw = residuals(sol.x)
    per_source = {}
    offset = 0
    for blk in blocks:
        n = 2 * blk.t.size
        per_source.setdefault(blk.source, []).append(raw[offset:offset + n] * sigma[blk.source])
        offset += n
    noise = {k: robust_std(np.concatenate(v)) for k, v in per_source.items()}
    return unpack(sol.x), dict(zip(names, std[:n_shared])), noise


# The steps of fit_recordings that concern the distance --------------------------------------

@dataclass
class DistanceFit:
    """
    The distance step of the calibration (step 5): scale, ICR offset and ``icr.x``.

    Attributes
    ----------
    s, c, x : float
        Distance scale, ICR offset (m) and ``icr.x`` (m): fitted, or the base's.
    std_s, std_x, std_c : float or None
        Standard errors of the position fit (None without one).
    stats : dict
        Residual spread (m) and samples per position source.
    straight : dict or None
        The measured straight: length, encoder chord, largest heading excursion.
    determined : list of str
        Of ``distance_scale``, ``icr.x`` and ``icr_offset``.

    """

    s: float
    c: float
    x: float
    std_s: float | None = None
    std_x: float | None = None
    std_c: float | None = None
    stats: dict = field(default_factory=dict)
    straight: dict | None = None
    determined: list = field(default_factory=list)


def _bases(recs, headings: HeadingData, heading: HeadingFit):
    """
    Return the dead-reckoning basis of every recording (None where too short).

    Each is rotated by the gyro's heading with its fitted bias removed, or by the pose's
    heading on a recording without a gyro, at the scale ratio of the heading fit.
    """
    out = []
    for k, r in enumerate(recs):
        gyro = headings.gyro[k] is not None
        series = headings.gyro[k] if gyro else headings.pose[k]
        bias = heading.biases[k] if gyro else 0.0
        out.append(_dead_reckoning_basis(r, series, bias, heading.rho))
    return out


def _straight_scale(bases, straight_distance: float):
    """
    Return the distance scale from one straight drive (its length over the encoders' chord).

    Raises ExcitationError when the encoders do not move or the heading turns by more than
    :data:`MAX_STRAIGHT_TURN`.
    """
    chords, excursions = [], []
    for basis in bases:
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
    return straight_distance / sum(chords), {
        'distance_m': straight_distance, 'encoder_chord_m': sum(chords),
        'max_heading_excursion_rad': turn}


def _position_blocks(recs, bases, pose_delay: float, position_window, gnss_antenna):
    """Return the position blocks of every recording and source (GNSS first, then the pose)."""
    blocks = []
    for r, basis in zip(recs, bases):
        if basis is None:
            continue
        for source, data in (('gnss', r.positions), ('pose', r.pose)):
            if data is None:
                continue
            t = data[0] - (pose_delay if source == 'pose' else 0.0)
            window = position_window or POSITION_WINDOW[source]
            blk = _position_block(source, r, basis, t, data[1], data[2], window,
                                  gnss_antenna if source == 'gnss' else (0.0, 0.0))
            if blk is not None:
                blocks.append(blk)
    return blocks


def _fit_positions(blocks, hold, base) -> DistanceFit:
    """
    Fit the distance scale, and ``icr.x`` and the ICR offset where determined, to positions.

    Noise per source from a first fit's residuals; ``x`` and ``c`` beyond :data:`X_STD_LIMIT` are
    held. Raises ExcitationError (scale beyond :data:`DISTANCE_STD_LIMIT`) or FitError.
    """
    base_s, _, _, base_c = calibration_quantities(base)
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
    determined = ['distance_scale']
    if 'x' in free:
        determined.append('icr.x')
    if 'c' in free:
        determined.append('icr_offset')
    stats = {k: {'residual_std_m': float(v)} for k, v in sigma.items()}
    for k in stats:
        stats[k]['samples'] = int(sum(b.t.size for b in blocks if b.source == k))
    return DistanceFit(s, c, x, std_s, std_x, std_c, stats, determined=determined)


def fit_distance(recs, headings: HeadingData, heading: HeadingFit, base, hold,
                 straight_distance: float | None, pose_delay: float, position_window,
                 gnss_antenna) -> DistanceFit:
    """
    Find the distance scale: from a measured straight, from positions, or held at the base's.

    Parameters
    ----------
    recs : list of Recording
        Checked and cleaned (step 1).
    headings, heading : HeadingData, HeadingFit
        The heading references (step 3) and their fit (step 4).
    base : IcrParams
        Held values.
    hold : tuple of str
        Quantities to hold.
    straight_distance : float or None
        m of a straight drive; it then gives the scale (positions are not fitted).
    pose_delay : float
        s of pose stamps behind the encoders (step 2).
    position_window, gnss_antenna
        As :func:`.calibration.fit_recordings`.

    Returns
    -------
    DistanceFit

    Raises
    ------
    ExcitationError, FitError
        See :func:`_straight_scale` and :func:`_fit_positions`.

    """
    base_s, _, _, base_c = calibration_quantities(base)
    bases = _bases(recs, headings, heading)
    distance = DistanceFit(base_s, base_c, base.x)
    if straight_distance is not None:
        distance.s, distance.straight = _straight_scale(bases, straight_distance)
        distance.determined.append('distance_scale')
    blocks = _position_blocks(recs, bases, pose_delay, position_window, gnss_antenna)
    if blocks and straight_distance is None and 'distance_scale' not in hold:
        distance = _fit_positions(blocks, hold, base)
    return distance
