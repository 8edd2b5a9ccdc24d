"""Commands from bags: setpoints or cmd_vel (Twist, TwistStamped) through the ideal inverse.

Also identify_drivetrain on a base that takes cmd_vel (issue 17).
"""

import re

from helpers.command_bags import write_commands_bag
import numpy as np
import pytest
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.bags import (
    BagError, CommandSource, EncoderSource, GroundTruthSource, read_recording)
from tracked_kinematics.offline.cli import identify_drivetrain
from tracked_kinematics.offline.model_evaluation import commands_of

B = 0.42
GT = GroundTruthSource('/ground_truth/pose')
ENC = EncoderSource(sprocket_radius=0.1)


@pytest.fixture(scope='module')
def sim(tmp_path_factory):
    return simulate_bag(tmp_path_factory.mktemp('cmd') / 'sim', 'auriga_alpha', duration=30.0,
                        seed=4)


@pytest.fixture(scope='module')
def bags(sim, tmp_path_factory):
    root = tmp_path_factory.mktemp('cmdbags')
    paths = {}
    for kind in ('setpoints', 'twist', 'twist_stamped', 'none'):
        paths[kind] = root / kind
        write_commands_bag(paths[kind], sim.run, B, commands=kind)
    return paths


def read_with_commands(path, commands=CommandSource('auto')):
    """Read as evaluate_model does: the recording and its commands (or None)."""
    rec = read_recording(path, ENC, ground_truth=GT, commands=commands)
    return rec, commands_of(rec)


def test_cmd_vel_through_the_ideal_inverse_gives_the_setpoints_back(bags):
    _, setpoints = read_with_commands(bags['setpoints'])
    assert setpoints[2] == 'setpoints'
    for kind in ('twist', 'twist_stamped'):
        rec, cmd_vel = read_with_commands(bags[kind], CommandSource('auto', track_width=B))
        assert cmd_vel[2] == 'cmd_vel'
        assert rec.cmd_vel.shape == (len(rec.cmd_vel_t), 2)
        np.testing.assert_allclose(cmd_vel[0], setpoints[0], atol=1e-9)
        np.testing.assert_allclose(cmd_vel[1], setpoints[1], atol=1e-12)
        assert rec.duration == pytest.approx(30.0, abs=0.1)


def test_a_bag_without_commands_has_none_unless_asked(bags):
    rec, found = read_with_commands(bags['none'])
    assert found is None and len(rec.gt_t) > 100
    with pytest.raises(BagError, match='no topic /left_track/setpoint for the setpoints'):
        read_with_commands(bags['none'], CommandSource('setpoints'))
    _, none = read_with_commands(bags['setpoints'], CommandSource('none'))
    assert none is None


def test_cmd_vel_needs_the_track_width(bags):
    with pytest.raises(BagError, match=r'needs the track width \(--track-width or --params\)'):
        read_with_commands(bags['twist'], CommandSource('cmd_vel'))
    with pytest.raises(BagError, match='topic /joint_states has type sensor_msgs/msg/JointState; '
                                       'the commands must be geometry_msgs/msg/Twist or '
                                       'geometry_msgs/msg/TwistStamped'):
        read_with_commands(bags['twist'], CommandSource('cmd_vel', cmd_vel_topic='/joint_states',
                                                        track_width=B))


def test_drive_bag_with_cmd_vel_has_the_same_commands(bags):
    setpoints = read_recording(bags['setpoints'], ENC, commands=CommandSource())
    cmd_vel = read_recording(bags['twist_stamped'], ENC,
                             commands=CommandSource('auto', track_width=B))
    np.testing.assert_allclose(cmd_vel.commands, setpoints.commands, atol=1e-12)
    np.testing.assert_allclose(cmd_vel.command_t, setpoints.command_t, atol=1e-9)
    with pytest.raises(BagError, match=r'no topic /left_track/setpoint for the setpoints \(nor '
                                       r'/cmd_vel for cmd_vel\); topics present: '):
        read_recording(bags['none'], ENC,
                       commands=CommandSource('auto', track_width=B, required=True))


def _fit(argv, capsys):
    argv = [str(a) for a in argv]
    if '--params' not in argv:
        argv += ['--sprocket-radius', '0.1']  # the vehicle: there is no default one
    status = identify_drivetrain.main(argv)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_identify_drivetrain_fits_a_cmd_vel_base_like_a_setpoint_one(bags, tmp_path, capsys):
    status, setpoint_out, _ = _fit([bags['setpoints'], '-o', tmp_path / 'a.yaml'], capsys)
    assert status == 0
    status, twist_out, _ = _fit([bags['twist'], '-o', tmp_path / 'b.yaml', '--track-width', B],
                                capsys)
    assert status == 0

    def values(text):
        return re.findall(r'^(delay|max_accel|time_constant)\s+(\S+)', text, re.M)

    assert values(twist_out) == values(setpoint_out) and len(values(twist_out)) == 3


def test_identify_drivetrain_cmd_vel_without_a_track_width_is_bad_input(bags, tmp_path, capsys):
    status, _, err = _fit([bags['twist'], '-o', tmp_path / 'c.yaml', '--command-source',
                           'cmd_vel'], capsys)
    assert status == 2 and err.count('\n') == 1
    assert 'needs the track width (--track-width or --params)' in err
    assert not (tmp_path / 'c.yaml').exists()
    base = tmp_path / 'base.yaml'
    base.write_text(f'track_width: {B}\nsprocket_radius: 0.1\n')
    status, _, err = _fit([bags['twist'], '-o', tmp_path / 'd.yaml', '--params', base], capsys)
    assert status == 0, err


def test_identify_drivetrain_on_a_bag_without_commands_names_both_topics(bags, tmp_path,
                                                                         capsys):
    status, _, err = _fit([bags['none'], '-o', tmp_path / 'e.yaml', '--track-width', B], capsys)
    assert status == 2 and err.count('\n') == 1
    assert ('no topic /left_track/setpoint for the setpoints (nor /cmd_vel for cmd_vel); '
            'topics present: ') in err
    assert not (tmp_path / 'e.yaml').exists()
