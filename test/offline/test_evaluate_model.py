"""evaluate_model end to end: simulated bags with commands, bad input, the real bags.

The metrics by hand: test/core/evaluate/. The real bags are those of ../shared/realdata
(test/helpers/realdata.py: beside the repository, or $TRACKED_KINEMATICS_REALDATA); their
tests skip when it is absent.
"""

import json
import math
import subprocess
import sys

from helpers.command_bags import T0_NS, write_commands_bag
from helpers.realdata import bag as real_bag
import numpy as np
import pytest
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.bags import BagWriter
from tracked_kinematics.offline.cli import evaluate_model as cli

B = 0.42
GT = '/ground_truth/pose'


@pytest.fixture(scope='module')
def sim(tmp_path_factory):
    root = tmp_path_factory.mktemp('eval')
    result = simulate_bag(root / 'calib', 'auriga_alpha', duration=60.0, seed=1)
    twist = root / 'ddc'
    write_commands_bag(twist, result.run, B, commands='twist')
    silent = root / 'joystick'
    write_commands_bag(silent, result.run, B, commands='none')
    ideal = root / 'nominal.yaml'
    ideal.write_text('track_width: 0.42\nsprocket_radius: 0.1\n')
    return {'bag': result.bag, 'truth': result.truth, 'twist': twist, 'silent': silent,
            'nominal': ideal, 'root': root}


def run(argv, capsys):
    status = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def assert_one_line(err, pattern):
    assert err.startswith('evaluate_model: error: ') and err.count('\n') == 1, err
    assert pattern in err, err


@pytest.fixture(scope='module')
def scored(sim, tmp_path_factory):
    out = tmp_path_factory.mktemp('scored')
    argv = [sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'], sim['nominal'],
            '--online', '--report', out / 'r.json', '--plot', out / 'p.png']
    status = cli.main([str(a) for a in argv])
    assert status == 0
    return json.loads((out / 'r.json').read_text()), out


def test_report_has_the_contract_keys_for_every_model(scored):
    report, _ = scored
    assert report['order'] == ['ideal', 'calib.truth', 'nominal', 'online_calib.truth',
                               'online_nominal']
    for name in report['order']:
        m = report['models'][name]
        for w in ('5', '10'):
            window = m['odometry']['windows'][w]
            assert window['n'] > 400
            for key in ('mean_position_error_m', 'p90_position_error_m',
                        'mean_heading_error_rad', 'p90_heading_error_rad', 'drift_pct'):
                assert math.isfinite(window[key]), (name, w, key)
        for key in ('rpe_1m', 'rpe_10m', 'rpe_1m_mean', 'rpe_10m_mean'):
            assert m[key] > 0.0
        assert m['rpe']['1m']['translation_m']['rmse'] == m['rpe_1m']
        prediction = m['prediction']
        assert prediction['source'] == 'setpoints' and prediction['n'] > 500
        assert prediction['mean_rmse_translation_m'] > 0.0
        assert prediction['mean_rmse_rotation_rad'] > 0.0
        assert m['odometry']['horizon']['n'] > 500
    assert report['recordings'][0]['ground_truth_delay_s'] == pytest.approx(0.0, abs=0.02)
    assert report['recordings'][0]['commands'] == 'setpoints'


def test_the_true_model_beats_ideal_drive_everywhere(scored):
    report, _ = scored
    ideal, truth = report['models']['ideal'], report['models']['calib.truth']
    for w in ('5', '10'):
        assert (truth['odometry']['windows'][w]['mean_position_error_m']
                < 0.2 * ideal['odometry']['windows'][w]['mean_position_error_m'])
    assert truth['rpe_1m'] < 0.2 * ideal['rpe_1m']
    assert (truth['prediction']['mean_rmse_translation_m']
            < 0.5 * ideal['prediction']['mean_rmse_translation_m'])
    # The nominal file is ideal drive: the same odometry, but the default drive train.
    nominal = report['models']['nominal']
    assert nominal['rpe_1m'] == pytest.approx(ideal['rpe_1m'])
    assert ideal['prediction']['drivetrain'].startswith('none')
    assert nominal['drivetrain'] == {'drivetrain.delay': 0.0, 'drivetrain.max_accel': 0.0,
                                     'drivetrain.loop': 'first_order',
                                     'drivetrain.time_constant': 0.1, 'from_file': False}


def test_the_online_estimator_learns_from_ideal_and_holds_the_true_model(scored):
    report, _ = scored
    models = report['models']

    def horizon(name):
        return models[name]['odometry']['horizon']['mean_rmse_translation_m']

    assert horizon('online_nominal') < 0.5 * horizon('nominal')
    assert horizon('online_calib.truth') < 1.02 * horizon('calib.truth')
    online = models['online_nominal']['online']
    assert online['outcomes']['updated'] > 500 and online['start'] == 'nominal'


def test_plot_is_an_image(scored):
    _, out = scored
    assert (out / 'p.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_table_has_one_row_per_model_baselines_first(sim, capsys, no_pyplot, tmp_path):
    status, out, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                            '--window', '2', '5', '--plot', tmp_path / 'p.svg'], capsys)
    assert status == 0, err
    lines = out.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith('model'))
    assert '2 s: pos m' in lines[head] and '5 s: pos m' in lines[head]
    assert lines[head + 1].split()[0] == 'ideal'
    assert lines[head + 2].split()[0] == 'calib.truth'
    assert lines[-1] == f'wrote {tmp_path / "p.svg"}'
    assert (tmp_path / 'p.svg').read_text().lstrip().startswith('<?xml')


def test_cmd_vel_bag_predicts_as_the_setpoint_bag(sim, scored, tmp_path, capsys):
    status, _, err = run([sim['twist'], '--ground-truth-topic', GT, '--params', sim['truth'],
                          '--report', tmp_path / 'r.json'], capsys)
    assert status == 0, err
    twist = json.loads((tmp_path / 'r.json').read_text())['models']
    setpoints = scored[0]['models']
    for name in ('ideal', 'calib.truth'):
        assert twist[name]['prediction']['source'] == 'cmd_vel'
        # write_commands_bag records the commands at 20 Hz, simulate_bag at 50 Hz.
        assert twist[name]['prediction']['mean_rmse_translation_m'] == pytest.approx(
            setpoints[name]['prediction']['mean_rmse_translation_m'], rel=0.1)


def test_bag_without_commands_scores_odometry_only(sim, tmp_path, capsys):
    status, out, err = run([sim['silent'], '--ground-truth-topic', GT, '--params', sim['truth'],
                            '--report', tmp_path / 'r.json'], capsys)
    assert status == 0, err
    assert 'no commands in the bags: no prediction from commands' in out
    report = json.loads((tmp_path / 'r.json').read_text())
    assert report['models']['ideal']['prediction'] is None
    assert report['models']['calib.truth']['odometry']['windows']['5']['n'] > 400


def test_given_delay_is_applied_and_reported(sim, tmp_path, capsys):
    status, _, _ = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                        '--ground-truth-delay', '0.3', '--report', tmp_path / 'r.json'], capsys)
    assert status == 0
    report = json.loads((tmp_path / 'r.json').read_text())
    record = report['recordings'][0]
    assert (record['ground_truth_delay_s'], record['ground_truth_delay_source']) == (0.3, 'given')
    assert record['ground_truth_delay_std_s'] is None


# --- bad input: one line, an exit status, nothing written ------------------------------------


def _still_bag(path, seconds=20.0):
    with BagWriter(path) as bag:
        for k in range(int(seconds * 50)):
            stamp = T0_NS + k * 20_000_000
            bag.write('/joint_states', stamp, bag.joint_state(
                stamp, ['left_sprocket_joint', 'right_sprocket_joint'], [1.0, 2.0]))
            if k % 5 == 0:
                bag.write(GT, stamp, bag.pose_stamped(stamp, 1.0, 2.0, 0.5))


@pytest.mark.parametrize('extra, status, pattern', [
    (['--ground-truth-topic', '/vicon'], 2, 'no topic /vicon for the ground truth'),
    (['--sprocket-radius', '-1'], 2, 'must be in [0.005, 5] m, got -1'),
    (['--track-width', '1e308'], 2, 'argument --track-width: must be in [0.05, 20] m, '
     'got 1e308'),
    (['--min-speed', '-0.1'], 2, 'argument --min-speed: must be in [0, 20] m/s, got -0.1'),
    (['--min-speed', 'nan'], 2, 'argument --min-speed: must be a finite number in [0, 20] m/s, '
     'got nan'),
    (['--min-speed', 'inf'], 2, 'argument --min-speed: must be a finite number in [0, 20] m/s, '
     'got inf'),
    (['--min-speed', '1e308'], 2, 'argument --min-speed: must be in [0, 20] m/s, got 1e308'),
    (['--prediction-dt', '3'], 2, '--prediction-dt (3 s) must be shorter than --horizon (2 s)'),
    (['--window', '5', '5'], 2, '--window lists a value twice: 5 5'),
    (['--plot', 'x.nope'], 2, "--plot: format 'nope' is not supported"),
    (['--command-source', 'cmd_vel'], 2, 'no topic /cmd_vel for the commands'),
    (['--ground-truth-delay', 'soon'], 2,
     "argument --ground-truth-delay: expected 'auto' or seconds, got 'soon'"),
])
def test_bad_options_are_one_line(sim, tmp_path, capsys, extra, status, pattern):
    argv = [sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
            '--report', tmp_path / 'r.json'] + extra
    if status == 2 and extra[0] in ('--sprocket-radius', '--track-width',
                                    '--ground-truth-delay', '--min-speed'):
        with pytest.raises(SystemExit) as exit_info:
            cli.main([str(a) for a in argv])
        assert exit_info.value.code == 2
        assert_one_line(capsys.readouterr().err, pattern)
    else:
        got, _, err = run(argv, capsys)
        assert got == status
        assert_one_line(err, pattern)
    assert not (tmp_path / 'r.json').exists()


def test_bad_files_are_one_line(sim, tmp_path, capsys):
    missing = tmp_path / 'none'
    status, _, err = run([missing, '--ground-truth-topic', GT, '--params', sim['truth']], capsys)
    assert status == 2
    assert_one_line(err, f'bag not found: {missing}')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('icr:\n  y_left: -0.3\n  y_right: 0.3\n')
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', bad], capsys)
    assert status == 2
    assert_one_line(err, f'{bad}: ')
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params',
                          tmp_path / 'gone.yaml'], capsys)
    assert status == 2 and 'No such file or directory' in err
    other = tmp_path / 'other.yaml'
    other.write_text('track_width: 0.42\nsprocket_radius: 0.2\n')
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                          other], capsys)
    assert status == 2
    assert_one_line(err, f'sprocket_radius 0.1 m from {sim["truth"]} and 0.2 m from {other} '
                         'differ by 50 %, more than rounding (1 %)')
    # --sprocket-radius does not settle it: a file of another vehicle is refused all the same.
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                          other, '--sprocket-radius', '0.1'], capsys)
    assert status == 2
    assert_one_line(err, f'sprocket_radius 0.1 m from --sprocket-radius and 0.2 m from {other}')


@pytest.mark.parametrize('options, dimension', [
    (['--track-width', '1.08'], 'track_width 1.08 m from --track-width and 0.42 m from '),
    (['--sprocket-radius', '0.3'], 'sprocket_radius 0.3 m from --sprocket-radius and 0.1 m '
                                   'from '),
])
def test_a_terrain_file_of_another_vehicle_is_refused(sim, tmp_path, capsys, options, dimension):
    # The Auriga's file scored with the Warthog's track width or radius: nothing is scored.
    status, out, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                            '--report', tmp_path / 'r.json', *options], capsys)
    assert status == 2 and out == ''
    assert_one_line(err, dimension + str(sim['truth']))
    assert not (tmp_path / 'r.json').exists()


def test_values_that_agree_to_rounding_are_one_vehicle(sim, tmp_path, capsys):
    rounded = tmp_path / 'rounded.yaml'
    rounded.write_text('track_width: 0.4213\nsprocket_radius: 0.1004\n')
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                          rounded, '--track-width', '0.42', '--sprocket-radius', '0.1',
                          '--window', '5'], capsys)
    assert status == 0, err


def test_existing_outputs_need_force_and_are_checked_first(sim, tmp_path, capsys):
    report = tmp_path / 'r.json'
    report.write_text('keep me')
    argv = [sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'], '--report', report]
    status, _, err = run(argv, capsys)
    assert status == 2
    assert_one_line(err, f'--report {report} exists; use --force to replace it')
    assert report.read_text() == 'keep me'
    status, _, err = run(argv + ['--force'], capsys)
    assert status == 0, err
    assert json.loads(report.read_text())['tool'] == 'evaluate_model'


def test_a_failure_after_the_work_leaves_nothing_behind(sim, tmp_path, capsys, monkeypatch):
    from tracked_kinematics.offline import model_evaluation_plot

    def broken(*args, **kwargs):
        raise OSError(28, 'No space left on device')

    monkeypatch.setattr(model_evaluation_plot, 'plot_evaluation', broken)
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'],
                          '--report', tmp_path / 'r.json', '--plot', tmp_path / 'p.png'], capsys)
    assert status == 2
    assert_one_line(err, 'No space left on device')
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_still_bag_has_no_delay_to_find_and_nothing_to_predict(sim, tmp_path, capsys):
    # As identify_icr: a delay the data cannot time is not removed, and the output says so.
    still = tmp_path / 'still'
    _still_bag(still)
    status, out, err = run([still, '--ground-truth-topic', GT, '--params', sim['truth'],
                            '--report', tmp_path / 'r.json'], capsys)
    assert status == 0, err
    assert 'ground-truth delay behind the encoders: not determined' in out
    assert 'none removed: give it with --ground-truth-delay' in out
    report = json.loads((tmp_path / 'r.json').read_text())
    assert report['recordings'][0]['ground_truth_delay_source'] == 'not determined'
    assert report['recordings'][0]['ground_truth_delay_s'] == 0.0
    # No window moves: none is scored by default; with --all-windows, all, without error.
    window = report['models']['ideal']['odometry']['windows']['5']
    assert window['n'] == 0 and window['n_total'] > 0
    assert window['mean_position_error_m'] is None and window['drift_pct'] is None
    assert ('windows in which the tracks move (mean track speed >= 0.1 m/s; --all-windows for '
            f'all): 0 of {window["n_total"]} of 5 s, 0 of ') in out
    status, out, err = run([still, '--ground-truth-topic', GT, '--params', sim['truth'],
                            '--report', tmp_path / 'r.json', '--force', '--all-windows'], capsys)
    assert status == 0, err
    report = json.loads((tmp_path / 'r.json').read_text())
    assert report['windows_selection'] == {'moving_only': False, 'min_speed_mps': None}
    window = report['models']['ideal']['odometry']['windows']['5']
    assert window['n'] == window['n_total'] > 0
    assert window['mean_position_error_m'] == 0.0 and window['drift_pct'] is None
    assert f'windows, idle ones too: {window["n"]} of 5 s, ' in out


def test_bags_whose_streams_do_not_meet_have_nothing_to_score(sim, tmp_path, capsys):
    apart = tmp_path / 'apart'
    with BagWriter(apart) as bag:
        for k in range(400):
            stamp = T0_NS + k * 20_000_000
            if k < 200:
                bag.write('/joint_states', stamp, bag.joint_state(
                    stamp, ['left_sprocket_joint', 'right_sprocket_joint'], [0.01 * k, 0.0]))
            elif k % 5 == 0:
                bag.write(GT, stamp, bag.pose_stamped(stamp, 0.001 * k, 0.0, 0.0))
    status, _, err = run([apart, '--ground-truth-topic', GT, '--params', sim['truth'],
                          '--ground-truth-delay', '0'], capsys)
    assert status == 3
    assert_one_line(err, 'no stretch of the bags has both encoders and ground truth')


def test_console_script_runs_as_a_process(sim, tmp_path):
    done = subprocess.run([sys.executable, '-m', 'tracked_kinematics.offline.cli.evaluate_model',
                           str(sim['bag']), '--ground-truth-topic', GT, '--params',
                           str(sim['truth']), '--report', str(tmp_path / 'r.json')],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith('evaluate_model: 1 bag(s), 60 s')
    assert (tmp_path / 'r.json').is_file()


# --- the real bags of ../shared/realdata --------------------------------------------------------

HUSKY = """track_width: 0.5384615384615384
sprocket_radius: 0.15875
icr: {y_left: 0.5156, y_right: -0.5331, x: -0.1657}
scale: {left: 0.9799, right: 0.9861}
"""
WARTHOG = """track_width: 1.08
sprocket_radius: 0.3
icr: {y_left: 0.9321, y_right: -0.9135, x: 0.0485}
scale: {left: 0.9457, right: 0.9646}
drivetrain: {loop: first_order, delay: 0.1, max_accel: 6.77, time_constant: 0.392}
"""
# identify_icr's icr_scales fits of ../shared/realdata (Husky on its one run, Warthog on the
# three), with identify_drivetrain's first-order drive train for the Warthog.


def _real(tmp_path_factory, bag, terrain):
    path = real_bag(bag)
    root = tmp_path_factory.mktemp('real')
    params = root / f'{bag.split("_")[0]}.yaml'
    params.write_text(terrain)
    status = cli.main([str(path), '--ground-truth-topic', '/icp/pose', '--params',
                       str(params), '--online', '--report', str(root / 'r.json')])
    assert status == 0
    return json.loads((root / 'r.json').read_text())


def _horizon(report, name):
    return report['models'][name]['odometry']['horizon']['mean_rmse_translation_m']


def test_husky_wet_grass(tmp_path_factory):
    report = _real(tmp_path_factory, 'husky_wetgrass_part1', HUSKY)
    record = report['recordings'][0]
    # The README's figures: 0.11 s of latency (our estimate: 0.09 s), 83 ICP jumps.
    assert record['ground_truth_delay_s'] == pytest.approx(0.11, abs=0.05)
    assert record['jumps'] == 83 and record['commands'] == 'setpoints'
    models = report['models']
    assert _horizon(report, 'husky') < 0.9 * _horizon(report, 'ideal')
    # The online estimator starts from the file and is never worse than it (here: even).
    assert _horizon(report, 'online_husky') < 1.01 * _horizon(report, 'husky')
    for w in ('5', '10'):
        assert (models['online_husky']['odometry']['windows'][w]['mean_position_error_m']
                < 1.01 * models['husky']['odometry']['windows'][w]['mean_position_error_m'])
    assert models['husky']['prediction']['n'] > 1000


def test_warthog_grass(tmp_path_factory):
    report = _real(tmp_path_factory, 'warthog_grass_2024-08-08_16h11', WARTHOG)
    record = report['recordings'][0]
    assert record['ground_truth_delay_s'] == pytest.approx(0.19, abs=0.05)
    assert record['jumps'] == 0
    # Here the online estimator helps (about 7 % on the 2-s horizon), and never hurts.
    assert _horizon(report, 'online_warthog') < 0.97 * _horizon(report, 'warthog')
    models = report['models']
    assert (models['online_warthog']['prediction']['mean_rmse_translation_m']
            < 1.01 * models['warthog']['prediction']['mean_rmse_translation_m'])
    assert (models['warthog']['prediction']['mean_rmse_translation_m']
            < 0.6 * models['ideal']['prediction']['mean_rmse_translation_m'])
    assert np.isfinite(models['warthog']['rpe_10m'])


def test_tum_export_holds_every_piece_for_evo(sim, tmp_path, capsys):
    tum = tmp_path / 'tum'
    argv = [sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'], '--tum', tum,
            '--report', tmp_path / 'r.json']
    status, _, err = run(argv, capsys)
    assert status == 0, err
    assert sorted(p.name for p in tum.iterdir()) == [
        'piece000.calib.truth.tum', 'piece000.ground_truth.tum', 'piece000.ideal.tum']
    rows = np.loadtxt(tum / 'piece000.ground_truth.tum')
    report = json.loads((tmp_path / 'r.json').read_text())
    assert rows.shape == (report['pieces'][0]['samples'], 8)
    np.testing.assert_allclose(np.hypot(rows[:, 6], rows[:, 7]), 1.0, atol=1e-8)
    status, _, err = run(argv + ['--force'], capsys)
    assert status == 2
    assert_one_line(err, f'--tum {tum} exists; choose a new path')


def test_a_file_with_only_the_track_width_is_ideal_drive_of_that_width(sim, tmp_path, capsys):
    # docs/model.md: the tread ICRs default to +-track_width/2 unless set.
    wide = tmp_path / 'wide.yaml'
    wide.write_text('track_width: 0.5\nsprocket_radius: 0.1\n')
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', wide,
                          '--report', tmp_path / 'r.json'], capsys)
    assert status == 0, err
    report = json.loads((tmp_path / 'r.json').read_text())
    assert report['models']['wide']['icr']['y_left'] == 0.25
    assert report['models']['wide']['icr']['y_right'] == -0.25
    assert report['settings']['track_width'] == 0.5
    assert report['models']['ideal']['icr']['y_left'] == 0.25


def test_windows_are_the_moving_ones_by_default(sim, scored, tmp_path, capsys):
    report, _ = scored
    assert report['windows_selection'] == {'moving_only': True, 'min_speed_mps': 0.1}
    for key in ('5', '10'):
        window = report['models']['ideal']['odometry']['windows'][key]
        assert 0 < window['n'] <= window['n_total']
    # A threshold no window reaches keeps none (and says so); 0 keeps them all.
    argv = [sim['bag'], '--ground-truth-topic', GT, '--params', sim['truth'], '--report',
            tmp_path / 'r.json', '--force']
    for speed, kept in (('20', lambda n, total: n == 0), ('0', lambda n, total: n == total)):
        status, _, err = run(argv + ['--min-speed', speed], capsys)
        assert status == 0, err
        doc = json.loads((tmp_path / 'r.json').read_text())
        assert doc['windows_selection']['min_speed_mps'] == float(speed)
        window = doc['models']['ideal']['odometry']['windows']['5']
        assert kept(window['n'], window['n_total']) and window['n_total'] > 0


def test_a_bag_after_params_is_a_bag(sim, tmp_path, capsys):
    # Issue 31 item 9: --params a.yaml BAG took the bag for a terrain file.
    status, out, err = run(['--ground-truth-topic', GT, '--params', sim['truth'], sim['bag']],
                           capsys)
    assert status == 0, err
    assert 'calib.truth' in out
    assert cli.bags_out_of_params(['--params', 'a.yaml', 'b.yml', 'run.mcap', '--force']) == [
        'run.mcap', '--params', 'a.yaml', 'b.yml', '--force']


def test_a_missing_params_file_and_an_empty_directory_say_what_they_are(sim, tmp_path, capsys):
    # Issue 31 item 9: a bare "[Errno 2]", and "Expected metadata file ... (truncated or
    # corrupt?)" for an empty directory.
    gone = tmp_path / 'gone.yaml'
    status, _, err = run([sim['bag'], '--ground-truth-topic', GT, '--params', gone], capsys)
    assert status == 2
    assert_one_line(err, f'--params {gone}: No such file or directory')
    empty = tmp_path / 'empty'
    empty.mkdir()
    status, _, err = run([empty, '--ground-truth-topic', GT, '--params', sim['truth']], capsys)
    assert status == 2
    assert_one_line(err, f'{empty} is not a bag: a rosbag2 bag is a directory with a '
                         'metadata.yaml')
    assert 'corrupt' not in err
