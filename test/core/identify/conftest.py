"""Shared data of the identification tests: four minutes of a known vehicle."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.models import ConstantIcr

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


@pytest.fixture(scope='module')
def clean():
    """Four minutes of the Auriga-alpha (Martinez sec. 5.3), ground truth off the encoder grid."""
    return simulate(TRUTH, P_TRUE, duration=240.0, seed=3, gt_phase=0.0137)


@pytest.fixture(scope='module')
def clean_segments(clean):
    segments = ident.build_segments([clean], 1.0)
    return segments.select(segments.travel >= 0.01)
