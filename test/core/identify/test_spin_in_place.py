"""core.identify.spin: steering efficiency from spin-in-place runs, Martinez eq. (16)."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import ConstantIcr, EffectiveWheelBase

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


def test_spin_in_place_gives_martinez_eq16():
    # Symmetric vehicle of chi = 0.526 spinning both ways: eq. (16) gives it back.
    rec = simulate(EffectiveWheelBase(B), [0.526], duration=60.0, seed=2, legs=('spin',))
    spin = ident.spin_in_place([rec], B)
    assert spin.chi == pytest.approx(0.526, abs=1e-9)
    assert len(spin.runs) >= 5
    assert spin.icr(B).y_left == pytest.approx(0.399, abs=5e-4)
    straight = simulate(TRUTH, P_TRUE, duration=30.0, seed=1, legs=('straight',))
    with pytest.raises(ident.ExcitationError, match='no spin-in-place run'):
        ident.spin_in_place([straight], B)
    with pytest.raises(ident.IdentificationError, match='outside'):
        ident.spin_in_place([rec], B * 2.5)
