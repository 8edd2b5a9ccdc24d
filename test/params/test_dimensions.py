"""One vehicle given twice (params/dimensions.py): the rule every tool and node applies.

The tools that apply it: test/offline/test_vehicle_given_twice.py and the tools' own tests.
"""

import pytest
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.params.dimensions import (
    check_same_vehicle, dimension_conflicts, DIMENSION_KEYS, dimensions_of, same_dimension,
    VehicleMismatch)

HUSKY = {'track_width': 0.5384615384615384, 'sprocket_radius': 0.15875}
WARTHOG = {'track_width': 1.08, 'sprocket_radius': 0.3}


def test_a_husky_file_beside_the_warthogs_track_width_is_refused_naming_both():
    with pytest.raises(VehicleMismatch) as caught:
        check_same_vehicle(('--track-width', {'track_width': 1.08}), ('husky.yaml', HUSKY))
    message = str(caught.value)
    assert message.startswith('track_width 1.08 m from --track-width and 0.538462 m from '
                              'husky.yaml differ by 50 %, more than rounding (1 %)')
    assert '\n' not in message
    # A refusal is bad input to every front door (exit status 2, a FATAL line).
    assert isinstance(caught.value, InvalidParameters)
    with pytest.raises(VehicleMismatch, match='^sprocket_radius 0.15875 m from a.yaml and '
                                              '0.3 m from b.yaml'):
        check_same_vehicle(('a.yaml', HUSKY), ('b.yaml', WARTHOG), keys=('sprocket_radius',))


@pytest.mark.parametrize('a, b, same', [
    (0.5384615384615384, 0.54, True),    # rounded to the centimetre: 0.3 %
    (0.5384615384615384, 0.5, False),    # 7 %
    (0.15875, 0.159, True),
    (0.15875, 0.16, True),               # 0.8 %
    (0.15875, 0.15, False),
    (0.0325, 0.033, True),               # rounded to the millimetre: 1.5 %, 0.5 mm
    (0.0325, 0.034, False),
    (1.08, 1.0908, True), (1.08, 1.0912, False),
])
def test_rounding_is_one_percent_or_half_a_millimetre(a, b, same):
    assert same_dimension(a, b) is same
    assert same_dimension(b, a) is same


def test_a_dimension_given_once_or_not_a_number_is_not_compared():
    check_same_vehicle(('--track-width', {'track_width': None}), ('husky.yaml', HUSKY))
    check_same_vehicle(('a.yaml', {'track_width': 0.54}), ('b.yaml', {}))
    # Not a number: the file's own check names it; here it is no second value.
    check_same_vehicle(('a.yaml', {'track_width': 'abc'}), ('b.yaml', HUSKY))
    check_same_vehicle(('a.yaml', {'track_width': True}), ('b.yaml', HUSKY))
    check_same_vehicle(('a.yaml', {'track_width': float('nan')}), ('b.yaml', HUSKY))


def test_terrain_and_vehicle_files_name_the_radius_differently():
    assert dimensions_of({'track_width': 0.42, 'sprocket_radius': 0.1}) == {
        'track_width': 0.42, 'sprocket_radius': 0.1}
    assert dimensions_of({'track_width': 0.4, 'encoders.sprocket_radius': 0.085}) == {
        'track_width': 0.4, 'sprocket_radius': 0.085}
    assert dimensions_of({}) == {'track_width': None, 'sprocket_radius': None}


# The nodes' form: every source listed, one message per dimension.

AURIGA = {'track_width': 0.42, 'sprocket_radius': 0.1}


def test_rounding_agrees_and_another_robot_does_not():
    assert same_dimension(0.5384615384615384, 0.538)     # the Husky's, to the millimetre
    assert same_dimension(0.116702, 0.117)                # the Marmotte's sprocket
    assert same_dimension(1.08, 1.0826)                   # 0.24 %
    assert not same_dimension(0.42, 1.08)                 # the Auriga's on the Warthog
    assert not same_dimension(0.1, 0.3)
    assert not same_dimension(1.08, 1.1)                  # 1.9 %: a measured, not a rounded


def test_each_dimension_given_twice_differently_is_named_with_both_sources():
    problems = dimension_conflicts([('params file auriga.yaml', AURIGA),
                                    ('-p track_width:=1.08', {'track_width': 1.08})])
    assert len(problems) == 1
    assert problems[0].startswith('track_width is 0.42 m in params file auriga.yaml but '
                                  '1.08 m in -p track_width:=1.08')
    both = dimension_conflicts([('auriga.yaml', AURIGA), ('warthog.yaml', WARTHOG)])
    assert [p.split()[0] for p in both] == list(DIMENSION_KEYS)


def test_once_agreeing_or_not_a_number_is_no_conflict():
    assert dimension_conflicts([('a.yaml', AURIGA)]) == []
    assert dimension_conflicts([('a.yaml', AURIGA), ('b.yaml', {'icr.x': 0.1})]) == []
    assert dimension_conflicts([('a.yaml', AURIGA), ('-p', {'track_width': 0.4201})]) == []
    # A value that is no number is its own check's to refuse, not a second vehicle.
    for odd in ('wide', True, float('nan'), None):
        assert dimension_conflicts([('a.yaml', AURIGA), ('-p', {'track_width': odd})]) == []
