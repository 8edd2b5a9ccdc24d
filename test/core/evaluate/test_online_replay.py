"""The EKF replayed over a recording as the node would run it, and scored."""

from helpers.vehicle_sim import B, simulate
import numpy as np
import pytest
from tracked_kinematics.core.evaluate import (
    Candidate, cut, Data, encoder_horizons, evaluate, replay)
from tracked_kinematics.core.identify import correct_ground_truth, Recording
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr

TRUE = IcrParams(B, 0.34, -0.40, 0.03, 1.0, 1.0)


@pytest.fixture(scope='module')
def recording():
    model = ConstantIcr(B, with_scales=False)
    return simulate(model, model.from_icr(TRUE), duration=120.0, enc_rate=50.0, gt_rate=10.0,
                    seed=3)


def _late(rec, delay, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    return Recording(rec.enc_t, rec.left, rec.right, rec.gt_t + delay,
                     rec.gt_x + rng.normal(0.0, noise, len(rec.gt_t)),
                     rec.gt_y + rng.normal(0.0, noise, len(rec.gt_t)), rec.gt_yaw)


def _horizon_mean(rec, params_at):
    return np.mean(np.concatenate([encoder_horizons(p, 2.0, params_at).rms_translation
                                   for p in cut(rec).pieces]))


def test_replay_learns_from_a_wrong_start_and_is_not_worse_than_a_right_one(recording):
    noisy = _late(recording, 0.0, noise=0.01, seed=1)
    wrong = IcrParams.ideal(B)
    learned = replay(noisy, wrong)
    assert learned.outcomes['updated'] > 1000
    np.testing.assert_allclose(learned.icr[-1], [TRUE.y_left, TRUE.y_right, TRUE.x], atol=0.03)
    assert _horizon_mean(recording, learned.params_at) < 0.5 * _horizon_mean(
        recording, lambda times: (wrong.y_left, wrong.y_right, wrong.x, 1.0, 1.0))
    right = replay(noisy, TRUE)
    exact = _horizon_mean(recording, lambda times: (TRUE.y_left, TRUE.y_right, TRUE.x, 1, 1))
    assert _horizon_mean(recording, right.params_at) < 1.02 * exact + 1e-4


def test_replay_takes_the_delay_off_the_pose_stamps(recording):
    late = _late(recording, 0.25, noise=0.01, seed=2)
    fixed = replay(correct_ground_truth([late], 0.25)[0], IcrParams.ideal(B), delay=0.25)
    naive = replay(late, IcrParams.ideal(B), delay=0.0)
    truth = np.array([TRUE.y_left, TRUE.y_right, TRUE.x])
    assert np.abs(fixed.icr[-1] - truth).max() < 0.5 * np.abs(naive.icr[-1] - truth).max()
    # The estimate in force at a time was available then: the first change comes after the
    # first pose arrived (its stamp plus the delay).
    assert fixed.t[1] > late.gt_t[0]


def test_evaluate_scores_the_online_candidate_next_to_the_constant_ones(recording):
    noisy = _late(recording, 0.0, noise=0.01, seed=4)
    run = replay(noisy, IcrParams.ideal(B))
    result = evaluate([Data(noisy)], [
        Candidate('ideal', IcrParams.ideal(B)), Candidate('true', TRUE),
        Candidate('online_ideal', IcrParams.ideal(B), runs=(run,))])
    assert list(result.models) == ['ideal', 'true', 'online_ideal']
    mean = {name: m['odometry']['horizon']['mean_rmse_translation_m']
            for name, m in result.models.items()}
    assert mean['true'] < mean['online_ideal'] < 0.5 * mean['ideal']
    assert result.models['ideal']['prediction'] is None
