"""core.identify.evaluation: held-out time blocks."""

import numpy as np
from tracked_kinematics.core import identify as ident


def test_holdout_blocks_are_time_blocks(clean_segments):
    held = ident.HoldOut.choose(clean_segments, 0.25, 30.0)
    assert held.total_blocks == 8 and len(held.blocks) == 2
    inside, outside = held.inside(clean_segments), held.outside(clean_segments)
    assert not np.any(inside & outside)
    assert inside.sum() > 0.2 * len(clean_segments)
    assert ident.HoldOut.choose(clean_segments, 0.2, 100.0) is None
