"""core.identify.procedure: the hold-out scores the windows in which the vehicle moves."""

from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.identify.procedure import MIN_SPEED, moving
from tracked_kinematics.core.models import ConstantIcr


def test_mean_track_speed_decides_and_a_turn_on_the_spot_moves():
    # 10 s standing, 10 s creeping at 0.05 m/s, 10 s turning on the spot at 0.2 m/s per track,
    # 10 s driving at 0.5 m/s; encoders at 50 Hz, ground truth at 10 Hz.
    t = np.arange(0, 40.0 + 1e-9, 0.02)
    left_speed = np.select([t < 10, t < 20, t < 30], [0.0, 0.05, -0.2], 0.5)
    right_speed = np.select([t < 10, t < 20, t < 30], [0.0, 0.05, 0.2], 0.5)
    left = np.concatenate([[0.0], np.cumsum(left_speed[:-1] * 0.02)])
    right = np.concatenate([[0.0], np.cumsum(right_speed[:-1] * 0.02)])
    gt_t = np.arange(0, 40.0 + 1e-9, 0.1)
    zeros = np.zeros_like(gt_t)
    rec = ident.Recording(t, left, right, gt_t, zeros, zeros, zeros)
    windows = ident.build_segments([rec], 10.0, partial=False)
    assert len(windows) == 4
    assert moving(windows, MIN_SPEED).tolist() == [False, False, True, True]
    assert moving(windows, 0.04).tolist() == [False, True, True, True]
    assert moving(windows, None).tolist() == [True] * 4


@pytest.mark.parametrize('min_speed', [MIN_SPEED, None])
def test_identify_counts_the_windows_before_and_after_the_selection(min_speed):
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=240.0, enc_rate=50.0, seed=5,
                   stand=(40.0, 25.0))
    result = ident.identify([rec], 'icr_scales', B, compare=('ideal', 'icr_scales'),
                            min_speed=min_speed)
    scored = result.evaluation('ideal').windows.n
    assert result.min_speed == min_speed
    if min_speed is None:
        assert scored == result.windows_total
    else:
        assert 0 < scored < 0.7 * result.windows_total
    np.testing.assert_allclose(result.icr.y_left, AURIGA[0], atol=1e-3)
