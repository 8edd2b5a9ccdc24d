"""
The heading fit: the turn gain, the veer and the gyro biases from heading increments.

Over any interval the heading change is linear in the nominal travel of the tracks,
``dpsi = u (D_r - D_l) + v (D_r + D_l)``: Martinez et al. (2005) eq. (9), integrated, with
the scales of eqs. (20)-(21); the turn gain ``u = s / W`` is their eq. (16) read the other
way (``chi = track_width u / s``). :func:`_heading_fit` fits ``(u, v)`` and a bias per gyro
recording to the segments of :mod:`.headings` (weighted robust least squares);
:func:`fit_heading` (step 4 of :func:`.calibration.fit_recordings`) holds what the data do
not determine.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from .headings import HeadingData
from .recordings import calibration_quantities
from ...errors import ExcitationError, FitError

HUBER_K = 2.0
"""Huber threshold of the heading fit, in robust standard deviations."""
RATIO_STD_LIMIT = 0.01
"""Largest standard error of the scale ratio at which it counts as determined."""
CHI_REL_STD_LIMIT = 0.05
"""Largest relative standard error of the turn gain at which chi counts as determined."""
MIN_TURN = 1.0
"""Least total absolute turning, rad, over the moving segments to fit chi."""


def robust_std(r):
    """Return the robust standard deviation (1.4826 MAD) of residuals; inf for none."""
    r = np.asarray(r)
    if r.size == 0:
        return math.inf
    return float(max(1.4826 * np.median(np.abs(r - np.median(r))), 1e-12))


def _heading_fit(sources, n_rec, hold_u=None, hold_ratio=None):
    """Weighted robust least squares of ``(u, v)`` and a bias per gyro recording."""
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
            sigma[k] = robust_std(res[src == k])
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


@dataclass
class HeadingFit:
    """
    The heading fit (step 4 of the calibration).

    Attributes
    ----------
    u, v : float
        Turn gain ``s / W`` and veer ``(s_r - s_l) / (2 W)``, rad per m of travel.
    rho : float
        Scale ratio ``s_r / s_l``: ``(u + v) / (u - v)``, or the base's when held.
    std_u, std_rho : float
        Their standard errors (``std_u`` 0 when ``u`` is held).
    biases : list
        Gyro bias per recording, rad/s (None for a recording without a gyro).
    stats : dict
        Residual statistics per heading source.
    determined, held : list of str
        Of ``chi`` and ``scale_ratio``.

    """

    u: float
    v: float
    rho: float
    std_u: float
    std_rho: float
    biases: list
    stats: dict
    determined: list
    held: list


def _held_turn_gain(hold, turned: float, straight: bool, base) -> float | None:
    """
    Return the turn gain to hold (the base's ``s / W``), or None to fit it.

    It is held when asked (``'chi'`` in ``hold``) or when the drive turns less than
    :data:`MIN_TURN` and is a straight of measured length; with neither, too little turning
    is an error.

    Raises
    ------
    ExcitationError
        The heading turns too little to fit chi.

    """
    base_s, _, base_w, _ = calibration_quantities(base)
    if 'chi' in hold:
        return base_s / base_w
    if turned < MIN_TURN:
        if not straight:
            raise ExcitationError(f'the heading reference turns {turned:.2f} rad in all over '
                                  f'the moving segments (need {MIN_TURN:g}): drive turns too')
        return base_s / base_w
    return None


def _ratio_std(u: float, v: float, cov, used, u_held: bool) -> float:
    """Return the standard error of ``rho = (u + v) / (u - v)`` by the delta method (inf: none)."""
    rho = (u + v) / (u - v) if u > abs(v) else math.inf
    if math.isfinite(rho) and not u_held:
        g = np.zeros(len(used))
        g[0], g[1] = -2 * v / (u - v) ** 2, 2 * u / (u - v) ** 2
        return float(math.sqrt(max(g @ cov @ g, 0.0)))
    if math.isfinite(rho):
        return (_param_std(cov, used, 0) * 2 * u / (u - v) ** 2)
    return math.inf


def fit_heading(data: HeadingData, n_rec: int, hold, base, straight: bool) -> HeadingFit:
    """
    Fit the turn gain, the veer and the gyro biases; hold what the heading does not determine.

    The scale ratio is held at the base's (and the fit repeated with ``v / u`` fixed) when
    asked, when its standard error exceeds :data:`RATIO_STD_LIMIT` or when it comes out
    infinite or negative; chi (the turn gain) is refused when its relative standard error
    exceeds :data:`CHI_REL_STD_LIMIT`.

    Parameters
    ----------
    data : HeadingData
        The segments (step 3).
    n_rec : int
        Number of recordings (one bias column each).
    hold : tuple of str
        Quantities to hold.
    base : IcrParams
        Held values.
    straight : bool
        The recordings are a straight of measured length (chi may be held for lack of turns).

    Returns
    -------
    HeadingFit

    Raises
    ------
    ExcitationError
        Too little turning for chi, or chi too uncertain.
    FitError
        A turn gain <= 0 (tracks or gyro sign swapped).

    """
    _, base_rho, _, _ = calibration_quantities(base)
    hold_u = _held_turn_gain(hold, data.turned, straight, base)
    determined, held = [], []
    p, cov, used, stats = _heading_fit(data.sources, n_rec, hold_u=hold_u)
    u, v = float(p[0]), float(p[1])
    std_u = _param_std(cov, used, 0) if hold_u is None else 0.0
    if u <= 0:
        raise FitError(f'the heading fit gives a turn gain {u:.4g} <= 0: are the tracks or '
                       'the gyro sign swapped?')
    rho = (u + v) / (u - v) if u > abs(v) else math.inf
    std_rho = _ratio_std(u, v, cov, used, hold_u is not None)
    if 'scale_ratio' in hold or not (std_rho <= RATIO_STD_LIMIT) or not math.isfinite(rho) \
            or rho <= 0:
        hold_ratio = (base_rho - 1.0) / (base_rho + 1.0)
        p, cov, used, stats = _heading_fit(data.sources, n_rec, hold_u=hold_u,
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
    biases = [float(p[2 + k]) if g is not None else None for k, g in enumerate(data.gyro)]
    return HeadingFit(u, v, rho, std_u, std_rho, biases, stats, determined, held)
