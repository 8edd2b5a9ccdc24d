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
                               '--spin-in-place', '--output', out], capsys)
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
    (['--track-width', '-1'], 2, r'argument --track-width: must be a finite number > 0'),
])
def test_error_paths_leave_no_file(bag, tmp_path, capsys, extra, status, pattern):
    out = tmp_path / 'out.yaml'
    out.write_text('old: contents\n')
    if extra[0] == '--track-width':
        with pytest.raises(SystemExit) as exc:
            identify_icr.main([str(bag), *ARGS, '--output', str(out), *extra])
        got, err = exc.value.code, capsys.readouterr().err.strip().splitlines()[-1]
        assert got == status and re.search(pattern, err)
    else:
        got, _, err = run([bag, *ARGS, '--output', out, *extra], capsys)
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
    ('scale:\n  left: -1\n', [], r'scale_left must be > 0, got -1.0$'),
    (None, ['--max-nfev', '-3'], r'--max-nfev must not be negative, got -3$'),
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
    out = tmp_path / 'o.yaml'
    got, _, err = run([bag, *ARGS, '--output', out, '--holdout', '0', '--plot',
                       tmp_path / 'fit.xyz'], capsys)
    one_line_error(err, got, 2, r"Format 'xyz' is not supported \(supported formats: .*png")
    assert out.exists()   # as before: the terrain file is written before the plot


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
    assert icr['windows'] == {'n': 0, 'position_mean': None, 'position_p90': None,
                              'heading_mean': None, 'heading_p90': None}
    assert icr['improvement_pct']['windows'] is None
    assert icr['improvement_pct']['segments']['position'] > 90


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
