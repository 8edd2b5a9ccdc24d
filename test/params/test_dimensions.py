"""params.dimensions: a vehicle's dimensions given twice must agree within rounding."""

from tracked_kinematics.params.dimensions import (dimension_conflicts, DIMENSION_KEYS,
                                                  same_dimension)

AURIGA = {'track_width': 0.42, 'sprocket_radius': 0.1}
WARTHOG = {'track_width': 1.08, 'sprocket_radius': 0.3}


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
