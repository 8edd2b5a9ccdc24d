"""
The scores: final errors after windows, relative pose error as evo computes it, horizons.

All of them compare two paths sampled at the ground-truth times of one piece
(:mod:`.pieces`): the *estimate* ``P`` (odometry or a prediction) and the *reference* ``Q``
(the ground truth), through the relative pose error of a pair of samples ``(i, j)``::

    E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)

(the relative motion of the estimate expressed in that of the reference, Sturm et al. 2012,
as evo's ``RPE.rpe_base``). Its translation part ``|t(E_ij)|`` equals the distance between
where the estimate ends and where the vehicle ended, had the estimate started from the
measured pose ``Q_i``; its rotation part is the absolute heading difference.

- **Windows** (:func:`window_pairs`): from every ground-truth sample ``i``, the last sample
  ``j`` at most ``length`` s later, where the piece lasts at least that long: the final
  position and heading error of odometry started at ``i``.
- **RPE per distance** (:func:`evo_path_pairs`, :func:`rpe`): evo's pairs for ``evo_rpe
  --delta D --delta_unit m`` (evo 1.38, ``filters.filter_pairs_by_path`` with its defaults:
  consecutive pairs, chosen along the *estimate*): the first sample is chosen; walking on,
  the path length is summed from the last chosen sample, and a sample is chosen where the
  sum first reaches ``D``; the pairs are consecutive chosen samples. The errors are
  ``|t(E_ij)|`` (m) and the rotation angle of ``E_ij`` (rad). (evo releases before 2024
  did not choose the first sample: their first pair started where the path first reached
  ``D``.)
- **Horizons** (:func:`horizon_members`): from every ground-truth sample ``i``, the samples
  ``k`` after it up to ``horizon`` s later: a prediction's error at each, its root mean
  square over the horizon and its value at the last.
"""

from __future__ import annotations

import math

import numpy as np

from ..integration import wrap_angle

STATISTICS = ('n', 'rmse', 'mean', 'median', 'std', 'min', 'max', 'sse', 'p90')
"""Keys of :func:`summary`: evo's statistics (``evo_res``) and the 90th percentile."""


def relative_errors(estimate, reference, i, j):
    """
    Return the translation (m) and rotation (rad) parts of ``E_ij`` for index pairs.

    Parameters
    ----------
    estimate, reference : ndarray, shape (M, 3)
        ``(x, y, yaw)`` at the same times (yaw continuous or wrapped).
    i, j : ndarray of int
        Pairs.

    Returns
    -------
    translation, rotation : ndarray
        ``|t(E_ij)|`` and ``|angle(E_ij)|`` in [0, pi].

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
    """
    Windows of ``length`` s: each sample ``i`` and the last sample ``j <= t_i + length``.

    Only windows the piece covers (its last sample at or after ``t_i + length``) and that
    span at least one interval.

    Returns
    -------
    i, j : ndarray of int

    """
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

    Parameters
    ----------
    positions : ndarray, shape (M, 2) or (M, 3)
        Positions of the path whose length decides (evo: the estimate).
    delta : float
        Path length between chosen samples, m (> 0).

    Returns
    -------
    ndarray of int
        Chosen samples; the pairs are consecutive entries. Sample 0 is chosen, then each
        sample where the path length from the previous chosen one first reaches ``delta``.
        O(pairs log M).

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
    Relative pose errors of evo's consecutive pairs ``delta`` m apart along the estimate.

    With ``pairs_from_reference``, the pairs are chosen along the reference instead
    (``evo_rpe --pairs_from_reference``): the same pairs for every estimate.

    Returns
    -------
    translation, rotation : ndarray
        m and rad, one per pair (none when the path is shorter than ``delta``).

    """
    chooser = reference if pairs_from_reference else estimate
    ids = evo_path_pairs(np.asarray(chooser)[:, :2], delta)
    return relative_errors(estimate, reference, ids[:-1], ids[1:])


def horizon_members(t, horizon: float):
    """
    Horizons from every sample: the samples ``k`` with ``t_i < t_k <= t_i + horizon``.

    Only horizons the piece covers (its last sample at or after ``t_i + horizon``).

    Returns
    -------
    starts : ndarray of int, shape (H,)
        First sample of each horizon.
    owner : ndarray of int, shape (K,)
        Horizon (index into ``starts``) of each member.
    member : ndarray of int, shape (K,)
        Sample of each member; the members of a horizon are consecutive, the last is its end.

    """
    starts, ends = window_pairs(t, horizon)
    lengths = ends - starts
    owner = np.repeat(np.arange(len(starts)), lengths)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp)
    member = starts[owner] + 1 + np.arange(int(lengths.sum())) - offsets[owner]
    return starts, owner, member


def horizon_scores(owner, n: int, translation, rotation):
    """
    Root mean square over each horizon of member errors, and the error at its last member.

    Returns
    -------
    rms_translation, rms_rotation, final_translation, final_rotation : ndarray, shape (n,)

    """
    owner = np.asarray(owner, dtype=np.intp)
    count = np.bincount(owner, minlength=n)
    last = np.cumsum(count) - 1
    with np.errstate(invalid='ignore', divide='ignore'):
        rms_t = np.sqrt(np.bincount(owner, translation ** 2, minlength=n) / count)
        rms_r = np.sqrt(np.bincount(owner, rotation ** 2, minlength=n) / count)
    return rms_t, rms_r, translation[last], rotation[last]


def summary(values) -> dict:
    """
    Return the statistics of errors, under evo's names, with ``n`` and ``p90``.

    evo's (``evo_res``): ``rmse``, ``mean``, ``median``, ``std``, ``min``, ``max``, ``sse``;
    None for each when there are no errors.
    """
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return {'n': 0, **dict.fromkeys(STATISTICS[1:])}
    return {'n': int(len(values)), 'rmse': float(math.sqrt(np.mean(values ** 2))),
            'mean': float(np.mean(values)), 'median': float(np.median(values)),
            'std': float(np.std(values)), 'min': float(np.min(values)),
            'max': float(np.max(values)), 'sse': float(np.sum(values ** 2)),
            'p90': float(np.percentile(values, 90))}
