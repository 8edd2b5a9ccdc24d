"""core.identify.excitation: data that cannot identify a model are refused, with the reason."""

from helpers.recordings import pieces
from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


def test_straight_driving_cannot_identify_the_icrs():
    rec = simulate(TRUTH, P_TRUE, duration=60.0, seed=1, legs=('straight',))
    segments = ident.build_segments([rec], 1.0)
    with pytest.raises(ident.ExcitationError,
                       match='too little turning to identify icr.y_left, icr.y_right, icr.x'):
        ident.check_excitation(TRUTH, ident.Excitation.of(segments, 0.01))
    with pytest.raises(ident.ExcitationError, match='too little turning'):
        ident.identify([rec], 'icr_scales', B)


def test_spinning_cannot_identify_the_scales():
    rec = simulate(TRUTH, P_TRUE, duration=60.0, seed=1, legs=('spin',))
    with pytest.raises(ident.ExcitationError,
                       match='too little straight driving to identify scale.left, scale.right'):
        ident.identify([rec], 'icr_scales', B)
    # The ICRs alone are identified by the same data.
    result = ident.identify([rec], 'icr', B, base=IcrParams(B, 0.3, -0.3, 0, *AURIGA[3:]),
                            holdout=0.0)
    np.testing.assert_allclose(result.fit.p, P_TRUE[:3], atol=1e-6)


def test_standing_still_is_too_little_motion():
    rec = simulate(TRUTH, P_TRUE, duration=30.0, seed=1)
    still = ident.Recording(rec.enc_t, np.zeros_like(rec.left), np.zeros_like(rec.right),
                            rec.gt_t, np.zeros_like(rec.gt_x), np.zeros_like(rec.gt_y),
                            np.zeros_like(rec.gt_yaw))
    with pytest.raises(ident.ExcitationError, match='too little motion: 0 of'):
        ident.identify([still], 'icr_scales', B)


def test_streams_that_never_overlap_say_so():
    rec = simulate(TRUTH, P_TRUE, duration=30.0, seed=1)
    apart = ident.Recording(rec.enc_t, rec.left, rec.right, rec.gt_t + 1000.0, rec.gt_x,
                            rec.gt_y, rec.gt_yaw)
    with pytest.raises(ident.ExcitationError, match=r'the encoders \(0.00-30.00 s\) and the '
                       r'ground truth \(1000.00-1029.90 s\) never both have samples'):
        ident.identify([apart], 'icr_scales', B)
    with pytest.raises(ident.ExcitationError, match=r'at most 1\.\d+ s long, less than half '
                       r'a segment of 4 s; give a shorter --segment-length'):
        ident.identify(pieces(rec, length=1.5, gap=1.0, encoders_late=0.3), 'icr_scales', B,
                       segment_length=4.0)
