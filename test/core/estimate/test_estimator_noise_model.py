"""The icr_estimator EKF with the terrain file's noise model (covariance.*) in its window noise."""

import numpy as np
import pytest
from tracked_kinematics.core.estimate.config import EstimatorConfig
from tracked_kinematics.core.estimate.ekf import SlipEstimator
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr

B = 0.42


def noise_parts(**noise):
    model = ConstantIcr(B, with_scales=False)
    est = SlipEstimator(model, model.from_icr(IcrParams.ideal(B)), EstimatorConfig(**noise))
    return est._noise_parts(2.0, np.array([1.5, 0.2, 0.5]))


def test_without_a_noise_model_the_window_noise_is_travel_std_alone():
    fixed, per_travel = noise_parts()
    travel2 = (0.01 * 2.0) ** 2
    np.testing.assert_allclose(per_travel, [travel2, travel2, 2 * travel2 / B ** 2])


def test_the_noise_model_adds_its_random_walks_over_the_window():
    base = noise_parts()[1]
    fixed, per_travel = noise_parts(track_noise=1e-3, turn_noise=2e-3, slip_noise=3e-2)
    # Travel 2 m, turned 0.5 rad (the measured heading change).
    pos = 0.5 * 1e-3 * 2.0 + 3e-2 * 0.5
    yaw = 2 * 1e-3 * 2.0 / B ** 2 + 2e-3 * 0.5
    np.testing.assert_allclose(per_travel - base, [pos, pos, yaw])
    assert fixed == pytest.approx(noise_parts()[0])
