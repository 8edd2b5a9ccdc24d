"""
The scores: final errors after windows, relative pose error as evo computes it, horizons.

All compare an estimate ``P`` with the ground truth ``Q`` at the ground-truth times of one piece
through ``E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` (Sturm et al. 2012, evo's ``rpe_base``). See
docs/tools/evaluate_model.md, "The figures, and how each is computed".
"""

from __future__ import annotations

import math

import numpy as np

from ..integration import wrap_angle

STATISTICS = ('n', 'rmse', 'mean', 'median', 'std', 'min', 'max', 'sse', 'p90')
"""Keys of :func:`summary`: evo's statistics (``evo_res``) and the 90th percentile."""


def relative_errors(estimate, reference, i, j):
    """
    Return the translation (m) and rotation (rad, [0, pi]) of ``E_ij`` for index pairs ``i, j``.

    ``estimate`` and ``reference`` are ``(x, y, yaw)`` (M, 3) at the same times.
    """
    i = np.asarray(i, dtype=np.intp)
    j = np.asarray(j, dtype=np.intp)
    p, q = np.asarray(estimate, float), np.asarray(reference, float)

    def motion(path):
        # P_i^-1 P_j: the displacement in the frame of sample i, and the heading change.
        c, s = np.cos(path[i, 2]), np.sin(path[i, 2])
        ex, ey = path[j, 0] - path[i, 0], path[j, 1] - path[i, 1]
        return c * ex + s * ey, -s * ex + c * ey, path[j, 2] - path[i, 2]

    px, py, pth = motion(p)
    qx, qy, qth = motion(q)
    # t(E) = R(-dth_Q) (t_P - t_Q): a rotation, which keeps the norm.
    return np.hypot(px - qx, py - qy), np.abs(wrap_angle(pth - qth))


def window_pairs(t, length: float):
    """Windows of ``length`` s the piece covers: each ``i``, the last ``j <= t_i + length``."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    tol = 1e-9 * max(1.0, abs(float(t[-1])))
    ends = t + length
    j = np.searchsorted(t, ends + tol, side='right') - 1
    i = np.arange(len(t))
    keep = (t[-1] >= ends - tol) & (j > i)
    return i[keep], j[keep]


def evo_path_pairs(positions, delta: float) -> np.ndarray:
    """
    Choose the samples evo's ``filter_pairs_by_path`` chooses (``all_pairs=False``).

    Sample 0, then each sample where the path length of ``positions`` from the previous chosen one
    first reaches ``delta`` (m); the pairs are consecutive entries. O(pairs log M).
    """
    positions = np.asarray(positions, dtype=float)
    if len(positions) < 2:
        return np.zeros(0, np.intp)
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(positions, axis=0),
                                                          axis=1))])
    chosen = [0]
    base = 0.0
    while True:
        k = int(np.searchsorted(cum, base + delta, side='left'))
        if k <= chosen[-1]:
            k = chosen[-1] + 1
        if k >= len(cum):
            break
        chosen.append(k)
        base = cum[k]
    return np.asarray(chosen, dtype=np.intp)


def rpe(estimate, reference, delta: float, pairs_from_reference: bool = False):
    """
    Relative pose errors (m, rad) of evo's consecutive pairs ``delta`` m apart along the estimate.

    ``pairs_from_reference`` chooses them along the reference (``evo_rpe --pairs_from_reference``).
    """
    chooser = reference if pairs_from_reference else estimate
    ids = evo_path_pairs(np.asarray(chooser)[:, :2], delta)
    return relative_errors(estimate, reference, ids[:-1], ids[1:])


def horizon_members(t, horizon: float):
    """
    Horizons the piece covers from every sample: the ``k`` with ``t_i < t_k <= t_i + horizon``.

    Returns ``starts`` (H,), and per member its ``owner`` horizon and its ``member`` sample
    (consecutive per horizon, the last is its end).
    """
    starts, ends = window_pairs(t, horizon)
    lengths = ends - starts
    owner = np.repeat(np.arange(len(starts)), lengths)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp)
    member = starts[owner] + 1 + np.arange(int(lengths.sum())) - offsets[owner]
    return starts, owner, member


def horizon_scores(owner, n: int, translation, rotation):
    """RMS over each horizon of its members' errors, and the error at its last member."""
    owner = np.asarray(owner, dtype=np.intp)
    count = np.bincount(owner, minlength=n)
    last = np.cumsum(count) - 1
    with np.errstate(invalid='ignore', divide='ignore'):
        rms_t = np.sqrt(np.bincount(owner, translation ** 2, minlength=n) / count)
        rms_r = np.sqrt(np.bincount(owner, rotation ** 2, minlength=n) / count)
    return rms_t, rms_r, translation[last], rotation[last]


def summary(values) -> dict:
    """Return the statistics of errors under evo's names (None when empty), ``n``, ``p90``."""
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return {'n': 0, **dict.fromkeys(STATISTICS[1:])}
    return {'n': int(len(values)), 'rmse': float(math.sqrt(np.mean(values ** 2))),
            'mean': float(np.mean(values)), 'median': float(np.median(values)),
            'std': float(np.std(values)), 'min': float(np.min(values)),
            'max': float(np.max(values)), 'sse': float(np.sum(values ** 2)),
            'p90': float(np.percentile(values, 90))}
