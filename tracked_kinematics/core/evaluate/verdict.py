"""
A one-word verdict on a published covariance from the errors of its windows.

:func:`covariance_verdict` tests the three figures of :func:`..noise_model.consistency` (the
shares inside the 50 % and 95 % ellipses, the mean NEES) against what a consistent
covariance gives, each at 95 % confidence, counting only the windows that do not overlap
(:func:`disjoint_windows`). The rule and its false-alarm rate: docs/tools/evaluate_model.md,
"The verdict".
"""

from __future__ import annotations

import math

import numpy as np

CONFIDENCE = 0.95
"""Confidence of each of the three tests."""

MIN_WINDOWS = 10
"""Fewer independent windows than this give no verdict (no test has the power to tell)."""

VERDICTS = ('consistent', 'over-confident', 'under-confident')


def disjoint_windows(t_start, t_end) -> int:
    """
    Return how many of the windows ``[t_start, t_end]`` do not overlap (first come, first kept).

    evaluate_model's windows start at every ground-truth sample, so neighbours share most of
    their motion; the non-overlapping ones are about independent when the odometry's errors
    grow as a random walk. Starts must be sorted (they are, from :func:`.pieces.window_pairs`).
    """
    t_start = np.asarray(t_start, float)
    t_end = np.asarray(t_end, float)
    count, k = 0, 0
    while k < len(t_start):
        count += 1
        k = int(np.searchsorted(t_start, t_end[k], side='left'))
    return count


def share_range(nominal: float, n: int, confidence: float = CONFIDENCE):
    """
    Return the range of the share inside an ellipse that a consistent covariance gives.

    The share of ``n`` independent windows inside the ellipse of probability ``nominal``
    stays within ``nominal +- z sqrt(nominal (1 - nominal) / n)`` with the given confidence
    (the score test: the range holds the observed share exactly when the share's Wilson
    interval holds ``nominal``).
    """
    from scipy import stats   # lazily: 0.6 s to import
    z = stats.norm.ppf(0.5 + 0.5 * confidence)
    half = z * math.sqrt(nominal * (1.0 - nominal) / n)
    return max(0.0, nominal - half), min(1.0, nominal + half)


def nees_range(n: int, dof: int = 2, confidence: float = CONFIDENCE):
    """
    Return the range of the mean NEES of ``n`` independent windows under a consistent covariance.

    The sum of ``n`` NEES of ``dof`` degrees of freedom is chi-square of ``n dof`` degrees
    (Bar-Shalom et al. 2001, sec. 5.4.2, the NEES test): its two-sided quantiles over ``n``.
    """
    from scipy import stats
    tail = 0.5 * (1.0 - confidence)
    return (float(stats.chi2.ppf(tail, n * dof)) / n,
            float(stats.chi2.ppf(1.0 - tail, n * dof)) / n)


def covariance_verdict(inside_50, inside_95, mean_nees, independent: int,
                       confidence: float = CONFIDENCE) -> dict:
    """
    Judge a published position covariance (2 degrees of freedom) by its windows' errors.

    ``over-confident`` (the covariance too small: the dangerous side for a filter that fuses
    it) when any of the three figures lies beyond its range on that side: a share below its
    :func:`share_range` or the mean NEES above its :func:`nees_range`; else
    ``under-confident`` when any lies beyond on the other side; else ``consistent``.

    Parameters
    ----------
    inside_50, inside_95 : float or None
        Shares of the windows inside the 50 % and 95 % ellipses.
    mean_nees : float or None
        Their mean NEES.
    independent : int
        How many of the windows do not overlap (:func:`disjoint_windows`).
    confidence : float
        Of each test.

    Returns
    -------
    dict
        ``verdict`` (one of :data:`VERDICTS`; None below :data:`MIN_WINDOWS` independent
        windows or without figures), ``independent_windows``, and the ranges a consistent
        covariance gives: ``range_inside_50``, ``range_inside_95``, ``range_mean_nees``
        (None without a verdict).

    """
    out = {'verdict': None, 'independent_windows': int(independent), 'range_inside_50': None,
           'range_inside_95': None, 'range_mean_nees': None}
    if independent < MIN_WINDOWS or None in (inside_50, inside_95, mean_nees):
        return out
    r50 = share_range(0.5, independent, confidence)
    r95 = share_range(0.95, independent, confidence)
    rn = nees_range(independent, 2, confidence)
    if inside_50 < r50[0] or inside_95 < r95[0] or mean_nees > rn[1]:
        verdict = 'over-confident'
    elif inside_50 > r50[1] or inside_95 > r95[1] or mean_nees < rn[0]:
        verdict = 'under-confident'
    else:
        verdict = 'consistent'
    return {**out, 'verdict': verdict, 'range_inside_50': list(r50),
            'range_inside_95': list(r95), 'range_mean_nees': list(rn)}
