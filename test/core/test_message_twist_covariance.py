"""The twist covariance per message: the mean over the message's own interval."""

import numpy as np
import pytest
from tracked_kinematics.core.covariance import (body_jacobian, message_twist_covariance,
                                                TrackNoise, twist_covariance, TWIST_TIME,
                                                twist_variances)
from tracked_kinematics.core.kinematics import IcrParams

ICR = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)


@pytest.mark.parametrize('interval', [0.001, 0.01, 0.05, 1.0, 2.5])
def test_the_mean_over_the_interval_of_a_random_walk(interval):
    """Travel variance k |d| per track over ``interval`` s: its mean's, B Q B^T / dt^2."""
    noise = TrackNoise(2e-3, 3e-3, 0.0)
    speeds = (0.4, -0.1)
    one_second = twist_covariance(body_jacobian(ICR), *twist_variances(noise, *np.abs(speeds)),
                                  TWIST_TIME)
    exact = twist_covariance(body_jacobian(ICR), *noise.travel_variances(
        *(np.abs(speeds) * interval)), interval)
    np.testing.assert_allclose(message_twist_covariance(one_second, interval), exact,
                               rtol=1e-12)
    # Fused as independent measurements, a second of messages carries the 1-s mean's
    # information whatever the rate.
    per_second = 1.0 / interval * 1.0 / message_twist_covariance(one_second, interval)[0]
    assert per_second == pytest.approx(1.0 / one_second[0])


@pytest.mark.parametrize('interval', [0.0, -1.0, float('nan')])
def test_no_interval_leaves_it(interval):
    upper = (1.0, 0.0, 0.0, 2.0, 0.0, 3.0)
    assert message_twist_covariance(upper, interval) == upper
