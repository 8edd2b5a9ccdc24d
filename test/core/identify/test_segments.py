"""core.identify.segments: cutting recordings into segments between ground-truth samples."""

from helpers.recordings import pieces
from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import ConstantIcr

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


def test_segment_length_zero_uses_every_ground_truth_sample(clean):
    every = ident.build_segments([clean], None)
    assert len(every) == len(clean.gt_t) - 1
    np.testing.assert_allclose(every.t1 - every.t0, 0.1, atol=1e-9)
    grouped = ident.build_segments([clean], 1.0)
    assert np.all(np.abs(grouped.t1 - grouped.t0 - 1.0) < 0.1 + 1e-9)
    # Segments tile time and their steps are positive.
    assert np.all(every.dt > 0) and np.all(np.diff(every.start) > 0)


def test_gaps_are_skipped(clean):
    # Drop 2 s of encoder samples and 2 s of ground truth elsewhere.
    enc_keep = (clean.enc_t < 50.0) | (clean.enc_t > 52.0)
    gt_keep = (clean.gt_t < 100.0) | (clean.gt_t > 102.0)
    rec = ident.Recording(clean.enc_t[enc_keep], clean.left[enc_keep], clean.right[enc_keep],
                          clean.gt_t[gt_keep], clean.gt_x[gt_keep], clean.gt_y[gt_keep],
                          clean.gt_yaw[gt_keep])
    segments = ident.build_segments([rec], 1.0)
    for lo, hi in ((50.0, 52.0), (100.0, 102.0)):
        assert not np.any((segments.t0 < hi) & (segments.t1 > lo))
    full = ident.build_segments([clean], 1.0)
    assert len(full) - len(segments) <= 7
    # Still exact: no segment straddles a hole.
    problem = ident.SegmentProblem(TRUTH, segments)
    np.testing.assert_allclose(problem.residuals(P_TRUE), 0.0, atol=1e-9)


@pytest.mark.parametrize('one', [False, True], ids=['300 bags', 'gaps in one bag'])
def test_pieces_with_ground_truth_before_the_encoders(one):
    # 300 pieces of 2 s, the ground truth starting 0.3 s before the encoders in each: the
    # segments are anchored where both streams cover, so every piece gives its own.
    rec = simulate(TRUTH, P_TRUE, duration=900.0, enc_rate=50.0, gt_rate=10.0, seed=4,
                   gt_phase=0.0137)
    parts = pieces(rec, length=2.0, gap=1.0, encoders_late=0.3, one=one)
    segments = ident.build_segments(parts, 1.0)
    start = np.floor(segments.t0 / 3.0)
    assert len(np.unique(start)) == 300            # every piece
    assert np.all(segments.t1 <= start * 3.0 + 2.0 + 1e-9)   # never across a gap
    assert np.all(segments.t0 >= start * 3.0 + 0.3 - 1e-9)   # nor before the encoders
    assert np.all(segments.t1 - segments.t0 >= 0.5 - 1e-9)
    problem = ident.SegmentProblem(TRUTH, segments)
    np.testing.assert_allclose(problem.residuals(P_TRUE), 0.0, atol=1e-9)
    # A piece shorter than a segment still gives one, of half a segment or more.
    short = ident.build_segments(pieces(rec, length=1.2, gap=1.0, encoders_late=0.3, one=one),
                                 1.0)
    assert len(short) > 250 and np.all(short.t1 - short.t0 >= 0.5 - 1e-9)
    assert len(ident.build_segments(parts, 1.0, partial=False)) == 300


def test_covered_spans_intersect_both_streams():
    enc_t = np.concatenate([np.arange(0.0, 10.0, 0.02), np.arange(12.0, 20.0, 0.02)])
    gt_t = np.concatenate([np.arange(-1.0, 5.0, 0.1), np.arange(6.0, 15.0, 0.1)])
    rec = ident.Recording(enc_t, enc_t, enc_t, gt_t, gt_t, 0 * gt_t, 0 * gt_t)
    start, end = ident.covered_spans(rec)
    np.testing.assert_allclose(start, [0.0, 6.0, 12.0], atol=1e-9)
    np.testing.assert_allclose(end, [4.9, 9.98, 14.9], atol=1e-9)


def test_ground_truth_jumps():
    rec = simulate(TRUTH, P_TRUE, duration=60.0, enc_rate=50.0, gt_rate=4.0, seed=1,
                   legs=('spin', 'arc'))
    # Fast spins at 4 Hz are no jumps.
    assert len(ident.segments.ground_truth_jumps(rec, B)) == 0
    x, yaw = rec.gt_x.copy(), rec.gt_yaw.copy()
    x[100:] += 1.0              # a re-localisation: the pose jumps and stays
    yaw[150] += 1.2             # a heading glitch
    jumped = ident.Recording(rec.enc_t, rec.left, rec.right, rec.gt_t, x, rec.gt_y, yaw)
    jumps = ident.segments.ground_truth_jumps(jumped, B)
    np.testing.assert_allclose(jumps[:, 0], rec.gt_t[[99, 149, 150]])
    segments = ident.build_segments([jumped], 1.0)
    over = ident.segments.over_jumps(segments, [jumped], B)
    assert over.sum() == 2 or over.sum() == 3
    assert np.all((segments.t0[over] <= rec.gt_t[150]) & (segments.t1[over] >= rec.gt_t[99]))
