"""core.identify.holdout: held-out time blocks, folds, windows inside pieces."""

from helpers.recordings import pieces
from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import ConstantIcr


def test_holdout_blocks_are_time_blocks(clean_segments):
    # Four minutes of driving: ten blocks of 24 s (MIN_BLOCKS), two held out.
    held = ident.HoldOut.choose(clean_segments, 0.25, 30.0)
    assert held.total_blocks == 10 and len(held.folds) == 1 and len(held.folds[0]) == 2
    assert held.block_length == pytest.approx(24.0, abs=0.1)
    inside, outside = held.inside(clean_segments), held.outside(clean_segments)
    assert not np.any(inside & outside)
    assert inside.sum() > 0.15 * len(clean_segments)
    # Long blocks are capped by --holdout-block: as many whole blocks as fit.
    capped = ident.HoldOut.choose(clean_segments, 0.2, 10.0)
    assert capped.total_blocks == 23 and 10.0 <= capped.block_length < 10.5
    assert ident.HoldOut.choose(clean_segments, 0.0, 30.0) is None


def test_short_data_keep_blocks_as_long_as_two_windows(clean_segments):
    one_minute = clean_segments.select(clean_segments.t1 <= 60.0)
    held = ident.HoldOut.choose(one_minute, 0.2, 30.0, window=10.0)
    assert held.total_blocks == 3 and held.block_length == pytest.approx(19.7, abs=0.2)
    assert ident.HoldOut.choose(one_minute, 0.2, 30.0, window=0.0).total_blocks == 10


def test_folds_hold_every_block_out_once(clean_segments):
    held = ident.HoldOut.choose(clean_segments, 0.2, 30.0, window=10.0, folds=5)
    assert held.cross_validated and len(held.folds) == 5
    assert sorted(np.concatenate(held.folds)) == list(range(held.total_blocks))
    covered = np.zeros(len(clean_segments), dtype=int)
    for f in range(5):
        inside = held.inside(clean_segments, f)
        assert not np.any(inside & held.outside(clean_segments, f))
        covered += inside
    # Every segment but those on a block border is held out by exactly one fold.
    assert covered.max() == 1 and covered.mean() > 0.95


def test_windows_overlap_by_half_and_stay_inside_held_blocks(clean, clean_segments):
    held = ident.HoldOut.choose(clean_segments, 0.25, 30.0)
    windows = held.windows([clean], 10.0)
    lengths = windows.t1 - windows.t0
    assert np.all(lengths >= 10.0 - 1e-9) and np.all(lengths < 10.1 + 1e-9)
    # Two blocks of 24 s: windows start every 5 s, three per block.
    assert len(windows) == 6
    assert np.all(held.inside(windows))
    problem = ident.SegmentProblem(ConstantIcr(B), windows)
    np.testing.assert_allclose(problem.residuals(np.array(AURIGA)), 0.0, atol=1e-8)


@pytest.mark.parametrize('one', [False, True], ids=['bags', 'gaps'])
def test_windows_fit_inside_pieces_or_there_are_none(one):
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=300.0, enc_rate=50.0, seed=2)
    parts = pieces(rec, length=8.0, gap=2.0, encoders_late=0.3, one=one)
    segments = ident.build_segments(parts, 1.0)
    held = ident.HoldOut.choose(segments, 0.2, 30.0, window=5.0, folds=5)
    windows = np.concatenate([[held.windows(parts, 5.0, f).t0, held.windows(parts, 5.0, f).t1]
                              for f in range(5)], axis=1)
    assert windows.shape[1] > 40
    # No window spans the gap between two pieces (pieces start every 10 s).
    start_piece = np.floor(windows[0] / 10.0)
    assert np.all(windows[1] <= start_piece * 10.0 + 8.0 + 1e-9)
    # Windows longer than any piece: none, and said so by n == 0 (never NaN percentages).
    assert all(len(held.windows(parts, 9.0, f)) == 0 for f in range(5))
    empty = ident.ErrorStats.of([], [])
    assert empty.n == 0 and empty.improvement_over(ident.ErrorStats.of([1.0], [1.0])) is None
