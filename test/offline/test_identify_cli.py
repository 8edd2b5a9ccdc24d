"""identify_icr end to end: bags of a known vehicle in, a terrain file that ROS loads out."""

import json
from pathlib import Path
import re
import subprocess
import sys

from helpers.recordings import late, noisy, pieces
from helpers.vehicle_sim import AURIGA, B, simulate, write_bag
import numpy as np
import pytest
from tracked_kinematics.core.models import ConstantIcr, EffectiveWheelBase
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.params import read_params_file, TERRAIN_PARAMS

BIN = Path(sys.executable).parent
ARGS = ['--ground-truth-topic', '/mocap/pose', '--sprocket-radius', '0.1', '--track-width',
        str(B)]


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """Two minutes of the Auriga-alpha, mcap, ground truth with 2 mm / 0.1 deg noise."""
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=120.0, enc_rate=50.0, seed=11,
                   gt_phase=0.003)
    path = tmp_path_factory.mktemp('bags') / 'calibration'
    write_bag(path, rec, 'mcap', gt_noise=(0.002, np.radians(0.1)))
    return path


def run(argv, capsys):
    status = identify_icr.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err.strip()


def test_console_script_writes_yaml_report_and_plot(bag, tmp_path):
    out, report, plot = tmp_path / 'floor.yaml', tmp_path / 'fit.json', tmp_path / 'fit.png'
    result = subprocess.run(
        [str(BIN / 'identify_icr'), str(bag), *ARGS, '--output', str(out), '--report',
         str(report), '--plot', str(plot), '--terrain', 'hard_floor', '--holdout-block', '20'],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ''   # no progress bar when stderr is not a terminal
    assert 'hold-out' in result.stdout and 'icr_scales' in result.stdout
    values = read_params_file(out)
    # 2 mm / 0.1 deg ground-truth noise, two minutes: within 5 mm and 0.5 %.
    np.testing.assert_allclose([values['icr.y_left'], values['icr.y_right'], values['icr.x']],
                               AURIGA[:3], atol=5e-3)
    np.testing.assert_allclose([values['scale.left'], values['scale.right']], AURIGA[3:],
                               rtol=5e-3)
    assert values['terrain'] == 'hard_floor'
    assert values['identification.model'] == 'icr_scales'
    assert values['identification.bags'] == [str(bag.resolve())]
    assert out.read_text().startswith('# Terrain parameters written by identify_icr')
    doc = json.loads(report.read_text())
    assert doc['icr']['chi'] == pytest.approx(0.540, abs=0.01)
    models = doc['holdout']['models']
    assert set(models) == {'ideal', 'tuned_ddc', 'effective_wheel_base', 'icr', 'icr_scales',
                           'general_slip', 'adaptive_icr'}
    assert models['icr_scales']['improvement_pct']['windows']['position'] > 50
    assert doc['fit']['standard_errors']['y_left'] < 5e-3
    assert plot.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.ros
def test_written_yaml_loads_with_params_file(bag, tmp_path, capsys):
    out = tmp_path / 'floor.yaml'
    assert run([bag, *ARGS, '--output', out, '--holdout', '0'], capsys)[0] == 0
    import rclpy
    from rclpy.node import Node
    from tracked_kinematics.ros.parameters import ParameterTable
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '--params-file', str(out)], context=context)
    try:
        node = Node('odometry_node', context=context)
        table = ParameterTable(node, TERRAIN_PARAMS)
        written = read_params_file(out)
        for name in ('track_width', 'icr.y_left', 'icr.y_right', 'icr.x', 'scale.left'):
            assert table[name] == pytest.approx(written[name])
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def test_general_slip_writes_icr_keys_from_the_icr_fit(bag, tmp_path, capsys):
    out = tmp_path / 'gs.yaml'
    status, stdout, err = run([bag, *ARGS, '--output', out, '--model', 'general_slip',
                               '--holdout', '0'], capsys)
    assert status == 0, err
    values = read_params_file(out)
    assert values['identification.model'] == 'general_slip'
    assert values['identification.icr_source'] == 'icr_scales'
    assert 'identification.parameters.alpha9' in values
    assert values['icr.y_left'] == pytest.approx(AURIGA[0], abs=5e-3)
    assert 'the general_slip parameters are under identification.parameters' in out.read_text()


def test_spin_in_place_mode(tmp_path, capsys):
    rec = simulate(EffectiveWheelBase(B), [0.526], duration=40.0, enc_rate=50.0, seed=2,
                   legs=('spin',))
    path = tmp_path / 'spins.bag'
    write_bag(path, rec, 'rosbag1', ground_truth='tf')
    out = tmp_path / 'sym.yaml'
    status, stdout, err = run([path, '--ground-truth-topic', '/tf', '--track-width', B,
                               '--sprocket-radius', 0.1, '--spin-in-place', '--output', out],
                              capsys)
    assert status == 0, err
    assert 'chi = 0.5260' in stdout
    values = read_params_file(out)
    assert values['icr.y_left'] == pytest.approx(0.399, abs=5e-4)
    assert values['icr.y_left'] == pytest.approx(-values['icr.y_right'])


def one_line_error(err, status, expected_status, pattern):
    assert status == expected_status
    assert '\n' not in err and err.startswith('identify_icr: error: ')
    assert re.search(pattern, err), err


@pytest.mark.parametrize('extra, status, pattern', [
    (['--ground-truth-topic', '/vicon'], 2, r'no topic /vicon .*topics present: /joint_states'),
    (['--left-joints', 'left_wheel,left_idler'], 2,
     r'joint left_wheel, left_idler not in /joint_states; joint names present: '
     r'left_sprocket_joint, right_sprocket_joint'),
    (['--max-nfev', '1'], 4, r'the icr_scales fit did not converge'),
    (['--track-width', '-1'], 2, r'argument --track-width: must be in \[0.05, 20\] m, got -1 '
                                 r'\(see identify_icr --help\)$'),
])
def test_error_paths_leave_no_file(bag, tmp_path, capsys, extra, status, pattern):
    # Even with --force, a failed run leaves the old file and adds nothing (no report, no
    # temporary file).
    out = tmp_path / 'out.yaml'
    out.write_text('old: contents\n')
    argv = [bag, *ARGS, '--output', out, '--report', tmp_path / 'r.json', '--force', *extra]
    if extra[0] == '--track-width':
        with pytest.raises(SystemExit) as exc:
            identify_icr.main([str(a) for a in argv])
        got, err = exc.value.code, capsys.readouterr().err
        one_line_error(err.strip(), got, status, pattern)
    else:
        got, _, err = run(argv, capsys)
        one_line_error(err, got, status, pattern)
    assert out.read_text() == 'old: contents\n'
    assert [p.name for p in tmp_path.iterdir()] == ['out.yaml']


def test_missing_bag(tmp_path, capsys):
    status, _, err = run([tmp_path / 'nope', *ARGS, '--output', tmp_path / 'o.yaml'], capsys)
    one_line_error(err, status, 2, r'bag not found: .*nope')
    assert not (tmp_path / 'o.yaml').exists()


def test_corrupt_bag(tmp_path, capsys):
    bad = tmp_path / 'broken.bag'
    bad.write_bytes(b'\x00' * 100)
    status, _, err = run([bad, *ARGS, '--output', tmp_path / 'o.yaml'], capsys)
    one_line_error(err, status, 2, r'cannot read bag .*broken.bag')


@pytest.mark.parametrize('legs, pattern', [
    (('straight',), r'too little turning to identify icr.y_left, icr.y_right, icr.x'),
    (('spin',), r'too little straight driving to identify scale.left, scale.right'),
])
def test_too_little_excitation(tmp_path, capsys, legs, pattern):
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=30.0, enc_rate=50.0, seed=3,
                   legs=legs)
    path = tmp_path / 'run'
    write_bag(path, rec, 'sqlite3')
    status, _, err = run([path, *ARGS, '--output', tmp_path / 'o.yaml'], capsys)
    one_line_error(err, status, 3, pattern)
    assert not (tmp_path / 'o.yaml').exists()


@pytest.mark.parametrize('params, extra, pattern', [
    ('a: [1, 2\n', [], r'base.yaml: not valid YAML \(while parsing'),
    (b'\x89PNG\r\n\x1a\n\xff\xfe', [], r"'utf-8' codec can't decode byte 0x89"),
    ('- 1\n- 2\n', [], r'base.yaml: expected a mapping of parameters$'),
    ('scale:\n  left: -1\n', [], r'base.yaml: scale.left must be > 0, got -1$'),
])
def test_user_errors_are_bad_input_not_tracebacks(bag, tmp_path, capsys, params, extra,
                                                  pattern):
    base = []
    if params is not None:
        path = tmp_path / 'base.yaml'
        path.write_bytes(params if isinstance(params, bytes) else params.encode())
        base = ['--params', path]
    got, _, err = run([bag, *ARGS, '--output', tmp_path / 'o.yaml', *base, *extra], capsys)
    one_line_error(err, got, 2, pattern)
    assert not (tmp_path / 'o.yaml').exists()


def test_plot_format_matplotlib_cannot_write_is_bad_input(bag, tmp_path, capsys):
    # Checked with the other outputs before any work: nothing is written.
    out = tmp_path / 'o.yaml'
    got, _, err = run([bag, *ARGS, '--output', out, '--holdout', '0', '--plot',
                       tmp_path / 'fit.xyz'], capsys)
    one_line_error(err, got, 2, r"--plot .*fit.xyz: Format 'xyz' is not supported "
                                r'\(supported formats: .*png')
    assert list(tmp_path.iterdir()) == []


def test_a_bug_in_the_core_surfaces_as_a_traceback(bag, tmp_path, capsys, monkeypatch):
    def bug(*args, **kwargs):
        raise ValueError('bug')
    monkeypatch.setattr(identify_icr.ident, 'identify', bug)
    with pytest.raises(ValueError, match='^bug$'):
        identify_icr.main([str(bag), *ARGS, '--output', str(tmp_path / 'o.yaml')])
    assert capsys.readouterr().err == ''
    assert not (tmp_path / 'o.yaml').exists()


def test_plot_shows_the_segments_of_the_fit(bag, tmp_path, capsys, monkeypatch, no_pyplot):
    # The residuals plotted are those of the segments the fit used (--min-travel), not of a
    # threshold of the plot's own; the plot is drawn without pyplot.
    from tracked_kinematics.core import identify as ident
    from tracked_kinematics.offline import plots
    seen = {}
    draw = plots.plot_identification

    def spy(path, recordings, result, segments):
        seen.update(recordings=recordings, result=result, segments=segments)
        draw(path, recordings, result, segments)

    monkeypatch.setattr(plots, 'plot_identification', spy)
    plot = tmp_path / 'fit.png'
    status, _, err = run([bag, *ARGS, '--output', tmp_path / 'o.yaml', '--min-travel', '0.4',
                          '--holdout', '0', '--plot', plot], capsys)
    assert status == 0, err
    segments, result = seen['segments'], seen['result']
    assert len(segments) == result.fit.segments
    assert np.all(segments.travel >= 0.4)
    every = ident.build_segments(seen['recordings'], result.segment_length)
    assert np.count_nonzero(every.travel >= 0.01) > len(segments)   # 0.4 m left some out
    assert plot.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('params, pattern', [
    ('track_width: abc\n', r"base.yaml: track_width must be a number, got 'abc'$"),
    ('sprocket_radius: [1]\n', r'base.yaml: sprocket_radius must be a number, got \[1\]$'),
    ('scale: {left: 1.0, right: x}\n', r"base.yaml: scale.right must be a number, got 'x'$"),
])
def test_a_base_value_that_is_not_a_number_is_one_line(bag, tmp_path, capsys, params,
                                                       pattern):
    # track_width: abc was a TypeError traceback (issue 14 item 13).
    path = tmp_path / 'base.yaml'
    path.write_text(params)
    got, _, err = run([bag, '--ground-truth-topic', '/mocap/pose', '--params', path,
                       '--output', tmp_path / 'o.yaml'], capsys)
    one_line_error(err, got, 2, pattern)
    assert not (tmp_path / 'o.yaml').exists()


def test_a_typo_in_the_base_file_is_named_with_the_closest_name(bag, tmp_path, capsys):
    path = tmp_path / 'base.yaml'
    path.write_text('track_widht: 0.5\nicr:\n  yleft: 0.3\nodom_frame: odom\n'
                    'identification:\n  model: icr\n')
    got, _, err = run([bag, *ARGS, '--params', path, '--output', tmp_path / 'o.yaml',
                       '--holdout', '0'], capsys)
    assert got == 0, err
    assert err.splitlines() == [
        f"identify_icr: warning: {path}: unknown parameter 'icr.yleft' is not used (did you "
        "mean 'icr.y_left'?)",
        f"identify_icr: warning: {path}: unknown parameter 'track_widht' is not used (did you "
        "mean 'track_width'?)"]
    # Copied on as before (it is the user's file), but not taken for the track width.
    values = read_params_file(tmp_path / 'o.yaml')
    assert values['track_widht'] == 0.5 and values['track_width'] == B


@pytest.mark.parametrize('argv, pattern', [
    (['--segment-length', '1e-12'], r'--segment-length: must be in \[0.01, 600\] s or 0, '
                                    r'got 1e-12'),
    (['--segment-length', '1e-9'], r'--segment-length: must be in'),
    (['--ground-truth-offset', '1e300', '0', '0'], r'--ground-truth-offset: must be in '
                                                   r'\[-10, 10\], got 1e300'),
    (['--ground-truth-offset', '0', 'nan', '0'], r'--ground-truth-offset: must be a finite '
                                                 r'number in'),
    (['--holdout', '1'], r'--holdout: must be in \[0, 0.9\]'),
    (['--max-nfev', '-3'], r'--max-nfev: must be in \[0, 1,000,000\], got -3'),
    (['--max-nfev', '2.5'], r"--max-nfev: expected a whole number, got '2.5'"),
    (['--heading-weight', '1e-30'], r'--heading-weight: must be in \[0.001, 1000\] m/rad'),
    (['--sprocket-radius', '5e-324'], r'--sprocket-radius: must be in \[0.005, 5\] m'),
    (['--ticks-per-revolution', '0.5'], r'--ticks-per-revolution: must be in \[1, 1e\+09\]'),
])
def test_absurd_numbers_are_refused_before_any_work(tmp_path, capsys, argv, pattern):
    # MemoryError / OverflowError tracebacks before (issue 14 item 12); now one line, exit 2,
    # before the bag is even looked for.
    with pytest.raises(SystemExit) as exc:
        identify_icr.main(['no_such_bag', *ARGS, '--output', str(tmp_path / 'o.yaml'), *argv])
    err = capsys.readouterr().err
    one_line_error(err.strip(), exc.value.code, 2, pattern)
    assert list(tmp_path.iterdir()) == []


# Outputs: all or none, --force, full disk, signals (issue 14 items 9-11) ------------------


def outputs_argv(bag, tmp_path):
    return [bag, *ARGS, '--holdout', '0', '--output', tmp_path / 'o.yaml', '--report',
            tmp_path / 'fit.json', '--plot', tmp_path / 'fit.png']


def test_force_replaces_existing_outputs_and_keeps_their_mode(bag, tmp_path, capsys):
    for name in ('o.yaml', 'fit.json'):
        (tmp_path / name).write_text('old\n')
        (tmp_path / name).chmod(0o600)
    got, out, err = run(outputs_argv(bag, tmp_path), capsys)
    assert got == 2 and 'o.yaml exists; use --force to replace it' in err
    assert (tmp_path / 'o.yaml').read_text() == 'old\n' and not (tmp_path / 'fit.png').exists()
    got, out, err = run(outputs_argv(bag, tmp_path) + ['--force'], capsys)
    assert got == 0, err
    assert f'wrote {tmp_path / "o.yaml"}, {tmp_path / "fit.json"}, {tmp_path / "fit.png"}' in out
    assert read_params_file(tmp_path / 'o.yaml')['identification.model'] == 'icr_scales'
    assert json.loads((tmp_path / 'fit.json').read_text())['tool'] == 'identify_icr'
    for name in ('o.yaml', 'fit.json'):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ['fit.json', 'fit.png', 'o.yaml']


def test_a_failing_plot_leaves_no_yaml_and_no_report(bag, tmp_path, capsys, monkeypatch):
    from tracked_kinematics.offline import plots
    from tracked_kinematics.offline.errors import UsageError

    def broken(path, *args):
        path.write_bytes(b'\x89PNG half')
        raise UsageError('the plot failed')
    monkeypatch.setattr(plots, 'plot_identification', broken)
    got, _, err = run(outputs_argv(bag, tmp_path), capsys)
    one_line_error(err, got, 2, 'the plot failed')
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize('victim', ['o.yaml', 'fit.json', 'fit.png'])
def test_a_full_disk_leaves_nothing(bag, tmp_path, capsys, monkeypatch, victim):
    # ENOSPC when a file is flushed (where a full disk shows with delayed allocation).
    import errno
    from tracked_kinematics.offline import outputs
    real = outputs._fsync_file

    def full(path):
        if path.name.startswith(f'.{victim}.tmp-'):
            raise OSError(errno.ENOSPC, 'No space left on device')
        real(path)
    monkeypatch.setattr(outputs, '_fsync_file', full)
    got, _, err = run(outputs_argv(bag, tmp_path), capsys)
    one_line_error(err, got, 2, r'No space left on device')
    assert list(tmp_path.iterdir()) == []


KILLER = """
import os, signal, sys
from tracked_kinematics.offline import plots
def save(fig, path, dpi):
    with open(path, 'wb') as stream:     # half a PNG, then the signal
        stream.write(b'\\x89PNG\\r\\n\\x1a\\n half')
    os.kill(os.getpid(), getattr(signal, sys.argv[1]))
plots.save = save
from tracked_kinematics.offline.cli import identify_icr
sys.exit(identify_icr.main(sys.argv[2:]))
"""


def test_sigkill_mid_write_leaves_only_hidden_temporary_files(bag, tmp_path, capsys):
    argv = [str(a) for a in outputs_argv(bag, tmp_path)]
    done = subprocess.run([sys.executable, '-c', KILLER, 'SIGKILL', *argv],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == -9
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left and all(re.match(r'^\.(o\.yaml|fit\.json|fit\.png)\.tmp-\w+\.(yaml|json|png)$',
                                 name) for name in left), left
    # No 0-byte PNG, no half file at a target; a rerun ignores the leftovers (no --force).
    got, _, err = run(argv, capsys)
    assert got == 0, err
    assert (tmp_path / 'fit.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert (tmp_path / 'fit.png').stat().st_size > 10_000


@pytest.mark.parametrize('signal_name, status', [
    ('SIGTERM', 143),
    # The same path for the other two (one handler): make stress signals them.
    pytest.param('SIGINT', 130, marks=pytest.mark.long),
    pytest.param('SIGHUP', 129, marks=pytest.mark.long)])
def test_a_signal_mid_write_exits_with_one_line_and_leaves_nothing(bag, tmp_path, signal_name,
                                                                   status):
    argv = [str(a) for a in outputs_argv(bag, tmp_path)]
    done = subprocess.run([sys.executable, '-c', KILLER, signal_name, *argv],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == status, done.stderr
    reason = 'interrupted' if signal_name == 'SIGINT' else f'terminated by {signal_name}'
    assert done.stderr == f'identify_icr: error: {reason}\n'
    assert list(tmp_path.iterdir()) == []


# Real recordings: late ground truth, pieces, noise; the tuned diff_drive_controller ------


def strict_json(path):
    """Load a JSON report, refusing NaN and infinities (never written)."""
    def refuse(name):
        raise ValueError(f'{name} in the report')
    return json.loads(Path(path).read_text(), parse_constant=refuse)


@pytest.fixture(scope='module')
def late_bag(tmp_path_factory):
    """Two minutes, ground truth stamped 0.2 s late (on receipt), 10 Hz, 2 mm noise."""
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=120.0, enc_rate=50.0, seed=11,
                   gt_phase=0.003)
    path = tmp_path_factory.mktemp('bags') / 'late'
    write_bag(path, late(rec, 0.2), 'sqlite3', gt_noise=(0.002, np.radians(0.1)))
    return path


def test_ground_truth_delay_is_estimated_removed_and_written(late_bag, tmp_path, capsys):
    out, report = tmp_path / 'o.yaml', tmp_path / 'o.json'
    status, stdout, err = run([late_bag, *ARGS, '--output', out, '--report', report], capsys)
    assert status == 0, err
    assert re.search(r'ground-truth delay behind the encoders: 0\.(19|20)\d s \+- 0\.00\d s '
                     r'\(jackknife over \d+ windows', stdout)
    values = read_params_file(out)
    assert values['identification.ground_truth_delay'] == pytest.approx(0.2, abs=0.005)
    assert values['identification.ground_truth_delay_method'] == 'jackknife'
    assert 0 < values['identification.ground_truth_delay_std'] < 0.01
    np.testing.assert_allclose([values['icr.y_left'], values['icr.y_right']], AURIGA[:2],
                               atol=5e-3)
    doc = strict_json(report)
    assert doc['ground_truth_delay']['delay'] == pytest.approx(0.2, abs=0.005)
    assert doc['ground_truth_delay']['determined'] is True
    # 0 turns it off; the hold-out then shows what the stale stamps cost.
    off = tmp_path / 'off.yaml'
    status, stdout, err = run([late_bag, *ARGS, '--output', off, '--ground-truth-delay', '0',
                               '--report', tmp_path / 'off.json'], capsys)
    assert status == 0, err
    assert 'ground-truth delay behind the encoders: off (--ground-truth-delay 0)' in stdout
    raw = read_params_file(off)
    assert raw['identification.ground_truth_delay'] == 0.0
    assert raw['identification.ground_truth_delay_method'] == 'off'
    windows = {name: strict_json(p)['holdout']['models']['icr_scales']['windows']['position_mean']
               for name, p in (('auto', report), ('off', tmp_path / 'off.json'))}
    assert windows['off'] > 3 * windows['auto']
    # A number fixes it.
    fixed = tmp_path / 'fixed.yaml'
    status, stdout, _ = run([late_bag, *ARGS, '--output', fixed, '--ground-truth-delay', '0.19',
                             '--holdout', '0'], capsys)
    assert status == 0 and '0.190 s as given' in stdout
    assert read_params_file(fixed)['identification.ground_truth_delay'] == 0.19


@pytest.mark.parametrize('value', ['soon', 'nan', '20'])
def test_bad_ground_truth_delay_is_bad_input(late_bag, tmp_path, capsys, value):
    with pytest.raises(SystemExit) as exc:
        identify_icr.main([str(late_bag), *map(str, ARGS), '--output', str(tmp_path / 'o.yaml'),
                           '--ground-truth-delay', value])
    assert exc.value.code == 2
    assert 'argument --ground-truth-delay' in capsys.readouterr().err
    assert not (tmp_path / 'o.yaml').exists()


def test_recording_in_short_pieces(tmp_path, capsys):
    # One bag, 60 pieces of 2 s with gaps of 1 s, ground truth starting 0.3 s before the
    # encoders in each (a logger restarted every 2 s), stamped 0.15 s late.
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=180.0, enc_rate=50.0, seed=4,
                   gt_phase=0.0137)
    piece, = pieces(late(rec, 0.15), length=2.0, gap=1.0, encoders_late=0.3, one=True)
    path = tmp_path / 'pieces'
    write_bag(path, piece, 'sqlite3')
    out, report = tmp_path / 'o.yaml', tmp_path / 'o.json'
    status, stdout, err = run([path, *ARGS, '--output', out, '--report', report], capsys)
    assert status == 0, err
    assert re.search(r'1 bag\(s\): \d+ s with encoders and ground truth \(in 60 pieces; '
                     r'1[78]\d s from first to last sample\), \d+ s driving', stdout)
    assert re.search(r'no held-out windows of 10 s \(the longest piece with both streams is '
                     r'1\.\d s; a shorter --window gives some\)', stdout)
    assert 'ground truth: ' not in stdout   # no jumps: the gaps between pieces are none
    assert 'nan' not in stdout and '+0 %' not in stdout
    values = read_params_file(out)
    np.testing.assert_allclose([values['icr.y_left'], values['icr.y_right'], values['icr.x']],
                               AURIGA[:3], atol=1e-3)
    assert not any(k.startswith('identification.holdout') for k in values)
    doc = strict_json(report)
    assert doc['time']['pieces'] == 60
    assert doc['holdout']['windows'] == 0 and doc['holdout']['cross_validated'] is True
    icr = doc['holdout']['models']['icr_scales']
    assert icr['windows'] == {'n': 0, 'n_total': 0, 'position_mean': None,
                              'position_p90': None, 'heading_mean': None, 'heading_p90': None}
    assert icr['improvement_pct']['windows'] is None
    assert icr['improvement_pct']['segments']['position'] > 90
    # The noise model on the windows the pieces hold (it was not written: the node's default
    # is several times over-confident on such logs), said so.
    assert values['identification.covariance.window_lengths'] == [0.5, 1.0]
    assert values['covariance.timing'] > 0.0 and values['covariance.k_left'] > 0.0
    assert doc['covariance']['window_lengths_s'] == [0.5, 1.0]
    assert 'no piece of the recordings holds a window of 10 s: fitted on windows of 0.5/1 s' \
        in stdout


def test_noisy_ground_truth_refused_with_its_cause_then_accepted(tmp_path, capsys):
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=90.0, enc_rate=50.0, gt_rate=4.0,
                   seed=8)
    path = tmp_path / 'ice'
    write_bag(path, noisy(late(rec, 0.2), 0.05, np.radians(2.0), glitches=0.02, seed=3),
              'sqlite3')
    out = tmp_path / 'ice.yaml'
    status, _, err = run([path, *ARGS, '--output', out], capsys)
    one_line_error(err, status, 3, r'scale\.left is determined but uncertain: its standard '
                   r'error is 0\.0\d+ \(limit 0\.02\) because the ground truth is noisy')
    assert 'drive more' not in err and 'mm / ' in err and '--accept-uncertain' in err
    assert not out.exists()
    status, stdout, err = run([path, *ARGS, '--output', out, '--accept-uncertain'], capsys)
    assert status == 0, err
    assert 'accepted (--accept-uncertain): scale.left is determined but uncertain' in stdout
    values = read_params_file(out)
    assert set(values['identification.uncertain']) >= {'scale.left'}
    np.testing.assert_allclose([values['scale.left'], values['scale.right']], AURIGA[3:],
                               atol=0.05)


def test_tuned_ddc_snippet_and_baseline_columns(bag, tmp_path, capsys):
    report = tmp_path / 'o.json'
    status, stdout, err = run([bag, *ARGS, '--output', tmp_path / 'o.yaml', '--report', report],
                              capsys)
    assert status == 0, err
    assert 'vs ideal  vs tuned DDC' in stdout
    snippet = stdout[stdout.index('diff_drive_controller:\n'):]
    lines = snippet.splitlines()[2:7]
    assert [line.split(':')[0].strip() for line in lines] == [
        'wheel_separation', 'wheel_separation_multiplier', 'wheel_radius',
        'left_wheel_radius_multiplier', 'right_wheel_radius_multiplier']
    import yaml
    ddc = yaml.safe_load('\n'.join(snippet.splitlines()[:7]))['diff_drive_controller']
    params = ddc['ros__parameters']
    assert params['wheel_separation'] == B and params['wheel_radius'] == 0.1
    assert 1.0 / params['wheel_separation_multiplier'] == pytest.approx(0.54, abs=0.02)
    doc = strict_json(report)
    assert doc['tuned_ddc']['parameters'] == pytest.approx(params, rel=1e-5)
    models = doc['holdout']['models']
    assert models['icr_scales']['improvement_vs_tuned_ddc_pct']['windows']['position'] > 50
    assert 'improvement_vs_tuned_ddc_pct' not in models['tuned_ddc']


def test_holdout_windows_where_the_tracks_move_unless_all_windows(tmp_path, capsys):
    # Stands still 25 s of every 40 s: most 10-s hold-out windows are idle.
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=240.0, enc_rate=50.0, seed=5,
                   stand=(40.0, 25.0))
    path = tmp_path / 'standing'
    write_bag(path, rec, 'mcap')
    docs, values, said = {}, {}, {}
    for name, extra in (('moving', []), ('all', ['--all-windows'])):
        out, report = tmp_path / f'{name}.yaml', tmp_path / f'{name}.json'
        status, stdout, err = run([path, *ARGS, '--output', out, '--report', report,
                                   '--ground-truth-delay', '0', *extra], capsys)
        assert status == 0, err
        docs[name], values[name] = strict_json(report), read_params_file(out)
        said[name] = next(line for line in stdout.splitlines() if line.startswith('hold-out:'))
    moving = docs['moving']['holdout']['models']['ideal']['windows']
    every = docs['all']['holdout']['models']['ideal']['windows']
    assert every['n'] == every['n_total'] == moving['n_total'] > moving['n'] > 0
    assert re.search(rf'{moving["n"]} of {moving["n_total"]} windows of 10 s, those in which '
                     r'the tracks move \(mean track speed >= 0\.1 m/s; --all-windows',
                     said['moving'])
    assert f'{every["n"]} windows of 10 s, idle ones too' in said['all']
    assert docs['moving']['windows_selection'] == {'moving_only': True, 'min_speed_mps': 0.1}
    assert docs['all']['windows_selection'] == {'moving_only': False, 'min_speed_mps': None}
    assert every['position_mean'] < 0.6 * moving['position_mean']
    assert values['moving']['identification.holdout_windows'] == 'moving'
    assert values['moving']['identification.holdout_min_speed'] == 0.1
    assert values['all']['identification.holdout_windows'] == 'all'
    # The fit does not depend on the selection.
    assert values['all']['icr.y_left'] == values['moving']['icr.y_left']
