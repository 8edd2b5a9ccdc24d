"""terrain_file: the one writer of identify_icr's and identify_drivetrain's terrain files."""

import math

import pytest
from tracked_kinematics.core.errors import FitError
from tracked_kinematics.offline.terrain_file import terrain_values, write_terrain_file
from tracked_kinematics.params import drivetrain_from_values, icr_from_values

BASE = {'track_width': 0.5, 'terrain': 'old', 'identification.cost': 1.0, 'extra': 5,
        'drivetrain.delay': 0.02, 'drivetrain.pid.kp': 3.0, 'drivetrain_fit.rms': 9.0,
        'sprocket_radius': 0.12}


def test_icr_values_drop_the_old_record_and_terrain_keep_the_rest_in_place():
    fitted = {'track_width': 0.42, 'sprocket_radius': 0.1, 'icr.y_left': 0.35,
              'icr.y_right': -0.42, 'icr.x': 0.03, 'scale.left': 1.0, 'scale.right': 1.0,
              'terrain': 'grass'}
    values = terrain_values(BASE, fitted, record='identification', check=icr_from_values,
                            extras={'cost': 0.5, 'chi': math.nan, 'bags': ['a']},
                            drop=('terrain',))
    assert list(values) == [
        'track_width', 'extra', 'drivetrain.delay', 'drivetrain.pid.kp', 'drivetrain_fit.rms',
        'sprocket_radius', 'icr.y_left', 'icr.y_right', 'icr.x', 'scale.left', 'scale.right',
        'terrain', 'identification.cost', 'identification.bags']
    assert values['track_width'] == 0.42 and values['terrain'] == 'grass'
    assert values['identification.cost'] == 0.5   # the new record, never a non-finite value


def test_drivetrain_values_drop_the_old_drive_train_and_record():
    fitted = {'sprocket_radius': 0.1, 'drivetrain.delay': 0.03, 'drivetrain.max_accel': 1.5,
              'drivetrain.loop': 'first_order', 'drivetrain.time_constant': 0.15}
    values = terrain_values(BASE, fitted, record='drivetrain_fit',
                            check=drivetrain_from_values, extras={'rms': 0.01},
                            drop=('drivetrain.',))
    assert list(values) == ['track_width', 'terrain', 'identification.cost', 'extra',
                            'sprocket_radius', 'drivetrain.delay', 'drivetrain.max_accel',
                            'drivetrain.loop', 'drivetrain.time_constant', 'drivetrain_fit.rms']
    assert values['drivetrain_fit.rms'] == 0.01 and values['sprocket_radius'] == 0.1


def test_an_invalid_model_is_a_fit_error():
    with pytest.raises(FitError, match='^the identified model is invalid, nothing written: '
                       'icr.y_left'):
        terrain_values({'track_width': 0.42, 'sprocket_radius': 0.1},
                       {'icr.y_left': -1.0, 'icr.y_right': 1.0}, record='identification',
                       check=icr_from_values, extras={})


def test_written_file_header_and_body(tmp_path):
    path = tmp_path / 'out.yaml'
    write_terrain_file(path, {'track_width': 0.42, 'identification.model': 'icr'},
                       tool='identify_icr', date='2026-01-02T03:04:05+00:00', note='one\ntwo')
    assert path.read_text() == (
        '# Terrain parameters written by identify_icr (tracked_kinematics) on '
        '2026-01-02T03:04:05+00:00.\n'
        '# Load with: --ros-args --params-file THIS_FILE\n'
        '# one\n'
        '# two\n'
        '/**:\n'
        '  ros__parameters:\n'
        '    track_width: 0.42\n'
        '    identification:\n'
        '      model: icr\n')
