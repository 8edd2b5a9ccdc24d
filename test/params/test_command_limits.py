"""Command limit parameters: ranges, "no limit" values, decelerations (issues 14 and 15)."""

import math

import pytest
from tracked_kinematics.core.command import TRACK_SPEED_ENVELOPE
from tracked_kinematics.params import COMMAND_LIMIT_PARAMS, limits_from_values
from tracked_kinematics.params.spec import means_no_limit


@pytest.mark.parametrize('none', [0.0, 0, math.nan, math.inf])
def test_zero_nan_and_inf_are_no_limit_and_never_reach_the_maths(none):
    names = ('max_track_speed', 'max_track_accel', 'linear.x.max_velocity',
             'linear.x.max_acceleration', 'angular.z.max_velocity',
             'angular.z.max_acceleration', 'max_track_decel', 'linear.x.max_deceleration',
             'angular.z.max_deceleration')
    limits = limits_from_values({name: none for name in names})
    for field in limits.__dataclass_fields__:
        assert getattr(limits, field) == math.inf, field


def test_deceleration_sign_and_default():
    limits = limits_from_values({'max_track_accel': 2.0, 'linear.x.max_acceleration': 1.0,
                                 'linear.x.max_deceleration': -3.0,  # DDC writes it negative
                                 'angular.z.max_deceleration': 5.0})
    assert limits.max_track_decel == 2.0  # unset: the acceleration limit, as in DDC
    assert limits.max_linear_deceleration == 3.0
    assert limits.max_angular_deceleration == 5.0
    assert limits.max_angular_acceleration == math.inf
    assert limits_from_values({'max_track_accel': 2.0, 'max_track_decel': math.nan}) \
        .max_track_decel == 2.0
    assert limits_from_values({'max_track_accel': 2.0, 'max_track_decel': math.inf}) \
        .max_track_decel == math.inf


@pytest.mark.parametrize('name, value, message', [
    ('max_track_speed', 31.0, 'max_track_speed must be in [0, 30] m/s'),
    ('max_track_speed', -1.0, 'max_track_speed must be >= 0'),
    ('max_track_speed', -math.inf, 'max_track_speed must be >= 0'),
    ('max_track_accel', 1e300, 'max_track_accel must be in [0, 100] m/s^2'),
    ('max_track_accel', -1.0, 'max_track_accel must be >= 0'),
    ('angular.z.max_acceleration', 'fast', 'angular.z.max_acceleration must be a number'),
    ('angular.z.max_velocity', 51.0, 'angular.z.max_velocity must be in [0, 50] rad/s'),
    ('linear.x.max_deceleration', -101.0, 'must be in [-100, 100] m/s^2'),
    ('max_track_decel', -math.inf, 'must not be -inf'),
    ('linear.x.max_velocity', 'fast', 'must be a number'),
    ('linear.x.max_velocity', True, 'must be a number'),
])
def test_out_of_range_refused_naming_it(name, value, message):
    with pytest.raises(ValueError, match=message.replace('[', r'\[').replace(']', r'\]')
                       .replace('^', r'\^')):
        limits_from_values({name: value})


def test_speed_ranges_are_the_envelope():
    by_name = {spec.name: spec for spec in COMMAND_LIMIT_PARAMS}
    assert by_name['max_track_speed'].high == TRACK_SPEED_ENVELOPE
    assert by_name['linear.x.max_velocity'].high == TRACK_SPEED_ENVELOPE
    assert all(spec.no_limit and spec.has_range for spec in COMMAND_LIMIT_PARAMS)
    assert by_name['max_track_speed'].validate(5e-324) is None  # tiny but a limit: stop
    assert 'or 0, .NAN, .inf' in by_name['max_track_speed'].validate(31.0)


def test_means_no_limit():
    assert all(map(means_no_limit, (0.0, 0, math.nan, math.inf)))
    assert not any(map(means_no_limit, (1.0, -math.inf, True, False, 'nan', None)))
