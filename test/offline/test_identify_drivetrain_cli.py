"""identify_drivetrain: user errors are one line with status 2, a bug is a traceback.

The fit itself and the other error paths: test/core/identify/test_drivetrain_fit.py.
"""

import json
import re

import numpy as np
import pytest
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.bags import BagWriter
from tracked_kinematics.offline.cli import identify_drivetrain as cli

JOINTS = ['left_sprocket_joint', 'right_sprocket_joint']


@pytest.fixture(scope='module')
def sim_bag(tmp_path_factory):
    return simulate_bag(tmp_path_factory.mktemp('drive') / 'auriga', 'auriga_alpha',
                        duration=20.0, seed=2).bag


def run(argv, capsys):
    argv = [str(a) for a in argv]
    if '--sprocket-radius' not in argv and '--params' not in argv:
        argv += ['--sprocket-radius', '0.1']  # the vehicle: there is no default one
    status = cli.main(argv)
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
    ('sprocket_radius: 0.1\ndrivetrain:\n  delay: -1\n',
     r'base.yaml: drivetrain.delay must be >= 0, got -1$'),
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
        cli.main([str(sim_bag), '-o', str(tmp_path / 'o.yaml'), '--sprocket-radius', '0.1'])
    assert capsys.readouterr().err == ''


@pytest.mark.parametrize('argv, pattern', [
    (['--dt', '1e-7'], r'--dt: must be in \[0.001, 0.1\] s, got 1e-7'),
    (['--max-delay', '1e9'], r'--max-delay: must be in \[0, 2\] s'),
    (['--max-gap', '-1'], r'--max-gap: must be in \[0, 60\] s'),
    (['--sprocket-radius', '5e-324'], r'--sprocket-radius: must be in \[0.005, 5\] m'),
])
def test_absurd_numbers_are_refused_before_any_work(tmp_path, capsys, argv, pattern):
    with pytest.raises(SystemExit) as exc:
        cli.main(['no_such_bag', '-o', str(tmp_path / 'o.yaml'), *argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert_one_line(err, pattern)
    assert list(tmp_path.iterdir()) == []


def test_the_grid_is_bounded_before_the_fit(sim_bag, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli, 'MAX_GRID_SAMPLES', 10_000)
    status, err = run([sim_bag, '-o', tmp_path / 'o.yaml', '--dt', '0.001'], capsys)
    assert status == 2
    assert_one_line(err, r'--dt 0.001 s over 20 s of data is a grid of 20,\d{3} samples '
                         r'\(at most 10,000\); give a larger --dt or fewer bags$')
    assert list(tmp_path.iterdir()) == []


def test_existing_output_needs_force_and_all_outputs_come_together(sim_bag, tmp_path, capsys):
    out, report = tmp_path / 'o.yaml', tmp_path / 'r.json'
    out.write_text('old\n')
    status, err = run([sim_bag, '-o', out, '--report', report], capsys)
    assert status == 2
    assert_one_line(err, r'--output .*o.yaml exists; use --force to replace it$')
    assert out.read_text() == 'old\n' and not report.exists()
    status, err = run([sim_bag, '-o', out, '--report', report, '--force'], capsys)
    assert status == 0, err
    assert out.read_text().startswith('# Terrain parameters with the drive train written by')
    assert report.read_text().startswith('{')


def test_base_file_typos_and_non_numbers(sim_bag, tmp_path, capsys):
    base = tmp_path / 'base.yaml'
    base.write_text('sprocket_radius: abc\n')
    status, err = run([sim_bag, '-o', tmp_path / 'o.yaml', '--params', base], capsys)
    assert status == 2
    assert_one_line(err, r"base.yaml: sprocket_radius must be a finite number > 0, got 'abc'$")
    base.write_text('sprocket_radius: 0.1\ndrivetrain:\n  time_constnt: 0.2\n')
    status, err = run([sim_bag, '-o', tmp_path / 'o.yaml', '--params', base], capsys)
    assert status == 0, err
    assert err.splitlines()[0] == (
        f"identify_drivetrain: warning: {base}: unknown parameter 'drivetrain.time_constnt' is "
        "not used (did you mean 'drivetrain.time_constant'?)")


def test_delay_is_explained_with_its_uncertainty(sim_bag, tmp_path, capsys):
    report = tmp_path / 'd.json'
    assert cli.main([str(sim_bag), '-o', str(tmp_path / 'd.yaml'), '--report', str(report),
                     '--sprocket-radius', '0.1']) == 0
    out = capsys.readouterr().out
    assert re.search(r'delay: of the measured speeds \(encoder stamps\) behind the setpoints '
                     r'\(bag receive times\), any clock offset between the two included; its '
                     r'standard error from (a jackknife|the \d+ ms grid alone)', out)
    doc = json.loads(report.read_text())
    assert doc['delay_uncertainty'] and doc['delay_at_zero'] is False
    assert doc['standard_errors']['delay'] >= 0.5 * doc['dt']


def test_per_side_speed_topics_with_a_grid_step(tmp_path, capsys):
    # track_speeds encoders carry no joint velocities: the --dt check took len(None) and
    # crashed with a TypeError before the one bag reader.
    path = tmp_path / 'sides'
    rng = np.random.default_rng(0)
    command = speed = 0.0
    with BagWriter(path) as bag:
        for k in range(1500):
            if k % 100 == 0:
                command = float(rng.uniform(-1.0, 1.0))
            speed += (command - speed) * 0.1    # a first-order loop, T = 0.2 s
            stamp = 10**18 + k * 20_000_000
            for side in ('left', 'right'):
                bag.write(f'/{side}_track/setpoint', stamp, bag.float64(command))
                bag.write(f'/{side}_track/speed', stamp, bag.float64(speed))
    status, err = run([path, '--output', tmp_path / 'o.yaml', '--encoder-input', 'track_speeds',
                       '--dt', '0.02'], capsys)
    assert status == 0, err
    assert (tmp_path / 'o.yaml').exists()
