"""identify_drivetrain: user errors are one line with status 2, a bug is a traceback.

The fit itself and the other error paths: test/core/identify/test_drivetrain_fit.py.
"""

import json
import re

import numpy as np
import pytest
from tracked_kinematics.offline.bags import BagWriter
from tracked_kinematics.offline.cli import identify_drivetrain as cli
from tracked_kinematics.offline.cli.simulate_bag import simulate_bag

JOINTS = ['left_sprocket_joint', 'right_sprocket_joint']


@pytest.fixture(scope='module')
def sim_bag(tmp_path_factory):
    return simulate_bag(tmp_path_factory.mktemp('drive') / 'auriga', 'auriga_alpha',
                        duration=20.0, seed=2).bag


def run(argv, capsys):
    status = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    return status, err


def assert_one_line(err, pattern):
    assert err.startswith('identify_drivetrain: error: ') and err.count('\n') == 1
    assert re.search(pattern, err), err


def test_commands_and_speeds_that_do_not_overlap_are_bad_input(tmp_path, capsys):
    path = tmp_path / 'apart'
    with BagWriter(path) as bag:
        for i in range(400):
            stamp = 1_700_000_000 * 10**9 + i * 10_000_000
            if i < 200:
                bag.write('/joint_states', stamp, bag.joint_state(stamp, JOINTS, [],
                                                                  [3.0, 3.0]))
            else:
                bag.write('/left_track/setpoint', stamp, bag.float64(0.3 * np.sin(i / 10)))
                bag.write('/right_track/setpoint', stamp, bag.float64(0.3 * np.cos(i / 10)))
    status, err = run([path, '-o', tmp_path / 'o.yaml'], capsys)
    assert status == 2
    assert_one_line(err, r'the commands \(2.00-3.99 s\) and the measured speeds '
                         r'\(0.00-1.99 s\) do not overlap in time')
    assert not (tmp_path / 'o.yaml').exists()


@pytest.mark.parametrize('params, pattern', [
    ('a: [1, 2\n', r'base.yaml: not valid YAML'),
    ('drivetrain:\n  delay: -1\n', r'base.yaml: drivetrain.delay must be >= 0, got -1$'),
])
def test_bad_parameter_files_are_bad_input(sim_bag, tmp_path, capsys, params, pattern):
    base = tmp_path / 'base.yaml'
    base.write_text(params)
    status, err = run([sim_bag, '-o', tmp_path / 'o.yaml', '--params', base], capsys)
    assert status == 2
    assert_one_line(err, pattern)


def test_plot_format_matplotlib_cannot_write_is_bad_input(sim_bag, tmp_path, capsys):
    status, err = run([sim_bag, '-o', tmp_path / 'o.yaml', '--plot', tmp_path / 'p.xyz'],
                      capsys)
    assert status == 2
    assert_one_line(err, r"Format 'xyz' is not supported \(supported formats: .*png")


def test_plot_is_written_without_pyplot(sim_bag, tmp_path, capsys, no_pyplot):
    plot = tmp_path / 'drive.png'
    status, err = run([sim_bag, '-o', tmp_path / 'o.yaml', '--plot', plot], capsys)
    assert status == 0, err
    assert plot.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_a_bug_in_the_core_surfaces_as_a_traceback(sim_bag, tmp_path, capsys, monkeypatch):
    def bug(*args, **kwargs):
        raise ValueError('bug')
    monkeypatch.setattr(cli, 'fit_drivetrain', bug)
    with pytest.raises(ValueError, match='^bug$'):
        cli.main([str(sim_bag), '-o', str(tmp_path / 'o.yaml')])
    assert capsys.readouterr().err == ''


def test_delay_is_explained_with_its_uncertainty(sim_bag, tmp_path, capsys):
    report = tmp_path / 'd.json'
    assert cli.main([str(sim_bag), '-o', str(tmp_path / 'd.yaml'), '--report', str(report)]) == 0
    out = capsys.readouterr().out
    assert re.search(r'delay: of the measured speeds \(encoder stamps\) behind the setpoints '
                     r'\(bag receive times\), any clock offset between the two included; its '
                     r'standard error from (a jackknife|the \d+ ms grid alone)', out)
    doc = json.loads(report.read_text())
    assert doc['delay_uncertainty'] and doc['delay_at_zero'] is False
    assert doc['standard_errors']['delay'] >= 0.5 * doc['dt']
