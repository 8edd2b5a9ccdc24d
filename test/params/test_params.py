"""The parameter table and the terrain YAML."""

import os

import pytest
from tracked_kinematics.core.errors import InvalidParameters
from tracked_kinematics.params import (
    check_values, Derived, drivetrain_from_values, ENCODER_INPUT_PARAMS, flatten,
    icr_from_values, nest, ParamSpec,
    read_params_file, resolve, TERRAIN_DEFAULTS, TERRAIN_PARAMS, values_from_icr,
    write_params_file)
from tracked_kinematics.share import config_file
import yaml


def test_shipped_terrain_file_loads_with_interface_values():
    values = read_params_file(config_file('auriga_alpha_hard_floor.yaml'))
    icr = icr_from_values(values)
    assert (icr.track_width, icr.y_left, icr.y_right, icr.x) == (0.42, 0.353, -0.425, 0.032)
    assert (icr.scale_left, icr.scale_right) == (1.0072, 1.0275)
    assert values['sprocket_radius'] == 0.1


VEHICLE = {'track_width': 0.42, 'sprocket_radius': 0.1}


def test_no_default_vehicle():
    # Issue 15 item 1: track_width has no default (as DDC's wheel_separation).
    with pytest.raises(ValueError, match='^track_width has no default'):
        icr_from_values({})
    with pytest.raises(ValueError, match='^track_width has no default'):
        icr_from_values({'icr.y_left': 0.3, 'icr.y_right': -0.3})
    required = [spec.name for spec in TERRAIN_PARAMS if spec.required]
    assert required == ['track_width', 'sprocket_radius']


@pytest.mark.parametrize('width', [0.3, 0.42, 0.5, 2.0])
def test_icrs_default_to_the_ideal_drive_of_the_given_width(width):
    icr = icr_from_values({'track_width': width})
    assert (icr.y_left, icr.y_right, icr.x) == (width / 2, -width / 2, 0.0)
    assert (icr.scale_left, icr.scale_right) == (1.0, 1.0)
    assert icr.chi == pytest.approx(1.0) and icr.eccentricity == pytest.approx(0.0)
    # One ICR given: only the other follows the width.
    icr = icr_from_values({'track_width': width, 'icr.y_left': width})
    assert (icr.y_left, icr.y_right) == (width, -width / 2)


def test_resolve_applies_the_default_rule():
    values, missing = resolve(TERRAIN_PARAMS, {'track_width': 0.6, 'terrain': 'grass'})
    assert missing == ['sprocket_radius'] and 'terrain' not in values
    assert values == {'track_width': 0.6, 'icr.y_left': 0.3, 'icr.y_right': -0.3,
                      'icr.x': 0.0, 'scale.left': 1.0, 'scale.right': 1.0}
    # A derived default is left out while what it derives from is missing or invalid.
    assert 'icr.y_left' not in resolve(TERRAIN_PARAMS, {})[0]
    assert 'icr.y_left' not in resolve(TERRAIN_PARAMS, {'track_width': 'wide'})[0]


def test_spec_default_texts():
    by_name = {spec.name: spec for spec in TERRAIN_PARAMS}
    assert by_name['track_width'].default_text == 'required, no default'
    assert by_name['icr.y_right'].default_text == 'default -track_width / 2 unless set'
    assert by_name['icr.x'].default_text == 'default 0.0'
    assert '(required, no default)' in by_name['sprocket_radius'].full_description
    specs = (ParamSpec('w', 2.0, 'Width'),
             ParamSpec('half', 1.0, 'Half', derived=Derived('w / 2', lambda v: v['w'] / 2)))
    assert not specs[1].has_default
    assert resolve(specs, {'w': 3.0})[0] == {'w': 3.0, 'half': 1.5}
    assert resolve(specs, {})[0] == {'w': 2.0, 'half': 1.0}
    assert resolve(specs, {'half': 7.0})[0] == {'w': 2.0, 'half': 7.0}
    # The offline tools' command-line defaults still read the examples (their engineer's).
    assert set(TERRAIN_DEFAULTS) == {spec.name for spec in TERRAIN_PARAMS}


@pytest.mark.parametrize('values, match', [
    ({'icr.y_left': -0.5}, r'icr\.y_left .* must be greater than icr\.y_right'),
    ({'icr.y_left': 0.1, 'icr.y_right': -0.1}, 'chi .* outside'),
    ({'scale.left': 0.0}, r'scale\.left must be > 0'),
    ({'scale.left': 1e-300}, r'scale\.left must be in \[0.1, 10\]'),
    ({'sprocket_radius': -0.1}, 'sprocket_radius must be > 0'),
    ({'sprocket_radius': 5e-324}, r'sprocket_radius must be in \[0.005, 5\] m'),
    ({'icr.x': float('nan')}, r'icr\.x must be finite'),
    ({'icr.x': 1e6}, r'icr\.x must be in \[-100, 100\] m'),
    ({'track_width': True}, 'track_width must be a number'),
    ({'track_width': 1e-9}, r'track_width must be in \[0.01, 20\] m'),
])
def test_invalid_values_named_in_ros_terms(values, match):
    with pytest.raises(ValueError, match=match):
        icr_from_values({**VEHICLE, **values})


def test_every_numeric_parameter_has_a_range():
    for spec in TERRAIN_PARAMS + ENCODER_INPUT_PARAMS:
        if isinstance(spec.default, (int, float)) and not isinstance(spec.default, bool):
            assert spec.low is not None and spec.high is not None, spec.name


def test_check_values_ignores_unknown_names():
    assert check_values(TERRAIN_PARAMS, {'terrain': 'grass', 'track_width': 0.5}) == []
    assert check_values(TERRAIN_PARAMS, {'track_width': -1.0}) == [
        'track_width must be > 0, got -1.0']


def test_flatten_nest_round_trip():
    tree = {'icr': {'y_left': 1.0, 'x': 0.0}, 'track_width': 0.4}
    assert flatten(tree) == {'icr.y_left': 1.0, 'icr.x': 0.0, 'track_width': 0.4}
    assert nest(flatten(tree)) == tree


def test_write_then_read_round_trip(tmp_path):
    icr = icr_from_values({**VEHICLE, 'icr.y_left': 0.3, 'icr.y_right': -0.35, 'icr.x': 0.01})
    out = tmp_path / 'terrain.yaml'
    write_params_file(out, {**values_from_icr(icr, 0.12), 'terrain': 'turf'},
                      comment='fitted by a test')
    text = out.read_text()
    assert text.startswith('# fitted by a test\n')
    doc = yaml.safe_load(text)
    assert doc['/**']['ros__parameters']['icr']['y_right'] == -0.35
    assert icr_from_values(read_params_file(out)) == icr
    assert oct(out.stat().st_mode & 0o777) != oct(0o600)
    assert [p.name for p in tmp_path.iterdir()] == ['terrain.yaml']


def test_write_failure_leaves_old_file(tmp_path):
    out = tmp_path / 'terrain.yaml'
    out.write_text('old')
    with pytest.raises(yaml.representer.RepresenterError):
        write_params_file(out, {'bad': object()})
    assert out.read_text() == 'old'
    assert os.listdir(tmp_path) == ['terrain.yaml']


def test_node_section_overrides_wildcard(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text('/**:\n  ros__parameters:\n    track_width: 0.5\n'
                    'odometry_node:\n  ros__parameters:\n    track_width: 0.6\n'
                    'other:\n  ros__parameters:\n    track_width: 0.7\n')
    assert read_params_file(path)['track_width'] == 0.5
    assert read_params_file(path, 'odometry_node')['track_width'] == 0.6


@pytest.mark.parametrize('text', ['- a\n- b\n', 'x: [unclosed\n'])
def test_bad_yaml_is_a_value_error(tmp_path, text):
    path = tmp_path / 'p.yaml'
    path.write_text(text)
    with pytest.raises(ValueError, match='p.yaml'):
        read_params_file(path)


def test_unknown_parameters_name_the_closest_known_one():
    from tracked_kinematics.params import unknown_parameters
    assert unknown_parameters(['track_widht', 'zzz', 'track_width', 'zzz'], TERRAIN_PARAMS) == [
        "unknown parameter 'track_widht' ignored (did you mean 'track_width'?)",
        "unknown parameter 'zzz' ignored"]
    assert unknown_parameters(['track_widht', 'odom_frame'], ['track_width'], only_close=True,
                              ignored=' is not used') == [
        "unknown parameter 'track_widht' is not used (did you mean 'track_width'?)"]


def test_unknown_terrain_parameters():
    from tracked_kinematics.params import unknown_terrain_parameters
    values = {'track_widht': 0.4, 'icr.yleft': 0.3, 'icr.zzz': 1, 'scale.left': 1.0,
              'odom_frame': 'odom', 'identification.anything': 1, 'drivetrain_fit.rms': 0.1,
              'terrain': 'grass', 'max_track_speed': 1.0, 'left_joints': ['a'],
              'drivetrain.pid.kp': 1.0}
    assert unknown_terrain_parameters(values) == [
        "unknown parameter 'icr.yleft' is not used (did you mean 'icr.y_left'?)",
        "unknown parameter 'icr.zzz' is not used (did you mean 'icr.x'?)",
        "unknown parameter 'track_widht' is not used (did you mean 'track_width'?)"]


def test_a_fifo_is_not_read_as_a_params_file(tmp_path):
    # open() on a FIFO would block until a writer comes; refused at once instead.
    fifo = tmp_path / 'params.yaml'
    os.mkfifo(fifo)
    with pytest.raises(InvalidParameters, match='params.yaml: not a regular file'):
        read_params_file(fifo)


@pytest.mark.parametrize('name, value, message', [
    ('drivetrain.delay', -0.1, 'drivetrain.delay must be >= 0'),
    ('drivetrain.max_accel', -1.0, 'drivetrain.max_accel must be >= 0'),
    ('drivetrain.time_constant', 0.0, 'drivetrain.time_constant must be > 0'),
    ('drivetrain.motor.inertia', 0.0, 'drivetrain.motor.inertia must be > 0'),
    ('drivetrain.pid.kd', -1.0, 'drivetrain.pid.kd must be >= 0'),
])
def test_drive_train_values_are_checked_where_they_enter(name, value, message):
    # DriveTrain, FirstOrderLag and PidMotor trust their ranges: this is the one check.
    loop = 'pid_dc_motor' if name.startswith(('drivetrain.motor', 'drivetrain.pid')) \
        else 'first_order'
    with pytest.raises(InvalidParameters, match=message):
        drivetrain_from_values({'drivetrain.loop': loop, name: value})


def test_a_pid_loop_without_gain_is_refused_in_ros_names():
    with pytest.raises(InvalidParameters, match='drivetrain.pid: at least one of'):
        drivetrain_from_values({'drivetrain.loop': 'pid_dc_motor', 'drivetrain.pid.kp': 0.0,
                                'drivetrain.pid.ki': 0.0, 'drivetrain.pid.kd': 0.0})
