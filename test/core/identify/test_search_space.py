"""core.identify.search_space: the models fitted, their bounds."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import ConstantIcr


def test_bounds_keep_the_model_valid():
    model = ident.build_model('icr_scales', B)
    lo, hi = ident.bounds(model)
    for p in (lo, hi, np.clip([0.0, 0.0, 9.0, 0.0, 9.0], lo, hi)):
        icr = model.as_icr(p)
        assert 0 < icr.chi <= 1 and icr.scale_left > 0 and icr.scale_right > 0


def test_tuned_ddc_bounds_keep_chi_at_most_one():
    model = ident.build_model('tuned_ddc', B)
    lo, hi = ident.bounds(model)
    assert list(lo) == [1.0, 0.5, 0.5] and list(hi) == [20.0, 2.0, 2.0]
    for p in (lo, hi):
        icr = model.as_icr(p)
        assert 0 < icr.chi <= 1 and icr.x == 0 and icr.y_left == -icr.y_right
    # The start: the data's steering efficiency, as a separation multiplier 1 / chi.
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=30.0, seed=1)
    start = ident.initial_guess(model, ident.build_segments([rec], 1.0))
    chi = ident.steering_efficiency_guess(ident.build_segments([rec], 1.0), B)
    assert 1.0 / start[0] == pytest.approx(chi)
