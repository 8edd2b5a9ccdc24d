"""
evaluate_model's report as a library (offline/model_evaluation.py): no command line, no bag.

The command line end to end: test_evaluate_model.py; the figures themselves:
test/core/evaluate/.
"""

import json
import math

from helpers.recordings import late
from helpers.vehicle_sim import AURIGA, B, simulate
import numpy as np
import pytest
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core.errors import ExcitationError, InvalidParameters
from tracked_kinematics.core.identify import Recording
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.models import ConstantIcr
from tracked_kinematics.offline.model_evaluation import (
    evaluate_models, gyro_references, pose_references, read_terrain_models, References,
    table_text)

TRUE = IcrParams(B, *AURIGA)
AURIGA_YAML = f"""track_width: {B}
sprocket_radius: 0.1
icr: {{y_left: {TRUE.y_left}, y_right: {TRUE.y_right}, x: {TRUE.x}}}
scale: {{left: {TRUE.scale_left}, right: {TRUE.scale_right}}}
"""
SETTINGS = ev.Settings(windows=(2.0, 5.0), track_width=B, min_speed=0.1)


@pytest.fixture(scope='module')
def drive():
    """Drive the Auriga-alpha on hard floor for a minute, exact pose at 10 Hz."""
    return simulate(ConstantIcr(B), np.array(AURIGA), duration=60.0, seed=3)


def setpoints(rec):
    """Return the nominal track speeds the drive held, as commands ``(t, values, kind)``."""
    dt = np.diff(rec.enc_t)
    values = np.column_stack([np.diff(rec.left) / dt, np.diff(rec.right) / dt])
    return rec.enc_t[:-1], values, 'setpoints'


@pytest.fixture
def models(tmp_path):
    (tmp_path / 'auriga.yaml').write_text(AURIGA_YAML)
    (tmp_path / 'nominal.yaml').write_text(f'track_width: {B}\nsprocket_radius: 0.1\n')
    return read_terrain_models([tmp_path / 'auriga.yaml', tmp_path / 'nominal.yaml'])


@pytest.fixture
def scored(drive, models, tmp_path):
    references = pose_references([tmp_path / 'run1'], [(drive, setpoints(drive))], delay=0.0)
    return evaluate_models(references, models, SETTINGS, sprocket_radius=0.1,
                           command_source='setpoints')


def test_terrain_files_are_named_by_stem_and_default_to_ideal_drive(tmp_path):
    (tmp_path / 'sub').mkdir()
    paths = [tmp_path / 'a.yaml', tmp_path / 'sub' / 'a.yaml', tmp_path / 'ideal.yaml',
             tmp_path / 'online_a.yaml']
    for path in paths:
        path.write_text('track_width: 0.5\nsprocket_radius: 0.1\n')
    models = read_terrain_models(paths)
    # 'ideal' is the baseline's; 'online_a_2' is the estimator started from a_2.
    assert [m.name for m in models] == ['a', 'a_2', 'ideal_2', 'online_a_3']
    icr = models[0].icr
    assert (icr.y_left, icr.y_right, icr.x) == (0.25, -0.25, 0.0)
    assert not models[0].drivetrain_in_file


def test_an_invalid_terrain_file_is_named_in_the_error(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('track_width: 0.42\nicr: {y_left: -0.3, y_right: 0.3}\n')
    with pytest.raises(InvalidParameters, match=f'^{bad}: '):
        read_terrain_models([bad])


def test_a_given_delay_is_taken_off_the_ground_truth(drive, tmp_path):
    references = pose_references([tmp_path / 'run1'], [(late(drive, 0.3), None)], delay=0.3)
    np.testing.assert_allclose(references.data[0].recording.gt_t, drive.gt_t, atol=1e-9)
    assert references.data[0].commands is None
    assert references.account == '0.3 s (given)' and references.reference == 'pose'
    record = references.records[0]
    assert record['bag'] == str((tmp_path / 'run1').resolve()) and record['name'] == 'run1'
    assert (record['ground_truth_delay_s'], record['ground_truth_delay_std_s'],
            record['ground_truth_delay_source']) == (0.3, None, 'given')
    assert (record['commands'], record['command_samples']) == (None, 0)
    assert record['ground_truth_samples'] == len(drive.gt_t)


def test_an_auto_delay_is_estimated_from_the_data(drive, tmp_path):
    references = pose_references([tmp_path / 'run1'], [(late(drive, 0.2), setpoints(drive))])
    record = references.records[0]
    assert record['ground_truth_delay_s'] == pytest.approx(0.2, abs=0.02)
    assert record['ground_truth_delay_source'] == 'auto'
    assert record['ground_truth_delay_std_s'] > 0.0
    assert 'given' not in references.account
    commands = references.data[0].commands
    assert isinstance(commands, ev.Commands) and commands.source == 'setpoints'
    assert record['command_samples'] == len(drive.enc_t) - 1


def test_the_report_holds_every_section_and_its_json(scored):
    content = scored.content
    assert content['tool'] == 'evaluate_model'
    assert content['order'] == scored.names == ['ideal', 'auriga', 'nominal']
    assert content['settings'] == {
        'windows_s': [2.0, 5.0], 'horizon_s': 2.0, 'prediction_dt_s': 0.05,
        'rpe_distances_m': [1.0, 10.0], 'max_command_age_s': 0.5, 'keep_jumps': False,
        'track_width': B, 'sprocket_radius': 0.1, 'command_source': 'setpoints',
        'fuse_imu_topic': None}
    assert content['windows_selection'] == {'moving_only': True, 'min_speed_mps': 0.1}
    assert content['data'] == {'pieces': 1, 'gaps': 0, 'jumps': 0,
                               'seconds': pytest.approx(60.0, abs=0.2)}
    record = content['recordings'][0]
    assert (record['pieces'], record['gaps'], record['jumps']) == (1, 0, 0)
    assert content['pieces'][0]['bag'] == record['bag'] == content['bags'][0]
    assert [m['kind'] for m in content['models'].values()] == ['ideal', 'file', 'file']
    assert content['models']['auriga']['icr']['y_left'] == TRUE.y_left
    assert content['models']['nominal']['drivetrain']['from_file'] is False
    assert json.loads(scored.json()) == content
    assert scored.json().endswith('}\n')
    assert len(scored.evaluation.pieces) == 1
    assert set(scored.evaluation.paths) == set(scored.names)


def test_the_true_file_is_scored_better_than_ideal_drive(scored):
    models = scored.content['models']
    for w in ('2', '5'):
        ideal = models['ideal']['odometry']['windows'][w]['mean_position_error_m']
        truth = models['auriga']['odometry']['windows'][w]['mean_position_error_m']
        assert truth < 1e-3 < 0.05 * ideal
    assert models['auriga']['rpe_1m'] < 1e-3 < models['ideal']['rpe_1m']
    assert (models['auriga']['prediction']['mean_rmse_translation_m']
            < 0.5 * models['ideal']['prediction']['mean_rmse_translation_m'])
    assert models['ideal']['prediction']['drivetrain'].startswith('none')


def test_the_table_is_what_evaluate_model_prints(scored, tmp_path):
    tmp_models = tmp_path
    lines = scored.table().split('\n')
    assert scored.table() == table_text(scored.content)
    assert lines[0] == ('evaluate_model: 1 bag(s), 60 s; scored 60 s in 1 gap-free pieces '
                        '(0 gaps, 0 ground-truth jumps left out)')
    assert lines[1] == 'ground-truth delay behind the encoders: 0 s (given)'
    assert lines[2] == ''
    head = lines.index(next(line for line in lines if line.startswith('model')))
    assert lines[head].split()[:6] == ['model', '2', 's:', 'pos', 'm', 'hdg']
    assert lines[head].endswith('2 s cmd: m    deg')
    assert [line.split()[0] for line in lines[head + 1:head + 4]] == [
        'ideal', 'auriga', 'nominal']
    windows = scored.content['models']['ideal']['odometry']['windows']
    assert lines[head + 4].startswith(
        'windows in which the tracks move (mean track speed >= 0.1 m/s; --all-windows for '
        f'all): {windows["2"]["n"]} of {windows["2"]["n_total"]} of 2 s, ')
    assert lines[head + 4].endswith(' from the commands')
    # The files' published covariance: shares, NEES and a verdict per window length.
    c = lines.index(next(line for line in lines if line.startswith('published covariance')))
    assert lines[c - 1] == '' and lines[c + 1].split()[:5] == ['model', '2', 's:', '50', '%']
    rows = {line.split()[0]: line.split()[1:] for line in lines[c + 2:c + 4]}
    assert set(rows) == {'auriga', 'nominal'}
    for name, cells in rows.items():
        found = scored.content['models'][name]['odometry']['windows']['2']['consistency']
        assert cells[:4] == [f'{100 * found["inside_50"]:.0f}',
                             f'{100 * found["inside_95"]:.0f}', f'{found["mean_nees"]:.1f}',
                             found['verdict']]
        assert found['verdict'] in ('consistent', 'over-confident', 'under-confident')
    assert lines[c + 4].startswith('independent (non-overlapping) windows behind each verdict')
    # The closing advice: the best row on these bags and the command that runs it.
    best = lines.index(next(line for line in lines if line.startswith('best on these bags')))
    assert lines[best].startswith('best on these bags (mean final position error after 5 s): '
                                  'auriga ')
    # The exact drive's errors are far inside the default noise model's ellipses.
    assert lines[best + 1] == ('its published covariance is under-confident after 5 s: see '
                               'the consistency lines above before fusing it')
    assert lines[best + 2:best + 4] == [
        'run it:', f'  odometry_node --ros-args --params-file {tmp_models}/auriga.yaml']
    assert lines[-1] == ('(in a ROS 2 workspace: ros2 run tracked_kinematics odometry_node '
                         '--ros-args ...)')


def test_every_window_and_kept_jumps_are_said(drive, models, tmp_path):
    references = pose_references([tmp_path / 'run1'], [(drive, None)], delay=0.0)
    settings = ev.Settings(windows=(5.0,), jumps=False, track_width=B)
    report = evaluate_models(references, models, settings, sprocket_radius=0.1)
    content = report.content
    assert content['windows_selection'] == {'moving_only': False, 'min_speed_mps': None}
    assert content['settings']['keep_jumps'] is True
    window = content['models']['ideal']['odometry']['windows']['5']
    assert window['n'] == window['n_total'] > 0
    assert content['models']['ideal']['prediction'] is None
    table = report.table()
    assert 'no commands in the bags: no prediction from commands' in table
    assert '(0 gaps, kept)' in table.split('\n')[0]
    assert f'windows, idle ones too: {window["n"]} of 5 s; ' in table
    assert 'cmd: m' not in table


def test_online_entries_follow_the_files(drive, models, tmp_path):
    references = pose_references([tmp_path / 'run1'], [(drive, None)], delay=0.0)
    report = evaluate_models(references, models[1:], SETTINGS, sprocket_radius=0.1,
                             online=True)
    assert report.names == ['ideal', 'nominal', 'online_nominal']
    entry = report.content['models']['online_nominal']
    assert entry['kind'] == 'online' and entry['online']['start'] == 'nominal'
    assert entry['online']['outcomes']['updated'] > 100
    assert 0.0 <= entry['online']['trusted_fraction'] <= 1.0
    assert len(entry['online']['final_icr']) == 1
    lines = report.table().split('\n')
    assert any(line.startswith('online_nominal: ') for line in lines)
    # The estimator learns the drive from ideal: the best row, and how to run it.
    best = next(line for line in lines if line.startswith('best on these bags'))
    assert best.split(': ')[1].startswith('online_nominal ')
    at = lines.index('run it (the online estimator needs a pose source on the robot):')
    nominal = report.content['models']['nominal']['file']
    assert lines[at + 1:at + 3] == [
        f'  odometry_node --ros-args --params-file {nominal}',
        f'  icr_estimator --ros-args --params-file {nominal} -p pose_topic:=YOUR_POSE_TOPIC '
        '-p push_to:=[odometry_node]']
    assert lines[at + 3].startswith('without a pose source, the file alone (nominal: ')


def test_nothing_to_score_is_an_excitation_error(drive, models, tmp_path):
    # The ground truth starts after the encoders have stopped.
    apart = Recording(drive.enc_t, drive.left, drive.right, drive.gt_t + 100.0, drive.gt_x,
                      drive.gt_y, drive.gt_yaw)
    references = pose_references([tmp_path / 'run1'], [(apart, None)], delay=0.0)
    with pytest.raises(ExcitationError, match='nothing to score'):
        evaluate_models(references, models, SETTINGS, sprocket_radius=0.1)


@pytest.fixture(scope='module')
def gyro_drive():
    """Two minutes with a gyro at 50 Hz, 0.01 rad/s of bias, stamped 0.1 s late."""
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=120.0, gt_rate=50.0, seed=5)
    yaw = np.unwrap(rec.gt_yaw)
    rate = np.diff(yaw) / np.diff(rec.gt_t) + 0.01
    stamps = 0.5 * (rec.gt_t[1:] + rec.gt_t[:-1]) + 0.1
    return Recording(rec.enc_t, rec.left, rec.right, gyro_t=stamps, gyro_rate=rate)


def test_a_gyro_reference_scores_heading_only(gyro_drive, models, tmp_path):
    references = gyro_references([tmp_path / 'run1'], [gyro_drive], B)
    assert references.reference == 'imu'
    record = references.records[0]
    assert record['imu_delay_s'] == pytest.approx(0.1, abs=0.02)
    assert record['gyro_bias_rad_s'] == pytest.approx(0.01, abs=1e-3)
    assert record['ground_truth_delay_s'] is None
    assert references.account.startswith('none (gyro reference); the gyro: ')
    report = evaluate_models(references, models, SETTINGS, sprocket_radius=0.1)
    content = report.content
    assert content['reference'] == 'imu'
    for entry in content['models'].values():
        window = entry['odometry']['windows']['5']
        assert window['mean_position_error_m'] is None and window['drift_pct'] is None
        assert math.isfinite(window['mean_heading_error_rad'])
        assert entry['rpe'] is None and entry['rpe_1m'] is None
        assert entry['odometry']['horizon']['mean_rmse_translation_m'] is None
    heading = content['models']['auriga']['odometry']['windows']['5']['mean_heading_error_rad']
    ideal = content['models']['ideal']['odometry']['windows']['5']['mean_heading_error_rad']
    assert heading < 0.2 * ideal
    assert content['pieces'][0]['path_length_m'] is None
    table = report.table().split('\n')
    assert table[2].startswith('reference: the gyro, heading only')
    assert next(line for line in table if line.startswith('ideal')).split()[1] == '-'
    with pytest.raises(ValueError, match='pose reference'):
        evaluate_models(references, models, SETTINGS, sprocket_radius=0.1, online=True)


def test_references_can_be_built_by_hand(drive, models):
    # The library does not need the readers: plain recordings and records do.
    record = {'bag': '/data/run1', 'name': 'run1', 'duration_s': drive.duration,
              'encoder_samples': len(drive.enc_t), 'ground_truth_samples': len(drive.gt_t),
              'ground_truth_delay_s': 0.0, 'ground_truth_delay_std_s': None,
              'ground_truth_delay_source': 'given', 'commands': None, 'command_samples': 0}
    references = References((ev.Data(drive),), (record,), 'none')
    report = evaluate_models(references, models, SETTINGS, sprocket_radius=0.1)
    assert report.content['bags'] == ['/data/run1']
    assert 'pieces' not in record


def test_the_error_plot_fits_the_calibrated_models_not_the_ideal_drive(scored):
    from tracked_kinematics.offline.model_evaluation_plot import error_curves, evaluation_figure
    # 'nominal' is the ideal drive again; the true file alone beside it.
    fig = evaluation_figure(scored.evaluation, ['ideal', 'auriga'], (2.0, 5.0), min_speed=0.1)
    position = fig.axes[0]
    curves = {line.get_label(): line.get_ydata() for line in position.get_lines()
              if not line.get_label().startswith('_')}
    ideal = next(label for label in curves if label.startswith('ideal'))
    # The ideal drive runs off the top, its values in its legend; the files fill the axis.
    assert ideal.startswith('ideal (off scale: ') and ' m at 5 s)' in ideal
    top = position.get_ylim()[1]
    assert np.nanmax(curves[ideal]) > 3.0 * top
    assert np.nanmax(curves['auriga']) <= top
    # With a file as poor as the ideal drive, nothing is cut.
    alone = evaluation_figure(scored.evaluation, ['ideal', 'nominal'], (2.0, 5.0),
                              min_speed=0.1)
    lengths = alone.axes[0].get_lines()[0].get_xdata()
    curve = error_curves(scored.evaluation, ['ideal'], lengths, 0.1)['ideal'][0]
    assert alone.axes[0].get_ylim()[1] >= np.nanmax(curve)


def test_a_gyro_reference_takes_a_given_delay(gyro_drive, tmp_path):
    # evaluate_model --imu-delay: where the tracks slip too much to time the gyro (refused,
    # test_realdata_pose_gyro.py), the delay measured on firm ground is given.
    references = gyro_references([tmp_path / 'run1'], [gyro_drive], B, imu_delay=0.12)
    assert references.records[0]['imu_delay_s'] == 0.12
    assert references.account.startswith('none (gyro reference); the gyro: ')
    assert 'given' in references.account
