"""The verdict on a published covariance (core/evaluate/verdict.py).

The rule is docs/tools/evaluate_model.md's "The verdict"; here its claims: a consistent
covariance is called consistent on evaluate_model's overlapping windows (false alarms under
5 %), a covariance half or twice the truth is caught, too few windows give no verdict.
"""

import numpy as np
import pytest
from tracked_kinematics.core.evaluate.verdict import (
    covariance_verdict, disjoint_windows, MIN_WINDOWS, nees_range, share_range)
from tracked_kinematics.core.noise_model import consistency

DT, LENGTH, DURATION = 0.1, 5.0, 240.0


def test_disjoint_windows_counts_the_ones_that_do_not_overlap():
    t = np.arange(0.0, 60.0 + 1e-9, 0.1)
    k = int(round(LENGTH / 0.1))
    assert disjoint_windows(t[:-k], t[k:]) == 12
    assert disjoint_windows([], []) == 0
    # Windows that touch at their ends share no motion.
    assert disjoint_windows([0.0, 1.0, 2.0], [1.0, 2.0, 3.0]) == 3
    assert disjoint_windows([0.0, 0.5, 1.0], [1.0, 1.5, 2.0]) == 2


def test_ranges_of_a_consistent_covariance():
    lo, hi = share_range(0.5, 100)
    assert lo == pytest.approx(0.5 - 1.96 * 0.05, abs=1e-3) and hi == pytest.approx(0.598, 1e-3)
    assert share_range(0.95, 10)[1] == 1.0
    lo, hi = nees_range(48)
    assert lo < 2.0 < hi
    assert lo == pytest.approx(1.47, abs=0.01) and hi == pytest.approx(2.6, abs=0.02)


def _verdicts(scale, runs, seed=0):
    """Random-walk position errors scored on overlapping windows against ``scale`` x the truth."""
    rng = np.random.default_rng(seed)
    k = int(round(LENGTH / DT))
    steps = int(round(DURATION / DT))
    t = np.arange(steps + 1) * DT
    out = []
    for _ in range(runs):
        path = np.vstack([[0.0, 0.0], np.cumsum(rng.normal(size=(steps, 2)) * np.sqrt(DT), 0)])
        errors = path[k:] - path[:-k]
        cov = np.broadcast_to(scale * LENGTH * np.eye(2), (len(errors), 2, 2))
        c = consistency(errors, cov)
        n = disjoint_windows(t[:-k], t[k:])
        out.append(covariance_verdict(c['inside_50'], c['inside_95'], c['mean_nees'],
                                      n)['verdict'])
    return out


def test_a_consistent_covariance_is_called_consistent():
    verdicts = _verdicts(1.0, 200)
    assert verdicts.count('consistent') >= 190, verdicts


@pytest.mark.parametrize('scale, word', [(0.5, 'over-confident'), (2.0, 'under-confident')])
def test_a_covariance_twice_off_is_caught(scale, word):
    verdicts = _verdicts(scale, 50, seed=1)
    assert verdicts.count(word) >= 48, verdicts


def test_the_dangerous_side_wins_and_too_few_windows_give_none():
    # Heavy tails: the core inside the 50 % ellipse too often, the mean NEES far above 2.
    v = covariance_verdict(0.8, 0.9, 4.0, 40)
    assert v['verdict'] == 'over-confident'
    assert v['range_mean_nees'][1] < 4.0 and v['independent_windows'] == 40
    assert covariance_verdict(0.8, 1.0, 1.0, 40)['verdict'] == 'under-confident'
    assert covariance_verdict(0.5, 0.95, 2.0, 40)['verdict'] == 'consistent'
    none = covariance_verdict(0.0, 0.0, 50.0, MIN_WINDOWS - 1)
    assert none['verdict'] is None and none['range_inside_50'] is None
    assert covariance_verdict(None, None, None, 0)['verdict'] is None
