"""
A node given the vehicle twice, differently, refuses to start (issue 37 item 5).

The Auriga's terrain file beside the Warthog's ``-p track_width`` ran with one of the two,
silently: distances a third of the truth. Now one FATAL line names both sources, status 2.
"""

from helpers.ros_helpers import ConsoleScript
from helpers.setup_info import ROOT
import pytest
from tracked_kinematics.ros.main import run

AURIGA = '/**:\n  ros__parameters:\n    track_width: 0.42\n    sprocket_radius: 0.1\n'


class Built(Exception):
    """The node factory was reached: the start was not refused for the dimensions."""


def reached():
    raise Built('the factory was reached')


def fatal_line(capfd):
    err = capfd.readouterr().err
    lines = [line for line in err.splitlines() if '[FATAL]' in line]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize('second, names', [
    (['-p', 'track_width:=1.08'],
     ('track_width is 0.42 m in params file', '-p track_width:=1.08')),
    (['--params-file', '{warthog}'], ('track_width is 0.42 m', 'warthog.yaml')),
    # A node's own section of a second file, as launch writes the parameters it is given.
    (['--params-file', '{section}'], ('sprocket_radius is 0.1 m', 'section.yaml')),
])
def test_a_second_vehicle_refuses_the_start_naming_both(tmp_path, capfd, second, names):
    auriga, warthog, section = (tmp_path / f'{n}.yaml' for n in ('auriga', 'warthog', 'section'))
    auriga.write_text(AURIGA)
    warthog.write_text('/**:\n  ros__parameters:\n    track_width: 1.08\n')
    section.write_text('probe:\n  ros__parameters:\n    sprocket_radius: 0.3\n')
    argv = ['probe', '--ros-args', '--params-file', str(auriga),
            *(a.format(warthog=warthog, section=section) for a in second)]
    assert run(reached, 'probe', argv) == 2
    line = fatal_line(capfd)
    assert all(name in line for name in names), line
    assert str(auriga) in line


@pytest.mark.parametrize('second', [
    ['-p', 'track_width:=0.420'],                        # the same, written otherwise
    ['-p', 'sprocket_radius:=0.1004'],                   # rounding
    ['-p', 'icr.x:=0.05'],                               # not a dimension
    ['--params-file', '{other_node}'],                   # another node's section
])
def test_the_same_vehicle_twice_starts(tmp_path, capfd, second):
    auriga, other = tmp_path / 'auriga.yaml', tmp_path / 'other.yaml'
    auriga.write_text(AURIGA)
    other.write_text('someone_else:\n  ros__parameters:\n    track_width: 1.08\n')
    argv = ['probe', '--ros-args', '--params-file', str(auriga),
            *(a.format(other_node=other) for a in second)]
    assert run(reached, 'probe', argv) == 2     # the factory's own failure, not the vehicle's
    assert 'the factory was reached' in fatal_line(capfd)


@pytest.mark.ros
def test_the_console_script_refuses_the_auriga_file_on_a_warthog(tmp_path):
    terrain = ROOT / 'config' / 'auriga_alpha_hard_floor.yaml'
    with ConsoleScript('odometry_node', '--ros-args', '--params-file', terrain,
                       '-p', 'track_width:=1.08', tmp_path=tmp_path) as node:
        assert node.wait(60) == 2, node.output
    fatal = [line for line in node.output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1, node.output
    assert f'params file {terrain}' in fatal[0] and '-p track_width:=1.08' in fatal[0]
