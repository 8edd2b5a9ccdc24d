"""
The README's main job: simulate, identify_icr, and odometry on held-out paths.

``make demo``'s run (its defaults, in a directory of its own) is made once: its outputs are
checked here, and so are its page's sample output and the README's figures against what it
printed (test/helpers/demo_page.py regenerates the page's block).
"""

import csv
import json
import os
from pathlib import Path
import re
import shlex
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import IdealDiffDrive
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.offline.cli import tracked_kinematics_demo as demo
from tracked_kinematics.offline.demo_directory import (DemoDirectory, DemoError, Entry, MANIFEST,
                                                       planned_outputs)
from tracked_kinematics.params import icr_from_values, read_params_file

BIN = Path(sys.executable).parent
SHORT = ['--duration', '90', '--paths', '2', '--path-duration', '30']


PATHS = ('path1_random', 'path2_sweep', 'path3_random', 'path4_mixed')


@pytest.fixture(scope='module')
def demo_run(tmp_path_factory):
    """``make demo``'s demo: its directory, ``demo_output`` (relative to it), its stdout."""
    from helpers.demo_page import run_default_demo
    directory = tmp_path_factory.mktemp('demo')
    return directory, Path('demo_output'), run_default_demo(directory)


def _rows(out_dir):
    with open(out_dir / 'heldout.csv', newline='', encoding='utf-8') as stream:
        return list(csv.DictReader(stream))


def test_demo_succeeds_and_writes_every_output(demo_run):
    directory, out_dir, _ = demo_run
    out_dir = directory / out_dir
    for name in ('hard_floor.yaml', 'identify_report.json', 'heldout.csv'):
        assert (out_dir / name).is_file(), name
    for name in ('identify.png', 'heldout.png'):
        assert (out_dir / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n', name
    assert (out_dir / 'calibration' / 'auriga_alpha_hard_floor' / 'metadata.yaml').is_file()
    assert (out_dir / 'calibration' / 'auriga_alpha_hard_floor.truth.yaml').is_file()
    bags = sorted(p.name for p in (out_dir / 'heldout').iterdir() if p.is_dir())
    assert bags == list(PATHS)
    report = json.loads((out_dir / 'identify_report.json').read_text())
    assert report['bags'] == [str((out_dir / 'calibration' / 'auriga_alpha_hard_floor')
                                  .resolve())]


def test_demo_says_where_outputs_are(demo_run):
    directory, out_dir, stdout = demo_run
    for step in ('1. ', '2. ', '3. ', '4. '):
        assert f'\n{step}' in stdout or stdout.startswith(step), step
    for name in ('hard_floor.yaml', 'identify_report.json', 'identify.png', 'heldout.csv',
                 'heldout.png'):
        assert str(out_dir / name) in stdout, name
    yaml_path = (directory / out_dir / 'hard_floor.yaml').resolve()
    # What a venv user can run (the console scripts), the workspace form said once.
    lines = stdout.splitlines()
    assert lines[-1] == (f'   odometry_node --ros-args --params-file {yaml_path} '
                         '-p imu_topic:=/imu/data')
    assert 'ros2 run tracked_kinematics NAME' in stdout
    assert 'ros2 run tracked_kinematics odometry_node' not in stdout
    at = next(k for k, line in enumerate(lines) if line.startswith('   evaluate_model '))
    end = at
    while lines[end].endswith('\\'):
        end += 1
    command = ' '.join(line.strip().rstrip('\\').strip() for line in lines[at:end + 1])
    bags = ' '.join(str(out_dir / 'heldout' / name) for name in PATHS)
    assert command.startswith(f'evaluate_model {bags} --ground-truth-topic /ground_truth/pose '
                              f'--params {out_dir / "hard_floor.yaml"} --fuse-imu /imu/data')
    # The covariance's verdicts, one per row and window length.
    for row in ('hard_floor ', 'hard_floor+imu '):
        line = next(line for line in lines if line.startswith('   ' + row))
        assert sum(line.count(v) for v in (': consistent', ': over-confident',
                                           ': under-confident', ': too few windows')) == 2
    # The fitted YAML is shown, with its values.
    icr = icr_from_values(read_params_file(directory / out_dir / 'hard_floor.yaml'))
    assert f'y_left: {icr.y_left!r}' in stdout


def test_identified_yaml_is_a_valid_model_near_the_simulated_truth(demo_run):
    directory, out_dir, _ = demo_run
    out_dir = directory / out_dir
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
    directory, out_dir, stdout = demo_run
    rows = _rows(directory / out_dir)
    assert len(rows) == len(PATHS)
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


def test_the_printed_evaluate_model_command_runs_as_written(demo_run, capsys, monkeypatch):
    from tracked_kinematics.offline.cli import evaluate_model
    directory, _, stdout = demo_run
    monkeypatch.chdir(directory)
    lines = stdout.splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith('   evaluate_model '))
    end = at
    while lines[end].endswith('\\'):
        end += 1
    words = shlex.split(' '.join(line.rstrip('\\') for line in lines[at:end + 1]))
    capsys.readouterr()
    assert evaluate_model.main(words[1:]) == 0
    printed = capsys.readouterr().out
    assert 'published covariance: ' in printed and '\nbest on these bags ' in printed


# The demo's figures on its page and in the README, against this run (test/helpers/
# demo_page.py regenerates the page's block; test_docs.py checks that the comparison can fail).

def test_the_demo_page_shows_what_the_demo_prints(demo_run):
    from helpers.demo_page import differences, page_block, page_text_block, PAGE, REGENERATE
    problems = differences(page_text_block(PAGE.read_text()), page_block(demo_run[2]))
    assert not problems, (f'{PAGE.name} is stale: regenerate its output with '
                          f'`{REGENERATE}`: ' + '; '.join(problems[:5]))


def test_the_readme_demo_figures_are_the_demos(demo_run):
    from helpers.demo_page import differences, page_block, README
    demo_block = page_block(demo_run[2])
    text = README.read_text()
    section = text[text.index('## What the demo shows'):text.index('## On a robot')]
    block = re.search(r'^```\w*\n(.*?)^```', section, re.S | re.M).group(1)
    printed = demo_block.splitlines()
    for line in block.splitlines():
        # Each line of the README's excerpt is a line the demo prints, figures included.
        same = [p for p in printed if not differences(line, p)]
        assert same, f'README.md: the demo prints no line like {line.strip()!r}'
    for words in re.findall(r'chi \d\.\d+,\s+e \d\.\d+', section):
        words = ' '.join(words.split())
        assert any(not differences(words, found)
                   for found in re.findall(r'chi \d\.\d+, e \d\.\d+', demo_block)), words


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
    assert list(tmp_path.iterdir()) == []   # the directory it made, and the bag, removed


def tree(directory):
    """Every path under ``directory`` (relative), with the bytes of the files."""
    found = {}
    for root, dirs, files in os.walk(directory):
        for name in dirs + files:
            path = Path(root) / name
            found[str(path.relative_to(directory))] = (
                path.read_bytes() if path.is_file() and not path.is_symlink() else None)
    return found


@pytest.mark.long  # two demos (~20 s); the manifest's rules are tested below without one
def test_demo_console_script_twice_in_a_row(tmp_path):
    # `make demo` twice: the second run replaces the outputs its manifest lists, without
    # --force, and nothing else (the user's files, dotfiles and YAML files included).
    argv = [str(BIN / 'tracked_kinematics_demo'), '--paths', '1', '--duration', '90',
            '--path-duration', '20']
    first = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    assert 'demo_output/hard_floor.yaml' in first.stdout
    out = tmp_path / 'demo_output'
    assert (out / 'hard_floor.yaml').is_file()
    written = set(tree(out))
    user = {'notes.yaml': b'mine\n', '.hidden.yaml': b'dot\n', 'calibration/mine.yaml': b'c\n',
            'heldout/readme.txt': b'r\n', '.hard_floor.yaml.tmp-leftover.yaml': b'half'}
    for name, data in user.items():
        (out / name).write_bytes(data)
    second = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert second.returncode == 0, second.stderr
    after = tree(out)
    assert set(after) == written | set(user)
    assert all(after[name] == data for name, data in user.items())
    assert (out / 'identify.png').stat().st_size > 10_000


# The output directory and its manifest (no simulation) -----------------------------------

PLANNED = planned_outputs('auriga_alpha', 'hard_floor', ['path1_random'])


def fake_run(directory, force=False):
    """Prepare ``directory`` and write every planned output as a run would."""
    outputs = DemoDirectory(directory, force=force)
    outputs.prepare(PLANNED)
    for entry in PLANNED:
        path = directory / entry.path
        if entry.kind == 'dir':
            continue
        outputs.record(Entry(entry.kind, entry.path))
        if entry.kind == 'bag':
            path.mkdir()
            (path / 'metadata.yaml').write_text('m\n')
            (path / f'{path.name}.mcap').write_text('data\n')
        else:
            path.write_text(f'{entry.path} of run\n')
    outputs.written()
    return outputs


def test_a_rerun_removes_only_what_the_manifest_lists(tmp_path):
    out = tmp_path / 'out'
    fake_run(out)
    ours = set(tree(out))
    user = ['notes.yaml', '.dot.yaml', 'calibration/mine.txt', 'heldout/x.yaml']
    for name in user:
        (out / name).write_text('user\n')
    DemoDirectory(out).prepare(PLANNED)
    left = set(tree(out))
    assert left == set(user) | {'calibration', 'heldout', MANIFEST}
    assert all((out / name).read_text() == 'user\n' for name in user)
    fake_run(out)
    assert set(tree(out)) == ours | set(user)


def test_a_listed_file_the_user_changed_is_theirs(tmp_path, capsys):
    out = tmp_path / 'out'
    fake_run(out)
    (out / 'hard_floor.yaml').write_text('edited by hand, longer than before\n')
    with pytest.raises(DemoError, match='hard_floor.yaml was changed since the demo wrote '
                                        'it; use --force'):
        DemoDirectory(out).prepare(PLANNED)
    assert (out / 'hard_floor.yaml').read_text().startswith('edited')
    assert (out / 'identify.png').exists()          # refused before anything was removed
    # With --force it is replaced; an unlisted file in the way likewise.
    outputs = DemoDirectory(out, force=True)
    outputs.prepare(PLANNED)
    assert (out / 'hard_floor.yaml').read_text().startswith('edited')   # until replaced
    assert not (out / 'identify.png').exists()
    # A failed forced run leaves the user's file it did not get to replace.
    outputs.record(Entry('file', 'hard_floor.yaml'))
    outputs.fail()
    assert (out / 'hard_floor.yaml').read_text().startswith('edited')


def test_an_unlisted_file_in_the_way_needs_force(tmp_path):
    out = tmp_path / 'out'
    out.mkdir()
    (out / MANIFEST).write_text('{"entries": []}\n')
    (out / 'heldout.csv').write_text('mine\n')
    with pytest.raises(DemoError, match='heldout.csv exists; use --force'):
        DemoDirectory(out).prepare(PLANNED)
    DemoDirectory(out, force=True).prepare(PLANNED)
    assert (out / 'heldout.csv').read_text() == 'mine\n'   # replaced only when written


@pytest.mark.parametrize('entry', [
    {'kind': 'file', 'path': '../outside.yaml'}, {'kind': 'file', 'path': '/etc/hostname'},
    {'kind': 'dir', 'path': '..'}, {'kind': 'bag', 'path': 'b', 'files': ['../outside.yaml']},
    {'kind': 'file', 'path': 'link/victim.yaml'}])
def test_the_manifest_never_reaches_outside(tmp_path, entry):
    out = tmp_path / 'out'
    out.mkdir()
    (tmp_path / 'outside.yaml').write_text('keep\n')
    (tmp_path / 'elsewhere').mkdir()
    (tmp_path / 'elsewhere' / 'victim.yaml').write_text('keep\n')
    (out / 'link').symlink_to(tmp_path / 'elsewhere')
    (out / 'b').mkdir()
    (out / MANIFEST).write_text(json.dumps({'entries': [entry]}))
    DemoDirectory(out).prepare(PLANNED)
    assert (tmp_path / 'outside.yaml').read_text() == 'keep\n'
    assert (tmp_path / 'elsewhere' / 'victim.yaml').read_text() == 'keep\n'
    assert (out / 'link').is_symlink()


@pytest.mark.parametrize('setup, pattern', [
    (lambda out, tmp: (out / 'calibration').symlink_to(tmp),
     r'calibration is a symbolic link; the demo neither follows'),
    (lambda out, tmp: (out / 'hard_floor.yaml').symlink_to(tmp / 'nowhere.yaml'),
     r'hard_floor.yaml is a symbolic link; the demo neither follows nor replaces it'),
    (lambda out, tmp: (out / 'identify.png').symlink_to(tmp / 'precious.png'),
     r'identify.png is a symbolic link'),
    (lambda out, tmp: (out / 'calibration' / 'auriga_alpha_hard_floor' / 'notes.txt')
     .write_text('x'), r'auriga_alpha_hard_floor holds files the demo did not write '
                       r'\(notes.txt\)'),
    (lambda out, tmp: os.mkfifo(out / 'heldout.csv'), r'heldout.csv is a FIFO'),
])
def test_links_and_foreign_files_in_a_demo_directory_are_refused(tmp_path, setup, pattern):
    out = tmp_path / 'out'
    fake_run(out)
    (tmp_path / 'precious.png').write_text('precious\n')
    for name in ('hard_floor.yaml', 'identify.png', 'heldout.csv'):
        (out / name).unlink()
    if pattern.startswith('calibration is a symbolic'):
        import shutil
        shutil.rmtree(out / 'calibration')
    setup(out, tmp_path)
    before = tree(out)
    for force in (False, True):
        with pytest.raises(DemoError, match=pattern):
            DemoDirectory(out, force=force).prepare(PLANNED)
    assert tree(out) == before
    assert (tmp_path / 'precious.png').read_text() == 'precious\n'
    assert not (tmp_path / 'nowhere.yaml').exists()


def test_an_older_demos_marker_is_not_a_manifest(tmp_path):
    out = tmp_path / 'out'
    out.mkdir()
    (out / MANIFEST).write_text('written by tracked_kinematics_demo; reruns replace its '
                                'outputs\n')
    (out / 'hard_floor.yaml').write_text('x\n')
    with pytest.raises(DemoError, match='older demo that kept no list of its files'):
        DemoDirectory(out).prepare(PLANNED)
    assert (out / 'hard_floor.yaml').read_text() == 'x\n'


def test_a_failed_first_run_removes_its_directory(tmp_path):
    out = tmp_path / 'a' / 'b' / 'out'
    outputs = fake_run(out)
    outputs.fail()
    assert list(tmp_path.iterdir()) == []


def test_sigterm_mid_run_exits_143_and_leaves_nothing(tmp_path):
    proc = subprocess.Popen([str(BIN / 'tracked_kinematics_demo'), '--paths', '1',
                             '--duration', '1200', '--path-duration', '5'], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    calibration = tmp_path / 'demo_output' / 'calibration'
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and not (
                calibration.is_dir()
                and any(p.name.startswith('.') for p in calibration.iterdir())):
            time.sleep(0.01)
        assert calibration.is_dir(), 'the calibration bag was never being written'
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert err == 'tracked_kinematics_demo: error: terminated by SIGTERM\n'
    assert list(tmp_path.iterdir()) == []
