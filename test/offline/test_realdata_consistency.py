"""
The fitted covariance and the gyro-aided odometry on the Warthog grass bags of ../shared/realdata.

Leave one bag out, through the tools as a user runs them: identify_icr on the other two from
the ICP alone (it finds the gyro in the bags: ``imu_delay``, ``gyro_scale``), from the ICP and
the gyro (``--imu-topic`` too) and from the gyro alone, then evaluate_model --fuse-imu on the
held-out bag. The three held-out bags together: 85-98 % of the windows inside the published
95 % ellipse and 35-65 % inside the 50 % one (issue 30), after 5 s and 10 s, for the encoders'
and the gyro-aided covariance of the pose and the pose + gyro files (issue 35: the pose fit
alone's gyro-aided row, measured 45 / 94 % and 57 / 97 %, was once reported too large, by a
benchmark that fitted without removing the ICP's delay); the gyro-aided 10-s error below the
encoders' (issue 29). Per fold (issue 36): pose + gyro never more than 2 % worse than the pose
alone, and the gyro-only file's covariance consistent on the held-out run. The fits are made
once for the module. Skipped without the data.
"""

import contextlib
import io
import json

from helpers import realdata
import pytest
from tracked_kinematics.offline.cli import evaluate_model, identify_icr
from tracked_kinematics.params import read_params_file

GRASS = [n for n in realdata.BAGS if n.startswith('warthog_grass')]
VEHICLE = ['--sprocket-radius', '0.3', '--track-width', '1.08']
GT = ['--ground-truth-topic', realdata.TOPIC]
GYRO = ['--imu-topic', '/imu/data']
FILES = {'pose': GT, 'both': GT + GYRO, 'gyro': GYRO}


@pytest.fixture(scope='module')
def folds(tmp_path_factory):
    """Per held-out bag: evaluate_model's models, the pose + gyro fit's stdout and file."""
    paths = [realdata.bag(n) for n in GRASS]
    found = {}
    for k, path in enumerate(paths):
        root = tmp_path_factory.mktemp(f'fold{k}')
        train = [str(p) for j, p in enumerate(paths) if j != k]
        printed = {}
        for name, references in FILES.items():
            stdout = io.StringIO()
            with contextlib.redirect_stdout(stdout):
                status = identify_icr.main([*train, *references, *VEHICLE,
                                            '--output', str(root / f'{name}.yaml')])
            assert status == 0, (name, stdout.getvalue())
            printed[name] = stdout.getvalue()
        report = root / 'eval.json'
        with contextlib.redirect_stdout(io.StringIO()):
            assert evaluate_model.main([str(path), *GT, '--params',
                                        *(str(root / f'{n}.yaml') for n in FILES),
                                        '--sprocket-radius', '0.3', '--fuse-imu', '/imu/data',
                                        '--report', str(report)]) == 0
        found[GRASS[k]] = (json.loads(report.read_text())['models'], printed['both'],
                           read_params_file(str(root / 'both.yaml')))
    return found


def windows(models, name):
    return models[name]['odometry']['windows']


def pooled(folds, name, window):
    """Return the consistency of a row over the three held-out bags (window-weighted)."""
    parts = [windows(models, name)[window]['consistency'] for models, _, _ in folds.values()]
    n = sum(p['windows'] for p in parts)
    return {key: sum(p[key] * p['windows'] for p in parts) / n
            for key in ('inside_50', 'inside_95', 'mean_nees')}


@pytest.mark.parametrize('name', ['pose', 'pose+imu', 'both', 'both+imu'])
@pytest.mark.parametrize('window', ['5', '10'])
def test_the_fitted_covariance_holds_its_share_of_held_out_windows(folds, name, window):
    c = pooled(folds, name, window)
    assert 0.85 <= c['inside_95'] <= 0.98, c
    assert 0.35 <= c['inside_50'] <= 0.65, c


def test_identify_icr_wrote_the_gyro_constants_it_measured(folds):
    for models, _, values in folds.values():
        # Two bags: the noise model scored each with the ICRs fitted on the other.
        assert values['identification.covariance.held_out'] == 'leave one recording out'
        gyro = models['both+imu']['gyro']
        # The encoders trail the gyro by about 0.17 s on these logs (issue 29).
        assert -0.20 < gyro['imu_delay_s'] < -0.15
        assert gyro['from_file'] == {'imu_delay': True, 'gyro_scale': True}


def test_the_gyro_aided_10_s_error_beats_the_encoders_on_every_held_out_bag(folds):
    total = {'both': 0.0, 'both+imu': 0.0}
    for models, _, _ in folds.values():
        errors = {name: windows(models, name)['10'] for name in total}
        assert errors['both+imu']['mean_position_error_m'] < \
            errors['both']['mean_position_error_m'], errors
        for name, w in errors.items():
            total[name] += w['mean_position_error_m'] * w['n']
    # Measured: 0.140 m against 0.167 m over the three bags.
    assert total['both+imu'] < 0.9 * total['both']


@pytest.mark.parametrize('held', GRASS)
def test_pose_and_gyro_never_worse_than_the_pose_alone(folds, held):
    models, printed, values = folds[held]
    for suffix in ('', '+imu'):
        for length in ('5', '10'):
            pose = windows(models, 'pose' + suffix)[length]['mean_position_error_m']
            combined = windows(models, 'both' + suffix)[length]['mean_position_error_m']
            assert combined <= 1.02 * pose, (suffix, length, combined, pose)
    # The combined fit says what it kept and why, and writes the gyro's constants.
    assert any(line.startswith('pose + gyro /imu/data') and 'kept' in line
               for line in printed.splitlines()), printed
    assert values['imu_delay'] == pytest.approx(-0.176, abs=0.01)
    assert values['gyro_bias_sigma'] > 0.0


@pytest.mark.parametrize('held', GRASS)
def test_gyro_only_covariance_is_consistent_on_the_held_out_run(folds, held):
    models, _, _ = folds[held]
    for length in ('5', '10'):
        inside = windows(models, 'gyro')[length]['consistency']['inside_95']
        # 0.26-0.60 before the held distance scale and icr.x entered the covariance; 0.99 and
        # 1.00 after 5 s (2024-07-18, 2024-08-08) while the scale's prior went through the
        # timing term (constant in the window's length, exact at 10 s only). With its own
        # term (covariance.scale, the displacement's, exact at any length): 0.94 / 0.98 /
        # 0.95 after 5 s, 0.98 / 0.95 / 0.93 after 10 s.
        assert 0.85 <= inside <= 0.98, (length, inside)


MARMOTTE = 'marmotte_snow_2024-01-25_12h15_part1'


def test_the_marmottes_gyro_aided_covariance_from_a_pose_fit_holds_on_its_held_out_drive(
        tmp_path):
    # The tracked Marmotte on snow, one bag: identify_icr's pose fit (it finds the gyro) on
    # its first 55 %, evaluate_model --fuse-imu on the rest, which starts mid-drive. With the
    # encoders' noise model (issue 35): 67 / 98.4 % of 61 windows of 5 s inside the 50 / 95 %
    # ellipses (above both target bands, 35-65 / 85-98 %), 61 / 97 % of 31 of 10 s. With the
    # gyro-aided odometry's own constants (covariance.gyro_aided.*, fitted on its windows of
    # the first 55 %) and the fusion of issue 35 item 4: 62 / 95 % and 61 / 90 %; four reset
    # schedules 58 / 94 % and 55 / 92 %, the split the other way round 43 / 90 % and 35 / 92 %
    # (benchmarks/bench_gyro_covariance.py).
    train, test = realdata.split_bag(realdata.bag(MARMOTTE), tmp_path, 0.55)
    vehicle = ['--sprocket-radius', '0.116702', '--track-width', '0.592723']
    pose = tmp_path / 'pose.yaml'
    assert identify_icr.main([str(train), *GT, *vehicle, '--output', str(pose)]) == 0
    values = read_params_file(str(pose))
    assert values['covariance.gyro_aided.drift'] > 0.0
    assert values['identification.covariance.gyro_aided.windows'] >= 50
    report = tmp_path / 'eval.json'
    assert evaluate_model.main([str(test), *GT, '--params', str(pose), '--sprocket-radius',
                                '0.116702', '--fuse-imu', '/imu/data',
                                '--report', str(report)]) == 0
    models = json.loads(report.read_text())['models']
    used = models['pose+imu']['gyro']['noise']
    assert used['from_file'] and used['drift'] == values['covariance.gyro_aided.drift']
    for window in ('5', '10'):
        c = models['pose+imu']['odometry']['windows'][window]['consistency']
        assert c['windows'] >= 25, c
        assert 0.85 <= c['inside_95'] <= 0.98, c
        assert 0.35 <= c['inside_50'] <= 0.65, c
    errors = {name: models[name]['odometry']['windows']['10']['mean_position_error_m']
              for name in ('pose', 'pose+imu')}
    # Measured: 0.161 m against the encoders' 0.450 m (0.188 m before issue 35 item 4).
    assert errors['pose+imu'] < 0.5 * errors['pose'], errors
