"""core.identify.search_space: the models fitted, their bounds."""

from helpers.vehicle_sim import B
import numpy as np
from tracked_kinematics.core import identify as ident


def test_bounds_keep_the_model_valid():
    model = ident.build_model('icr_scales', B)
    lo, hi = ident.bounds(model)
    for p in (lo, hi, np.clip([0.0, 0.0, 9.0, 0.0, 9.0], lo, hi)):
        icr = model.as_icr(p)
        assert 0 < icr.chi <= 1 and icr.scale_left > 0 and icr.scale_right > 0
