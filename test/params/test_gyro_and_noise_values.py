"""The gyro's and the noise model's values: one table for odometry_node and evaluate_model."""

import math

import pytest
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.params import (gyro_config_from_values, GYRO_PARAMS,
                                       noise_model_from_values, NOISE_PARAMS)
from tracked_kinematics.ros.odometry_node import PARAMS


def test_the_node_declares_the_tables_it_shares():
    names = {spec.name for spec in PARAMS}
    assert {spec.name for spec in GYRO_PARAMS + NOISE_PARAMS} <= names


def test_missing_values_are_the_nodes_defaults():
    defaults = {spec.name: spec.default for spec in PARAMS}
    gyro = gyro_config_from_values({})
    assert (gyro.imu_delay, gyro.gyro_scale, gyro.timeout, gyro.adapt) == (
        defaults['imu_delay'], defaults['gyro_scale'], defaults['imu_timeout'],
        defaults['adapt_slip'])
    # The gates are on by default (issue 35), from a ground vehicle's limits; 0 turns them off.
    assert (gyro.saturation, gyro.max_jump) == (defaults['imu_saturation'],
                                                defaults['imu_max_jump'])
    assert (gyro.saturation, gyro.max_jump) == (10.0, 5.0)
    off = gyro_config_from_values({'imu_saturation': 0.0, 'imu_max_jump': 0.0})
    assert off.saturation == math.inf and off.max_jump == math.inf
    assert (gyro.gyro_bias, gyro.gyro_bias_sigma) == (0.0, 0.0)     # no prior
    prior = gyro_config_from_values({'gyro_bias': -0.015, 'gyro_bias_sigma': 0.002})
    assert (prior.gyro_bias, prior.gyro_bias_sigma) == (-0.015, 0.002)
    noise = noise_model_from_values({})
    assert (noise.turn, noise.slip, noise.timing) == (
        defaults['covariance.turn'], defaults['covariance.slip'], defaults['covariance.timing'])
    assert noise.track == pytest.approx(defaults['covariance.k_left'])


@pytest.mark.parametrize('read, name, value', [
    (gyro_config_from_values, 'gyro_scale', 1e300),
    (gyro_config_from_values, 'imu_delay', math.nan),
    (gyro_config_from_values, 'imu_timeout', -1.0),
    (gyro_config_from_values, 'gyro_scale', '1e308'),
    (gyro_config_from_values, 'gyro_bias', math.inf),
    (gyro_config_from_values, 'gyro_bias_sigma', -0.001),
    (noise_model_from_values, 'covariance.slip', 1e300),
    (noise_model_from_values, 'covariance.k_left', -1e-3),
    (noise_model_from_values, 'covariance.timing', math.inf),
])
def test_a_value_the_node_refuses_is_refused_here_too(read, name, value):
    with pytest.raises(InvalidParameters, match=name.replace('.', r'\.')):
        read({name: value})
