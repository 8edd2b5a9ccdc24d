"""identify_icr's noise model and gyro constants: covariance.*, imu_delay, gyro_scale.

Simulated bags with a known gyro (bias, noise, scale error, offset in time: simulate_bag's
--imu options); the coverage of the fitted covariance on held-out real runs is in
test_realdata_consistency.py.
"""

import json

import pytest
from tracked_kinematics.core.sim.sensors import GyroModel
from tracked_kinematics.offline.bag_simulation import simulate_bag
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.params import read_params_file

GT = '/ground_truth/pose'
IMU = '/imu/data'
KEYS = ('covariance.k_left', 'covariance.k_right', 'covariance.turn', 'covariance.slip',
        'covariance.timing')


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Two simulated drives with a gyro 0.08 s late, 5 % over-reading, biased and noisy."""
    root = tmp_path_factory.mktemp('gyro')
    gyro = GyroModel(rate=100.0, bias=0.01, noise_std=0.003, latency=0.08, scale=1.05)
    out = {}
    for name, seed, model in (('scaled', 3, gyro), ('true_scale', 4,
                                                    GyroModel(bias=-0.004, noise_std=0.003,
                                                              latency=0.08))):
        result = simulate_bag(root / name, 'auriga_alpha', duration=150.0, seed=seed, imu=model)
        out[name] = (result.bag, result.truth)
    return out


def identify(tmp_path, capsys, bag, truth, *extra):
    out = tmp_path / 'fit.yaml'
    report = tmp_path / 'fit.json'
    bag = bag if isinstance(bag, list) else [bag]
    status = identify_icr.main([*map(str, bag), '--params', str(truth), '--output', str(out),
                                '--report', str(report), *map(str, extra)])
    text = capsys.readouterr().out
    assert status == 0, text
    return read_params_file(out), json.loads(report.read_text()), text


def test_pose_and_gyro_write_the_noise_model_imu_delay_and_gyro_scale(bags, tmp_path, capsys):
    values, report, text = identify(tmp_path, capsys, *bags['scaled'], '--ground-truth-topic',
                                    GT, '--imu-topic', IMU)
    assert values['imu_delay'] == pytest.approx(0.08, abs=0.01)
    assert values['identification.imu_delay'] == values['imu_delay']
    # 5 % scale error, the fit's standard error a few 0.001: determined and written.
    assert values['gyro_scale'] == pytest.approx(1.05, abs=0.005)
    assert values['identification.gyro_scale_method'] == 'fitted against the pose'
    assert 0 < values['identification.gyro_scale_std'] < 0.005
    for key in KEYS:
        assert values[key] > 0.0, key
    assert values['covariance.k_left'] == values['covariance.k_right']
    assert values['identification.covariance.errors'] == 'pose'
    assert values['identification.covariance.held'] == []
    assert sorted(values['identification.covariance.fitted']) == sorted(
        ['track', 'turn', 'slip', 'timing'])
    assert values['identification.covariance.held_out'] == 'held-out time blocks'
    assert values['identification.covariance.windows'] > 100
    assert report['covariance']['model']['turn'] == values['covariance.turn']
    assert report['gyro']['gyro_scale'] == values['gyro_scale']
    # One fit of the segments on the pose and the gyro: the table and the choice are printed.
    assert 'hold-out:' in text and 'pose + gyro' in text and 'kept:' in text
    assert 'noise model (pose errors' in text and 'gyro scale (measured / true)' in text


def test_a_gyro_of_the_right_scale_gets_1_and_says_why(bags, tmp_path, capsys):
    values, _, text = identify(tmp_path, capsys, *bags['true_scale'], '--ground-truth-topic',
                               GT, '--imu-topic', IMU)
    assert values['gyro_scale'] == 1.0
    assert values['identification.gyro_scale_fitted'] == pytest.approx(1.0, abs=0.01)
    assert values['identification.gyro_scale_method'].startswith('not determined')
    assert 'not determined' in text


def test_gyro_alone_fits_what_the_heading_determines_and_holds_slip(bags, tmp_path, capsys):
    values, report, text = identify(tmp_path, capsys, *bags['scaled'], '--imu-topic', IMU)
    assert values['imu_delay'] == pytest.approx(0.08, abs=0.01)
    assert 'gyro_scale' not in values   # no pose: the scale cannot be told from chi
    assert values['identification.covariance.errors'] == 'heading'
    assert values['identification.covariance.held'] == ['slip']
    # The prior's slip, and the held icr.x's uncertainty (0.1 track width) on top of it;
    # the held distance scale's (5 %) in its own term.
    assert values['covariance.slip'] > 2e-2
    assert values['identification.covariance.held_prior'] == ['distance_scale +- 0.05',
                                                              'icr.x +- 0.042']
    assert values['covariance.scale'] == pytest.approx(0.05 ** 2)
    assert report['covariance']['held'] == ['slip']
    assert 'held at the prior: slip' in text
    assert 'the uncertainty of what was held added' in text
    # The same DDC snippet as a pose fit prints.
    assert 'diff_drive_controller:\n  ros__parameters:' in text


@pytest.mark.long   # leave one recording out: the grass folds run it in make test
def test_pose_alone_on_two_bags_holds_each_out_in_turn(bags, tmp_path, capsys):
    values, _, _ = identify(tmp_path, capsys, [bags['scaled'][0], bags['true_scale'][0]],
                            bags['true_scale'][1], '--ground-truth-topic', GT)
    for key in KEYS:
        assert values[key] > 0.0, key
    assert values['identification.covariance.held_out'] == 'leave one recording out'
    # The bags carry one gyro topic: its constants are written beside the pose fit's ICRs.
    assert values['identification.gyro_topic'] == IMU
    assert values['imu_delay'] == pytest.approx(0.08, abs=0.01)
    assert 'gyro_scale' in values
