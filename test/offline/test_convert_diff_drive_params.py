"""convert_diff_drive_params: DDC controllers files in, terrain files out, odometry kept."""

import math
import os
from pathlib import Path
import subprocess
import sys

from helpers.ddc_odometry import ddc_from_parameters, run_ddc, run_ours, wheel_stream
import numpy as np
import pytest
from tracked_kinematics.offline.cli.convert_diff_drive_params import main
from tracked_kinematics.offline.ddc import convert, convert_file, DdcError
from tracked_kinematics.params import flatten, icr_from_values, read_params_file
import yaml

DATA = Path(__file__).resolve().parents[1] / 'data' / 'ddc'
BIN = Path(sys.executable).parent
PROG = 'convert_diff_drive_params'

# Fixture -> (--controller or None, path to its DDC parameters in the YAML).
FIXTURES = {
    'ros2_controllers_test_humble.yaml': (None, ['test_diff_drive_controller']),
    'ros2_controllers_test_jazzy.yaml': (None, ['test_diff_drive_controller']),
    'husky_style_controllers.yaml': (None, ['husky_velocity_controller']),
    'rosbot_style_controllers.yaml': (None, ['/**', 'rosbot_base_controller']),
    'namespaced_jazzy_controllers.yaml': (None, ['/a200_0000/platform_velocity_controller']),
    'two_controllers.yaml': ('base_controller', ['base_controller']),
    'narrow_multiplier.yaml': (None, ['mobile_base_controller']),
}


def ddc_params(name):
    """Return the DDC parameters of a fixture, read from its YAML (not by the tool)."""
    node = yaml.safe_load((DATA / name).read_text())
    for key in FIXTURES[name][1]:
        node = node[key]
    return flatten(node.get('ros__parameters', node))


def run(capsys, *args):
    """Run the tool in-process; return (status, stdout, stderr)."""
    status = main([str(a) for a in args])
    out = capsys.readouterr()
    return status, out.out, out.err


def convert_fixture(capsys, tmp_path, name, *extra):
    controller = FIXTURES[name][0]
    output = tmp_path / f'{Path(name).stem}.terrain.yaml'
    args = [DATA / name, '--output', output, *extra]
    if controller:
        args += ['--controller', controller]
    status, out, err = run(capsys, *args)
    assert status == 0, err
    return output, out, err


def assert_refused(status, err, tmp_path, *fragments, before=None):
    """Exit 2, one error line naming the problem, and nothing new in ``tmp_path``."""
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f'{PROG}: error: '), err
    for fragment in fragments:
        assert fragment in lines[0]
    if before is not None:
        assert sorted(os.listdir(tmp_path)) == before


# --- what each fixture becomes ---------------------------------------------------------------

EXPECTED = {
    'ros2_controllers_test_humble.yaml': {
        'track_width': 0.4, 'sprocket_radius': 0.1, 'icr.y_left': 0.2, 'icr.y_right': -0.2,
        'icr.x': 0.0, 'scale.left': 1.0, 'scale.right': 1.0, 'left_joints': ['left_wheels'],
        'right_joints': ['right_wheels'], 'odom_frame': 'odom', 'base_frame': 'base_link',
        'publish_tf': True, 'cmd_timeout': 0.5, 'use_stamped': False,
        'linear.x.max_velocity': 0.0, 'linear.x.max_acceleration': 0.0,
        'angular.z.max_velocity': 0.0, 'angular.z.max_acceleration': 0.0},
    'ros2_controllers_test_jazzy.yaml': {
        'track_width': 0.4, 'icr.y_left': 0.2, 'icr.y_right': -0.2, 'cmd_timeout': 0.5,
        'linear.x.max_velocity': 0.0, 'linear.x.max_acceleration': 0.0,
        'angular.z.max_velocity': 0.0, 'angular.z.max_acceleration': 0.0},
    'husky_style_controllers.yaml': {
        'track_width': 0.512, 'sprocket_radius': 0.1651, 'icr.y_left': 0.384,
        'icr.y_right': -0.384, 'left_joints': ['front_left_wheel_joint', 'rear_left_wheel_joint'],
        'right_joints': ['front_right_wheel_joint', 'rear_right_wheel_joint'],
        'publish_rate': 50.0, 'linear.x.max_velocity': 1.0, 'linear.x.max_acceleration': 3.0,
        'angular.z.max_velocity': 2.0, 'angular.z.max_acceleration': 6.0},
    'rosbot_style_controllers.yaml': {
        'track_width': 0.186, 'icr.y_left': 0.13485, 'icr.y_right': -0.13485,
        'publish_tf': False, 'publish_rate': 20.0, 'odom_frame': 'odom',
        'linear.x.max_velocity': 1.5, 'angular.z.max_acceleration': 2.0},
    'namespaced_jazzy_controllers.yaml': {
        'track_width': 0.512, 'icr.y_left': 0.48, 'icr.y_right': -0.48, 'scale.left': 1.012,
        'scale.right': 0.994, 'odom_frame': 'a200_0000/odom',
        'base_frame': 'a200_0000/base_link', 'cmd_timeout': 0.0,
        'linear.x.max_velocity': 0.5, 'linear.x.max_acceleration': 1.0,
        'angular.z.max_velocity': 2.0, 'angular.z.max_acceleration': 4.0},
    'two_controllers.yaml': {
        'track_width': 0.42, 'icr.y_left': 0.273, 'icr.y_right': -0.273},
    'narrow_multiplier.yaml': {
        'track_width': 0.45, 'sprocket_radius': 0.08, 'icr.y_left': 0.225,
        'icr.y_right': -0.225, 'scale.left': 1.02, 'scale.right': 1.02,
        'left_joints': ['left_track_joint'], 'right_joints': ['right_track_joint'],
        'base_frame': 'base_footprint', 'cmd_timeout': 0.25},
}


@pytest.mark.parametrize('name', sorted(FIXTURES))
def test_fixture_values(capsys, tmp_path, name):
    output, out, _ = convert_fixture(capsys, tmp_path, name)
    values = {}
    for node in ('odometry_node', 'cmd_vel_translator', 'icr_estimator'):
        values.update(read_params_file(output, node))
    for key, expected in EXPECTED[name].items():
        assert values[key] == (pytest.approx(expected) if isinstance(expected, float)
                               else expected), key
    # Every key of the DDC section is accounted for on stdout.
    for key in ddc_params(name):
        assert key in out, key
    assert f'wrote {output}' in out


@pytest.mark.parametrize('name', sorted(FIXTURES))
def test_converted_file_reproduces_ddc_odometry(capsys, tmp_path, name):
    # Converter end to end: its file, read as the nodes read it, gives DDC's odometry on a
    # joint stream (DDC's side configured from the fixture's own parameters).
    output, _, _ = convert_fixture(capsys, tmp_path, name)
    values = read_params_file(output)
    icr = icr_from_values(values)
    rng = np.random.default_rng(len(name))
    times = 10.0 + np.cumsum(rng.uniform(0.005, 0.05, 1500))
    tau = times - times[0]
    v_left = 0.5 - 0.6 * np.sin(tau / 3.0)
    v_right = 0.5 + 0.6 * np.sin(tau / 5.0)
    positions = wheel_stream(times, v_left, v_right, values['sprocket_radius'])
    theirs = run_ddc(ddc_from_parameters(ddc_params(name)), times, *positions)
    ours, _ = run_ours(icr, values['sprocket_radius'], times, *positions)
    error = np.abs(np.asarray(ours) - np.asarray(theirs)).max()
    assert error < 1e-9
    path_length = np.hypot(*np.diff(np.asarray(theirs)[:, :2], axis=0).T).sum()
    assert path_length > 10.0


def test_every_node_reads_the_vehicle_joints_and_frames_and_no_yaml_aliases(capsys, tmp_path):
    # Issue 31 items 1 and 5: the joints reach calibration_drive, and no section naming a
    # node holds what -p should override, except icr_estimator's other publish_rate.
    output, _, _ = convert_fixture(capsys, tmp_path, 'husky_style_controllers.yaml')
    text = output.read_text()
    doc = yaml.safe_load(text)
    # rcl's YAML parser refuses anchors and aliases: the joint lists are written twice.
    assert '&' not in text and '*id' not in text
    assert set(doc) == {'/**', '/**/odometry_node'}
    assert set(flatten(doc['/**/odometry_node']['ros__parameters'])) == {'publish_rate'}
    shared = flatten(doc['/**']['ros__parameters'])
    assert {'track_width', 'sprocket_radius', 'icr.y_left', 'scale.left', 'left_joints',
            'right_joints', 'odom_frame', 'base_frame', 'publish_tf', 'cmd_timeout'} <= set(shared)
    for node in ('calibration_drive', 'icr_estimator', 'cmd_vel_translator'):
        assert read_params_file(output, node)['left_joints'] == shared['left_joints']
    assert 'publish_rate' not in read_params_file(output, 'icr_estimator')
    assert text.startswith('# Converted by convert_diff_drive_params')


@pytest.mark.parametrize('key, meant', [
    ('wheel_seperation_multiplier', 'wheel_separation_multiplier'),
    ('left_wheel_radius_multiplyer', 'left_wheel_radius_multiplier'),
    ('linear.x.max_velocty', 'linear.x.max_velocity'),
])
def test_a_misspelt_key_that_is_mapped_stops_the_conversion(capsys, tmp_path, key, meant):
    # Issue 31 item 7: wheel_seperation_multiplier 1.4 became chi = 1 with exit 0.
    source = write(tmp_path, 'base_controller:\n' + BASIC + f'    {key}: 1.4\n')
    output = tmp_path / 'out.yaml'
    assert main([str(source), '--output', str(output)]) == 2
    err = capsys.readouterr().err
    assert f'{key!r} (did you mean {meant!r}?)' in err
    assert not output.exists()


def test_a_misspelt_key_without_counterpart_is_a_hint(capsys, tmp_path):
    source = write(tmp_path, 'base_controller:\n' + BASIC + '    pose_covariance_diagonl: [1]\n'
                   '    wheel_separation_multiplyer: 1.0\n    wheel_separation_multiplier: 1.2\n')
    assert main([str(source), '--output', str(tmp_path / 'out.yaml')]) == 0
    out = capsys.readouterr().out
    assert "did you mean 'pose_covariance_diagonal'?" in out
    assert "did you mean 'wheel_separation_multiplier'?" in out


# --- finding the section ---------------------------------------------------------------------


def write(tmp_path, text, name='controllers.yaml'):
    path = tmp_path / name
    path.write_text(text)
    return path


BASIC = ('  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
         '    left_wheel_names: [l]\n    right_wheel_names: [r]\n')


def test_several_controllers_need_controller(capsys, tmp_path):
    before = sorted(os.listdir(tmp_path))
    status, out, err = run(capsys, DATA / 'two_controllers.yaml', '--output', tmp_path / 'o.yaml')
    assert_refused(status, err, tmp_path, 'base_controller', 'sim_base_controller',
                   '--controller', before=before)
    assert out == ''
    status, _, err = run(capsys, DATA / 'two_controllers.yaml', '--output', tmp_path / 'o.yaml',
                         '--controller', 'sim_base_controller')
    assert status == 0, err
    assert read_params_file(tmp_path / 'o.yaml')['icr.y_left'] == pytest.approx(0.21)


def test_controller_by_name_and_errors(capsys, tmp_path):
    status, _, err = run(capsys, DATA / 'two_controllers.yaml', '--output', tmp_path / 'o.yaml',
                         '--controller', 'nope')
    assert_refused(status, err, tmp_path, "'nope'", 'base_controller, sim_base_controller',
                   before=[])
    path = write(tmp_path, 'controller_manager:\n  ros__parameters:\n    jsb:\n'
                 '      type: joint_state_broadcaster/JointStateBroadcaster\n'
                 'jsb:\n' + BASIC)
    status, _, err = run(capsys, path, '--output', tmp_path / 'o.yaml', '--controller', 'jsb')
    assert_refused(status, err, tmp_path, 'JointStateBroadcaster')
    # Undeclared, found by its keys; declared of another type, skipped.
    status, _, err = run(capsys, path, '--output', tmp_path / 'o.yaml')
    assert_refused(status, err, tmp_path, 'no diff_drive_controller section')


def test_section_found_by_keys_in_plain_and_wildcard_forms(tmp_path):
    plain = write(tmp_path, 'wheel_separation: 0.5\nwheel_radius: 0.1\n', 'plain.yaml')
    assert convert_file(plain).values['track_width'] == 0.5
    star = write(tmp_path, '/**/base:\n' + BASIC, 'star.yaml')
    conversion = convert_file(star)
    assert conversion.controller == 'base'
    assert any('any namespace' in w for w in conversion.warnings)
    own_type = write(tmp_path, 'base:\n  ros__parameters:\n    type: '
                     'diff_drive_controller/DiffDriveController\n    wheel_separation: 0.5\n'
                     '    wheel_radius: 0.1\n', 'own_type.yaml')
    assert 'its type is' in convert_file(own_type).found_by
    namespaced = write(tmp_path, '/robot/base:\n' + BASIC, 'ns.yaml')
    assert convert_file(namespaced).values['odom_frame'] == 'robot/odom'


@pytest.mark.parametrize('text, fragment', [
    ('a: [1, 2\n', 'not valid YAML'),
    ('', 'an empty file'),
    ('- 1\n- 2\n', 'not a YAML mapping'),
    ('controller_manager:\n  ros__parameters:\n    update_rate: 50\n',
     'no diff_drive_controller section'),
    ('controller_manager:\n  ros__parameters:\n    base:\n'
     '      type: diff_drive_controller/DiffDriveController\n',
     "'base' is declared as diff_drive_controller/DiffDriveController but the file has no"),
    ('base:\n  ros__parameters:\n    wheel_radius: 0.1\n    left_wheel_names: [l]\n',
     'wheel_separation is missing'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    left_wheel_names: [l]\n',
     'wheel_radius is missing'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.0\n    wheel_radius: 0.1\n',
     'wheel_separation must be a finite number > 0 m, got 0.0'),
    ('base:\n  ros__parameters:\n    wheel_separation: .nan\n    wheel_radius: 0.1\n',
     'wheel_separation must be a finite number > 0 m, got .nan'),
    ('base:\n  ros__parameters:\n    wheel_separation: [0.5]\n    wheel_radius: 0.1\n',
     'wheel_separation must be a number'),
    ('base:\n  ros__parameters:\n    wheel_separation: $(var sep)\n    wheel_radius: 0.1\n',
     'launch substitution'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: -0.1\n',
     'wheel_radius must be a finite number > 0'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    wheel_separation_multiplier: 0\n', 'wheel_separation_multiplier must be'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    left_wheel_radius_multiplier: -1.0\n', 'left_wheel_radius_multiplier must be'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    left_wheel_names: []\n    right_wheel_names: [r]\n', 'left_wheel_names is empty'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    left_wheel_names: [a, b]\n    right_wheel_names: [b]\n', 'both list b'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    enable_odom_tf: maybe\n', 'enable_odom_tf must be true or false'),
    ('base:\n  ros__parameters:\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    odom_frame_id: /odom\n', 'odom_frame_id must not start with "/"'),
    # rcl refuses anchors and aliases; a recursive one must not hang or crash the tool.
    ('a: &x\n  b: *x\n', 'line 2: YAML alias *x'),
    ('base:\n  ros__parameters: &p\n    wheel_separation: 0.5\n    wheel_radius: 0.1\n'
     '    linear: *p\n', 'anchors and aliases'),
    ('[' * 3000 + ']' * 3000 + '\n', 'nested too deeply'),
    ('a: ' + '{k: ' * 1500 + '1' + '}' * 1500 + '\n', 'nested too deeply'),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(capsys, tmp_path, text, fragment):
    path = write(tmp_path, text)
    before = sorted(os.listdir(tmp_path))
    status, out, err = run(capsys, path, '--output', tmp_path / 'terrain.yaml')
    assert_refused(status, err, tmp_path, fragment, before=before)
    assert out == ''


@pytest.mark.parametrize('make, fragment', [
    (lambda p: p, 'no such file'),
    (lambda p: (p.mkdir(), p)[1], 'not a regular file'),
])
def test_missing_or_directory_input(capsys, tmp_path, make, fragment):
    source = make(tmp_path / 'controllers.yaml')
    status, _, err = run(capsys, source, '--output', tmp_path / 'terrain.yaml')
    assert_refused(status, err, tmp_path, fragment)
    assert not (tmp_path / 'terrain.yaml').exists()


def test_binary_input(capsys, tmp_path):
    path = tmp_path / 'controllers.yaml'
    path.write_bytes(b'\xff\xfe\x00wheel')
    status, _, err = run(capsys, path, '--output', tmp_path / 'terrain.yaml')
    assert_refused(status, err, tmp_path, 'not a text')


# --- outputs ---------------------------------------------------------------------------------


def test_existing_output_needs_force(capsys, tmp_path):
    target = tmp_path / 'terrain.yaml'
    target.write_text('mine\n')
    status, _, err = run(capsys, DATA / 'husky_style_controllers.yaml', '--output', target)
    assert_refused(status, err, tmp_path, 'exists; use --force', before=['terrain.yaml'])
    assert target.read_text() == 'mine\n'
    status, _, err = run(capsys, DATA / 'husky_style_controllers.yaml', '--output', target,
                         '--force')
    assert status == 0, err
    assert read_params_file(target)['track_width'] == 0.512
    assert sorted(os.listdir(tmp_path)) == ['terrain.yaml']


@pytest.mark.parametrize('force', [[], ['--force']])
def test_symlink_or_directory_output_refused(capsys, tmp_path, force):
    real = tmp_path / 'real.yaml'
    real.write_text('mine\n')
    link = tmp_path / 'link.yaml'
    link.symlink_to(real)
    status, _, err = run(capsys, DATA / 'husky_style_controllers.yaml', '--output', link, *force)
    assert_refused(status, err, tmp_path, 'symbolic link')
    assert real.read_text() == 'mine\n' and link.is_symlink()
    folder = tmp_path / 'folder'
    folder.mkdir()
    status, _, err = run(capsys, DATA / 'husky_style_controllers.yaml', '--output', folder, *force)
    assert_refused(status, err, tmp_path, 'is a directory')
    assert list(folder.iterdir()) == []
    status, _, err = run(capsys, DATA / 'husky_style_controllers.yaml', '--output',
                         tmp_path / 'missing' / 't.yaml', *force)
    assert_refused(status, err, tmp_path, 'does not exist')
    assert sorted(os.listdir(tmp_path)) == ['folder', 'link.yaml', 'real.yaml']


def test_output_checked_before_the_input_is_read(capsys, tmp_path):
    # Both wrong: the output is named first, as every tool checks outputs before any work.
    target = tmp_path / 'terrain.yaml'
    target.write_text('mine\n')
    status, _, err = run(capsys, tmp_path / 'missing.yaml', '--output', target)
    assert_refused(status, err, tmp_path, '--output')


def test_input_is_never_the_output(capsys, tmp_path):
    source = tmp_path / 'controllers.yaml'
    source.write_text((DATA / 'husky_style_controllers.yaml').read_text())
    status, _, err = run(capsys, source, '--output', source, '--force')
    assert_refused(status, err, tmp_path, 'is the input file')
    assert source.read_text() == (DATA / 'husky_style_controllers.yaml').read_text()


def test_failure_after_the_output_check_leaves_nothing(capsys, tmp_path):
    # The output is reserved, then the conversion fails: no file, no temporary file.
    source = write(tmp_path, 'base:\n  ros__parameters:\n    wheel_separation: 0.5\n')
    status, _, err = run(capsys, source, '--output', tmp_path / 'terrain.yaml')
    assert_refused(status, err, tmp_path, 'wheel_radius is missing',
                   before=['controllers.yaml'])


# --- the mapping, key by key -----------------------------------------------------------------

GEOMETRY = {'wheel_separation': 0.4, 'wheel_radius': 0.1, 'left_wheel_names': ['l'],
            'right_wheel_names': ['r']}


def conv(**params):
    return convert({**GEOMETRY, **params}, 'base', 'test')


def test_multiplier_below_one_keeps_ddc_kinematics_and_warns():
    c = conv(wheel_separation_multiplier=0.8)
    assert c.values['track_width'] == pytest.approx(0.32)
    assert c.values['icr.y_left'] == pytest.approx(0.16)
    assert c.values['icr.y_right'] == pytest.approx(-0.16)
    icr = icr_from_values(c.values)
    assert icr.chi == pytest.approx(1.0)
    assert c.narrowed and len(c.warnings) == 1
    assert '0.8 < 1' in c.warnings[0] and 'chi would be 1.25 > 1' in c.warnings[0]
    assert 'effective separation' in c.yaml_text()


def test_multiplier_above_one_is_chi():
    c = conv(wheel_separation_multiplier=1.6)
    assert c.values['track_width'] == 0.4
    assert icr_from_values(c.values).chi == pytest.approx(1 / 1.6)
    assert not c.warnings


def test_radius_multipliers_are_scales_and_ros1_names():
    c = conv(left_wheel_radius_multiplier=1.02, right_wheel_radius_multiplier=0.98)
    assert (c.values['scale.left'], c.values['scale.right']) == (1.02, 0.98)
    c = convert({'wheel_separation': 0.4, 'wheel_radius': 0.1, 'wheel_radius_multiplier': 1.05,
                 'left_wheel': 'l', 'right_wheel': ['r1', 'r2']})
    assert (c.values['scale.left'], c.values['scale.right']) == (1.05, 1.05)
    assert (c.values['left_joints'], c.values['right_joints']) == (['l'], ['r1', 'r2'])
    assert any('different counts' in w for w in c.warnings)


def test_missing_wheel_names_warn_and_are_not_written():
    c = convert({'wheel_separation': 0.4, 'wheel_radius': 0.1})
    assert 'left_joints' not in c.values and 'right_joints' not in c.values
    assert sum('wheel_names is not in the section' in w for w in c.warnings) == 2


@pytest.mark.parametrize('nan', [math.nan, '.nan', '.NAN', 'nan', 'NaN'])
def test_nan_limits_are_no_limit(nan):
    c = conv(**{'linear.x.max_velocity': nan, 'angular.z.max_acceleration': nan})
    assert c.values['linear.x.max_velocity'] == 0.0
    assert c.values['angular.z.max_acceleration'] == 0.0
    assert 'linear.x.max_acceleration' not in c.values  # nothing given: our default applies
    assert not c.warnings


def test_has_limits_switches():
    c = conv(**{'linear.x.has_velocity_limits': False, 'linear.x.max_velocity': 0.7,
                'linear.x.has_acceleration_limits': True, 'linear.x.max_acceleration': '1e0',
                'linear.x.min_acceleration': -1.0})
    assert c.values['linear.x.max_velocity'] == 0.0
    assert c.values['linear.x.max_acceleration'] == 1.0
    assert not c.warnings
    c = conv(**{'angular.z.has_velocity_limits': True})
    assert any('DDC refuses' in w for w in c.warnings)
    assert c.values['angular.z.max_velocity'] == 0.0


def test_asymmetric_limits_write_the_tightest_and_warn():
    c = conv(**{'linear.x.max_velocity': 1.0, 'linear.x.min_velocity': -0.4,
                'linear.x.max_acceleration': 2.0, 'linear.x.max_deceleration': -3.0,
                'linear.x.max_acceleration_reverse': -1.5})
    assert c.values['linear.x.max_velocity'] == 0.4
    assert c.values['linear.x.max_acceleration'] == 1.5
    assert len(c.warnings) == 2
    assert 'linear.x.min_velocity = -0.4' in c.warnings[0]
    assert 'slowing down' in c.warnings[1]


def test_zero_limits_cannot_be_expressed_and_warn():
    # With has_* true DDC clamps to 0 (forbids that direction); 0 means none here.
    c = conv(**{'angular.z.has_velocity_limits': True, 'angular.z.max_velocity': 1.0,
                'angular.z.min_velocity': 0.0})
    assert c.values['angular.z.max_velocity'] == 1.0
    assert any('angular.z.min_velocity = 0.0' in w and 'cannot forbid' in w for w in c.warnings)
    c = conv(**{'linear.x.max_velocity': 0.0})
    assert c.values['linear.x.max_velocity'] == 0.0
    assert any('without has_velocity_limits' in w for w in c.warnings)


def test_jerk_is_reported_not_mapped():
    c = conv(**{'linear.x.has_jerk_limits': True, 'linear.x.max_jerk': 5.0})
    assert not any('jerk' in k for k in c.values)
    assert any('jerk' in w for w in c.warnings)
    assert any('linear.x.max_jerk = 5.0' in ddc for ddc, _ in c.not_mapped)
    c = conv(**{'linear.x.has_jerk_limits': False, 'linear.x.max_jerk': 5.0})
    assert not c.warnings


@pytest.mark.parametrize('given, written, warns', [
    (0.0, 0.0, False), (0, 0.0, False), (math.inf, 0.0, False), (0.25, 0.25, False),
    (500, 500.0, True), (-1.0, None, True), ('.nan', None, True)])
def test_cmd_vel_timeout(given, written, warns):
    c = conv(cmd_vel_timeout=given)
    assert c.values.get('cmd_timeout') == written
    assert bool(c.warnings) == warns


def test_frames_tf_rate_stamped():
    c = conv(odom_frame_id='odom_wheels', base_frame_id='base_footprint', enable_odom_tf=False,
             publish_rate=30, use_stamped_vel=True)
    assert c.values['odom_frame'] == 'odom_wheels'
    assert c.values['base_frame'] == 'base_footprint'
    assert c.values['publish_tf'] is False
    assert c.values['publish_rate'] == 30.0
    assert c.values['use_stamped'] is True


def test_tf_frame_prefix():
    c = convert({**GEOMETRY, 'tf_frame_prefix': '/robot1/'}, 'base', 'test')
    assert (c.values['odom_frame'], c.values['base_frame']) == ('robot1/odom',
                                                                'robot1/base_link')
    c = convert({**GEOMETRY, 'tf_frame_prefix_enable': False}, 'ns/base', 'test', 'ns')
    assert 'odom_frame' not in c.values
    c = convert({**GEOMETRY, 'odom_frame_id': 'odom'}, 'ns/base', 'test', 'ns')
    assert c.values['odom_frame'] == 'ns/odom'


def test_every_key_is_reported_with_a_reason():
    params = {**GEOMETRY, 'open_loop': True, 'position_feedback': False,
              'pose_covariance_diagonal': [0.1] * 6, 'velocity_rolling_window_size': 5,
              'publish_limited_velocity': True, 'wheels_per_side': 2, 'mystery_key': 3,
              'use_sim_time': True}
    c = convert(params, 'base', 'test')
    reported = ' '.join(ddc for ddc, _ in c.mapped + c.not_mapped)
    for key in params:
        assert key in reported, key
    reasons = {ddc.split(' = ')[0]: why for ddc, why in c.not_mapped}
    assert 'not a ROS 2 diff_drive_controller parameter' in reasons['mystery_key']
    assert 'noise model' in reasons['pose_covariance_diagonal']
    assert any('open_loop' in w for w in c.warnings)


def test_a_bad_value_names_the_file_and_the_controller(tmp_path):
    path = write(tmp_path, 'base:\n  ros__parameters:\n    wheel_separation: 0.5\n')
    with pytest.raises(DdcError, match=r"controllers.yaml: controller 'base': wheel_radius"):
        convert_file(path)


# --- the console script ----------------------------------------------------------------------


def test_console_script(tmp_path):
    script = BIN / PROG
    assert os.access(script, os.X_OK), 'run make setup (or pip install -e .) first'
    output = tmp_path / 'terrain.yaml'
    done = subprocess.run([str(script), str(DATA / 'narrow_multiplier.yaml'), '--output',
                           str(output)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert 'mapped (diff_drive_controller -> tracked_kinematics):' in done.stdout
    assert f'{PROG}: warning: wheel_separation_multiplier 0.9 < 1' in done.stderr
    assert read_params_file(output)['track_width'] == 0.45
    again = subprocess.run([str(script), str(DATA / 'narrow_multiplier.yaml'), '--output',
                            str(output)], capture_output=True, text=True, timeout=60)
    assert again.returncode == 2
    assert again.stderr.strip().splitlines() == [
        f'{PROG}: error: --output {output} exists; use --force to replace it']
    helped = subprocess.run([str(script), '--help'], capture_output=True, text=True, timeout=60)
    assert helped.returncode == 0 and '--controller NAME' in helped.stdout


def test_values_the_nodes_would_refuse_are_refused(monkeypatch):
    # The converted values are checked with the parameter tables the nodes declare, ranges
    # included: a range on track_width (as a table may add) refuses a 1e-300 m vehicle.
    from tracked_kinematics.offline.ddc import mapping
    from tracked_kinematics.params import ParamSpec, positive, TERRAIN_PARAMS
    ranged = tuple(ParamSpec(s.name, s.default, s.description, s.unit, s.check, low=0.01)
                   if s.name == 'track_width' else s for s in TERRAIN_PARAMS)
    monkeypatch.setattr(mapping, 'TERRAIN_PARAMS', ranged)
    assert positive(1e-300) is None
    with pytest.raises(DdcError, match=r'would not start the nodes: track_width must be >= '):
        convert({**GEOMETRY, 'wheel_separation': 1e-300})
    assert convert(GEOMETRY).values['track_width'] == 0.4
