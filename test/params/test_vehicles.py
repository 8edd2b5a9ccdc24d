"""The vehicle file is where a vehicle's values are checked, once (the core trusts them)."""

import math

import pytest
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.params.vehicles import robot_from_values


@pytest.mark.parametrize('name, value, message', [
    ('mass', 0.0, 'mass must be > 0'),
    ('friction.mu_y', math.nan, 'friction.mu_y must be finite'),
    ('centre_of_mass.z', -0.1, 'centre_of_mass.z must be >= 0'),
    ('track_width', 'wide', 'track_width must be a number'),
    ('encoders.ticks_per_revolution', -1.0, 'encoders.ticks_per_revolution must be >= 0'),
    ('encoders.scale.left', 0.0, 'encoders.scale.left must be > 0'),
])
def test_a_value_out_of_range_is_refused_naming_it(name, value, message):
    with pytest.raises(InvalidParameters, match=message):
        robot_from_values({name: value})


def test_an_impossible_geometry_is_refused_in_file_names():
    # Checked by the core's Vehicle (no single range says it), named as in the file.
    with pytest.raises(InvalidParameters, match='centre_of_mass.y'):
        robot_from_values({'centre_of_mass.y': -0.3, 'track_width': 0.42})
