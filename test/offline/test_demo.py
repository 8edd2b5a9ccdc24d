"""The README's main job: simulate, identify_icr, and odometry on held-out paths."""

import csv
import io
import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import IdealDiffDrive
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.offline.cli import tracked_kinematics_demo as demo
from tracked_kinematics.params import icr_from_values, read_params_file

BIN = Path(sys.executable).parent
SHORT = ['--duration', '90', '--paths', '2', '--path-duration', '30']


@pytest.fixture(scope='module')
def demo_run(tmp_path_factory):
    out_dir = tmp_path_factory.mktemp('demo') / 'out'
    stdout = io.StringIO()
    args = demo.build_parser().parse_args(['--output', str(out_dir), '--seed', '3'] + SHORT)
    status = demo.run(args, stdout)
    return status, out_dir, stdout.getvalue()


def _rows(out_dir):
    with open(out_dir / 'heldout.csv', newline='', encoding='utf-8') as stream:
        return list(csv.DictReader(stream))


def test_demo_succeeds_and_writes_every_output(demo_run):
    status, out_dir, stdout = demo_run
    assert status == 0, stdout
    for name in ('hard_floor.yaml', 'identify_report.json', 'heldout.csv'):
        assert (out_dir / name).is_file(), name
    for name in ('identify.png', 'heldout.png'):
        assert (out_dir / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n', name
    assert (out_dir / 'calibration' / 'auriga_alpha_hard_floor' / 'metadata.yaml').is_file()
    assert (out_dir / 'calibration' / 'auriga_alpha_hard_floor.truth.yaml').is_file()
    bags = sorted(p.name for p in (out_dir / 'heldout').iterdir() if p.is_dir())
    assert bags == ['path1_random', 'path2_sweep']
    report = json.loads((out_dir / 'identify_report.json').read_text())
    assert report['bags'] == [str((out_dir / 'calibration' / 'auriga_alpha_hard_floor')
                                  .resolve())]


def test_demo_says_where_outputs_are(demo_run):
    _, out_dir, stdout = demo_run
    for step in ('1. ', '2. ', '3. ', '4. '):
        assert f'\n{step}' in stdout or stdout.startswith(step), step
    for name in ('hard_floor.yaml', 'identify_report.json', 'identify.png', 'heldout.csv',
                 'heldout.png'):
        assert str(out_dir / name) in stdout, name
    yaml_path = (out_dir / 'hard_floor.yaml').resolve()
    assert (f'ros2 run tracked_kinematics odometry_node --ros-args --params-file {yaml_path}'
            in stdout)
    # The fitted YAML is shown, with its values.
    icr = icr_from_values(read_params_file(out_dir / 'hard_floor.yaml'))
    assert f'y_left: {icr.y_left!r}' in stdout


def test_identified_yaml_is_a_valid_model_near_the_simulated_truth(demo_run):
    _, out_dir, _ = demo_run
    icr = icr_from_values(read_params_file(out_dir / 'hard_floor.yaml'))
    assert 0.0 < icr.chi <= 1.0
    # A tracked vehicle slips: ICRs outside the track centrelines.
    assert icr.y_left > icr.track_width / 2 and icr.y_right < -icr.track_width / 2
    truth = icr_from_values(read_params_file(
        out_dir / 'calibration' / 'auriga_alpha_hard_floor.truth.yaml'))
    assert abs(icr.chi - truth.chi) < 0.03
    assert abs(icr.eccentricity - truth.eccentricity) < 0.03
    assert abs(icr.scale_left - truth.scale_left) < 0.01
    assert abs(icr.scale_right - truth.scale_right) < 0.01


def test_identified_model_beats_ideal_on_every_held_out_path(demo_run):
    _, out_dir, stdout = demo_run
    rows = _rows(out_dir)
    assert len(rows) == 2
    for row in rows:
        assert float(row['distance_m']) > 1.0
        ideal = float(row['ideal_position_error_m'])
        identified = float(row['identified_position_error_m'])
        assert identified < 0.5 * ideal, row
        pct = 100 * identified / float(row['distance_m'])
        assert float(row['identified_error_pct_of_distance']) == pytest.approx(pct, rel=1e-4)
        assert row['path'] in stdout
    # Final headings can agree by chance on one path (S-curves cancel), not on average.
    heading = {m: np.mean([float(r[f'{m}_heading_error_deg']) for r in rows])
               for m in ('ideal', 'identified')}
    assert heading['identified'] < 0.5 * heading['ideal']
    # The printed mean is the mean of the rows.
    mean_ideal = np.mean([float(r['ideal_position_error_m']) for r in rows])
    mean_row = next(line for line in stdout.splitlines() if line.strip().startswith('mean'))
    assert f'{mean_ideal:.3f}' in mean_row


def test_rerun_replaces_the_previous_outputs_only(tmp_path):
    out_dir = tmp_path / 'out'
    demo.prepare_output(out_dir)
    (out_dir / 'heldout' / 'path1_random').mkdir(parents=True)
    (out_dir / 'old_terrain.yaml').write_text('x: 1\n')
    (out_dir / 'notes.txt').write_text('mine\n')
    demo.prepare_output(out_dir)
    assert not (out_dir / 'heldout').exists()
    assert not (out_dir / 'old_terrain.yaml').exists()
    assert (out_dir / 'notes.txt').read_text() == 'mine\n'


def _random_travel(n, seed):
    rng = np.random.default_rng(seed)
    speeds = np.repeat(rng.uniform(-1.0, 1.0, size=(n // 50 + 1, 2)), 50, axis=0)[:n]
    speeds += rng.normal(0.0, 0.01, size=speeds.shape)
    travel = np.vstack([np.zeros((1, 2)), np.cumsum(speeds * 0.01, axis=0)])
    return travel[:, 0] + 0.3, travel[:, 1] - 1.2   # any offset of a counter


def test_dead_reckoning_agrees_with_odometry_stepped_message_by_message():
    icr = IcrParams(0.42, 0.3688, -0.4581, 0.0551, 1.0099, 1.0330)
    left, right = _random_travel(3000, 1)
    poses = demo.dead_reckon(icr, left, right)
    odo = Odometry(icr)
    stepped = [odo.pose]
    for d_left, d_right in zip(np.diff(left), np.diff(right)):
        assert odo.update(float(d_left), float(d_right), 0.01)
        stepped.append(odo.pose)
    np.testing.assert_allclose(poses, np.array(stepped), atol=1e-9)
    assert np.ptp(poses[:, 2]) > 1.0   # the test path does turn


def test_ideal_dead_reckoning_is_diff_drive_controllers():
    left, right = _random_travel(1000, 2)
    poses = demo.dead_reckon(IcrParams.ideal(0.42), left, right)
    x, y, theta = IdealDiffDrive(0.42).integrate((), np.diff(left), np.diff(right), 0.01)
    np.testing.assert_allclose(poses[1:], np.column_stack([x, y, theta]), atol=1e-12)
    np.testing.assert_array_equal(poses[0], [0.0, 0.0, 0.0])


def _one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert err.startswith('tracked_kinematics_demo: error: ') and '\n' not in err, err
    return err


def test_unknown_vehicle_is_a_one_line_error(tmp_path, capsys):
    assert demo.main(['--vehicle', 'no_such_robot', '--output', str(tmp_path / 'o')]) == 2
    err = _one_line_error(capsys)
    assert 'no_such_robot' in err and 'auriga_alpha' in err
    assert not (tmp_path / 'o').exists()


def test_unwritable_output_is_a_one_line_error(tmp_path, capsys):
    blocker = tmp_path / 'file'
    blocker.write_text('not a directory\n')
    assert demo.main(['--output', str(blocker / 'out')] + SHORT) == 2
    assert str(blocker / 'out') in _one_line_error(capsys)


def test_terrain_name_must_be_a_file_name(tmp_path, capsys):
    assert demo.main(['--terrain', '../up', '--output', str(tmp_path / 'o')]) == 2
    assert "'../up'" in _one_line_error(capsys)
    assert not (tmp_path / 'o').exists()


def test_foreign_directory_is_left_alone(tmp_path, capsys):
    (tmp_path / 'thesis.tex').write_text('keep me\n')
    assert demo.main(['--output', str(tmp_path)] + SHORT) == 2
    assert 'not written by the demo' in _one_line_error(capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['thesis.tex']


def test_too_short_a_drive_reports_identify_icr_failure(tmp_path, capsys):
    status = demo.main(['--output', str(tmp_path / 'o'), '--duration', '5', '--paths', '1',
                        '--path-duration', '5'])
    assert status == 3   # identify_icr: too little motion
    err = capsys.readouterr().err
    assert 'identify_icr: error: too little motion' in err
    assert 'tracked_kinematics_demo: identify_icr failed' in err


def test_demo_console_script(tmp_path):
    result = subprocess.run([str(BIN / 'tracked_kinematics_demo'), '--paths', '1',
                             '--duration', '90', '--path-duration', '20'], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert 'demo_output/hard_floor.yaml' in result.stdout
    assert (tmp_path / 'demo_output' / 'hard_floor.yaml').is_file()
