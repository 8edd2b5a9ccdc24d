"""core.identify.segments: cutting recordings into segments between ground-truth samples."""

from helpers.vehicle_sim import AURIGA, B
import numpy as np
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
