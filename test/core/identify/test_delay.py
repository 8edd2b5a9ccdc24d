"""core.identify.delay: the ground-truth stamps' delay behind the encoders, model-free."""

from helpers.recordings import bursts, late, noisy, pieces
from helpers.vehicle_sim import AURIGA, B, simulate
from hypothesis import given, settings, strategies as st
import numpy as np
import pytest
from tracked_kinematics.core import identify as ident
from tracked_kinematics.core.identify import delay as delay_module
from tracked_kinematics.core.models import AdaptiveIcr, ConstantIcr

TRUTH = ConstantIcr(B)
P_TRUE = np.array(AURIGA)


@pytest.fixture(scope='module')
def slow_gt():
    """Two minutes, encoders at 20 Hz, ground truth at 4 Hz (lidar ICP at its slowest)."""
    return simulate(TRUTH, P_TRUE, duration=120.0, enc_rate=20.0, gt_rate=4.0, seed=4,
                    gt_phase=0.0137)


@pytest.mark.parametrize('injected', [-0.12, 0.0, 0.13, 0.31, 0.6])
def test_injected_delay_is_recovered_at_4_hz_ground_truth(slow_gt, injected):
    found = ident.estimate_delay([late(slow_gt, injected)])
    assert found.determined
    # Exact data: far within one encoder period (0.05 s).
    assert found.delay == pytest.approx(injected, abs=0.002)
    assert found.uncertainty == 'jackknife' and found.windows >= 5
    assert found.std < 0.005
    assert set(found.correlation) == {'heading', 'forward'}


def test_any_model_is_fitted_not_assumed():
    # Adaptive ICRs (slip that changes with curvature) and scales far from 1: the proxies of
    # an ideal drive would be wrong; the regression on both tracks is not.
    rec = simulate(AdaptiveIcr(B), [0.3, 0.2, 0.1, 0.25, 0.05, 0.1], duration=120.0,
                   enc_rate=50.0, gt_rate=10.0, seed=6)
    found = ident.estimate_delay([late(rec, 0.21)])
    assert found.delay == pytest.approx(0.21, abs=0.02)


def test_noise_and_glitches_as_lidar_on_ice(slow_gt):
    # 5 cm / 2 deg per sample, 3 % glitches: within one encoder period, and the error is
    # covered by the standard error reported.
    rec = noisy(late(slow_gt, 0.2), 0.05, np.radians(2.0), glitches=0.03, seed=1)
    found = ident.estimate_delay([rec])
    assert found.determined
    assert abs(found.delay - 0.2) < 0.05
    assert 0.002 < found.std < 0.05
    assert abs(found.delay - 0.2) < 3 * found.std + 0.005
    assert found.excluded['jumps'] > 0


def test_bursts_of_a_mapper_that_falls_behind_are_left_out():
    rec = simulate(TRUTH, P_TRUE, duration=240.0, enc_rate=50.0, gt_rate=10.0, seed=9)
    burst = bursts(late(rec, 0.15), 40.0, 90.0, period=1.0, lag=0.7)
    found = ident.estimate_delay([burst])
    assert found.delay == pytest.approx(0.15, abs=0.01)
    assert found.excluded['irregular'] > 50
    # Without the exclusion the bursts pull the estimate (the test can fail).
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(delay_module, 'IRREGULAR', np.inf)
        pulled = ident.estimate_delay([burst])
    assert abs(pulled.delay - 0.15) > 0.03


@pytest.mark.parametrize('one', [False, True], ids=['300 bags', 'gaps in one bag'])
def test_recording_in_short_pieces(one):
    # 300 pieces of 2 s, ground truth starting 0.3 s before the encoders in each.
    rec = simulate(TRUTH, P_TRUE, duration=900.0, enc_rate=50.0, gt_rate=10.0, seed=4,
                   gt_phase=0.0137)
    parts = pieces(late(rec, 0.2), length=2.0, gap=1.0, encoders_late=0.3, one=one)
    assert len(parts) == (1 if one else 300)
    found = ident.estimate_delay(parts)
    assert found.delay == pytest.approx(0.2, abs=0.002)
    assert found.intervals > 4000


def test_no_motion_is_not_determined():
    t = np.arange(0.0, 60.0, 0.02)
    gt_t = np.arange(0.0, 60.0, 0.1)
    found = ident.estimate_delay_arrays(t, np.zeros_like(t), np.zeros_like(t), gt_t,
                                        np.zeros_like(gt_t), np.zeros_like(gt_t),
                                        np.zeros_like(gt_t))
    assert not found.determined and found.delay == 0.0 and found.std == np.inf
    assert 'usable ground-truth intervals while the encoders move' in found.problem
    assert found.describe().startswith('not determined (')


def test_delay_beyond_the_search_is_not_determined(slow_gt):
    found = ident.estimate_delay([late(slow_gt, 0.9)], max_delay=0.5)
    assert not found.determined
    assert 'on the bound of the search' in found.problem


def test_short_data_use_the_curvature():
    rec = simulate(TRUTH, P_TRUE, duration=30.0, enc_rate=50.0, gt_rate=10.0, seed=2)
    found = ident.estimate_delay([late(rec, 0.1)], window=20.0)
    assert found.uncertainty == 'curvature' and found.windows < 5
    assert found.delay == pytest.approx(0.1, abs=0.005)
    assert 0 < found.std < 0.05
    assert 'curvature of the correlation peak' in found.describe()


def test_correct_ground_truth_and_fixed_delay(slow_gt):
    moved = ident.correct_ground_truth([late(slow_gt, 0.25)], 0.25)[0]
    np.testing.assert_allclose(moved.gt_t, slow_gt.gt_t, atol=1e-12)
    assert ident.correct_ground_truth([slow_gt], 0.0)[0] is slow_gt
    given = ident.fixed_delay(0.3)
    assert given.delay == 0.3 and given.uncertainty == 'given' and given.determined
    with pytest.raises(ValueError, match='finite number of seconds'):
        ident.fixed_delay(float('nan'))


@pytest.mark.parametrize('options, message', [
    ({'min_delay': 0.5, 'max_delay': 0.1}, 'min_delay must be < max_delay'),
    ({'resolution': 0.0}, 'must be > 0'),
    ({'max_delay': float('inf')}, 'max_delay must be a finite number'),
    ({'channels': ('pitch',)}, 'channels must be some of heading, forward'),
])
def test_invalid_options(slow_gt, options, message):
    with pytest.raises(ValueError, match=message):
        ident.estimate_delay([slow_gt], **options)


@settings(max_examples=12, deadline=None, derandomize=True)
@given(injected=st.floats(-0.4, 0.9), seed=st.integers(0, 50),
       gt_rate=st.sampled_from([4.0, 7.3, 10.0]), enc_rate=st.sampled_from([20.0, 50.0]))
def test_any_injected_delay_is_recovered(injected, seed, gt_rate, enc_rate):
    rec = simulate(TRUTH, P_TRUE, duration=60.0, enc_rate=enc_rate, gt_rate=gt_rate, seed=seed,
                   gt_phase=0.011)
    found = ident.estimate_delay([late(rec, injected)])
    assert found.determined
    assert found.delay == pytest.approx(injected, abs=0.002)


def test_a_gyro_delay_is_known_given_or_within_its_limit():
    from tracked_kinematics.core.identify.reference.delays import (
        IMU_DELAY_STD_LIMIT, imu_delay_problem)
    known = ident.DelayEstimate(-0.13, 0.003, 'jackknife', correlation={'heading': 0.99})
    assert imu_delay_problem(known) == ''
    assert imu_delay_problem(ident.fixed_delay(0.5)) == ''
    # Warthog ice (../shared/realdata): slip, not the clock.
    slip = ident.DelayEstimate(0.487, 0.083, 'jackknife', correlation={'heading': 0.88})
    assert imu_delay_problem(slip) == ('+0.487 s +- 0.083 s (need +- 0.02 s; heading r 0.88): '
                                       'the tracks slip too much to time the gyro against them')
    edge = ident.DelayEstimate(0.1, IMU_DELAY_STD_LIMIT * 1.01, 'curvature')
    assert 'slip' in imu_delay_problem(edge)
    none = ident.DelayEstimate(0.0, np.inf, determined=False, problem='too few intervals')
    assert imu_delay_problem(none) == 'not determined (too few intervals)'
