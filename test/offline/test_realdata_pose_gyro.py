"""
identify_icr with a pose, a gyro, or both, on the Warthog grass runs of ../shared/realdata.

Each fold fits on two runs and scores the third as evaluate_model does (``--fuse-imu`` for
the gyro-aided rows): pose + gyro never more than 2 % worse than the pose alone, and the
gyro-only file's covariance consistent on the held-out run. Skipped without the data. The
fits (holdout 0: the table's comparison is not what is tested here) are made once per module.
"""

from dataclasses import replace
from pathlib import Path
import tempfile

from helpers import realdata
import pytest
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core.identify.procedure import IdentifyOptions
from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource, read_recording
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.offline.identification.api import fit, FitOptions
from tracked_kinematics.offline.identification.combined import (
    icr_from_pose_and_gyro, time_split)
from tracked_kinematics.offline.identification.noise_constants import gyro_extras
from tracked_kinematics.offline.identification.poses import icr_from_poses
from tracked_kinematics.offline.identification.references import icr_from_references
from tracked_kinematics.offline.model_evaluation import (
    evaluate_models, pose_references, TerrainModel)
from tracked_kinematics.offline.terrain_file import terrain_text

GRASS = [n for n in realdata.BAGS if n.startswith('warthog_grass')]
WIDTH, RADIUS = 1.08, 0.3
GYRO = '/imu/data'


def without_pose(rec):
    return replace(rec, gt_t=None, gt_x=None, gt_y=None, gt_yaw=None)


@pytest.fixture(scope='module')
def recordings():
    encoders = EncoderSource(sprocket_radius=RADIUS)
    return [read_recording(realdata.bag(n), encoders, imu_topic=GYRO,
                           ground_truth=GroundTruthSource(realdata.TOPIC)) for n in GRASS]


def options(names, **changes):
    fields = {'ground_truth': GroundTruthSource(realdata.TOPIC), **changes}
    return FitOptions(bags=tuple(names), sprocket_radius=RADIUS, track_width=WIDTH,
                      identify=IdentifyOptions(ground_truth_delay='auto', holdout=0.0),
                      **fields)


def write(tmp, name, found):
    path = tmp / f'{name}.yaml'
    path.write_text(terrain_text(found.values, tool='test', date=found.date))
    return TerrainModel(path)


@pytest.fixture(scope='module')
def folds(recordings, tmp_path_factory):
    """Per held-out run: evaluate_model's report of the pose, gyro and pose+gyro files."""
    reports = {}
    for held, name in enumerate(GRASS):
        tmp = tmp_path_factory.mktemp(f'fold{held}')
        train = [r for k, r in enumerate(recordings) if k != held]
        names = [n for k, n in enumerate(GRASS) if k != held]
        # The pose alone as identify_icr writes it: with the gyro found in the bags.
        pose = fit(options([str(realdata.bag(n)) for n in names]))
        both = icr_from_pose_and_gyro(train, options(names, imu_topic=GYRO), GYRO, WIDTH,
                                      RADIUS)
        gyro = icr_from_references([without_pose(r) for r in train],
                                   options(names, ground_truth=None, imu_topic=GYRO),
                                   WIDTH, RADIUS)
        files = (('pose', pose), ('both', both), ('gyro', gyro))
        models = [write(tmp, k, f) for k, f in files]
        refs = pose_references([name], [(recordings[held], None)])
        report = evaluate_models(refs, models, ev.Settings(track_width=WIDTH, min_speed=0.1),
                                 sprocket_radius=RADIUS, fuse_imu=True)
        reports[name] = (report.content['models'], both)
    return reports


def windows(models, name):
    return models[name]['odometry']['windows']


@pytest.mark.parametrize('held', GRASS)
def test_pose_and_gyro_never_worse_than_the_pose_alone(folds, held):
    models, both = folds[held]
    for suffix in ('', '+imu'):
        for length in ('5', '10'):
            pose = windows(models, 'pose' + suffix)[length]['mean_position_error_m']
            combined = windows(models, 'both' + suffix)[length]['mean_position_error_m']
            assert combined <= 1.02 * pose, (suffix, length, combined, pose)
    # The combined fit says what it kept and why, and writes the gyro's constants.
    assert any(line.startswith(f'pose + gyro {GYRO}') and 'kept' in line
               for line in both.lines)
    assert both.values['imu_delay'] == pytest.approx(-0.176, abs=0.01)
    assert both.values['gyro_bias_sigma'] > 0.0


@pytest.mark.parametrize('held', GRASS)
def test_gyro_only_covariance_is_consistent_on_the_held_out_run(folds, held):
    models, _ = folds[held]
    for length in ('5', '10'):
        inside = windows(models, 'gyro')[length]['consistency']['inside_95']
        # 0.26-0.60 before the held distance scale and icr.x entered the covariance. The
        # target is 0.85-0.98; the held priors are exact for 10-s windows and generous for
        # 5-s ones: after 5 s the 2024-07-18 and 2024-08-08 runs are over-covered (0.99 and
        # 1.00 with the time error's lever arm of issue 35), never under.
        assert 0.85 <= inside <= (0.98 if length == '10' else 1.0), (length, inside)


def test_a_gyro_mounted_upside_down_is_left_out(recordings):
    names = GRASS[1:]
    flipped = [replace(r, gyro_rate=-r.gyro_rate) for r in recordings[1:]]
    found = icr_from_pose_and_gyro(flipped, options(names, imu_topic=GYRO), GYRO, WIDTH,
                                   RADIUS)
    assert any('left out' in line and 'sign is swapped' in line for line in found.lines)
    for key in ('imu_delay', 'gyro_scale', 'gyro_bias'):
        assert key not in found.values
    assert found.values['identification.gyro_refused'].startswith('the gyro turns the other')
    # The ICRs are the pose's alone.
    alone = icr_from_poses(recordings[1:], options(names), WIDTH, RADIUS)
    assert found.values['icr.y_left'] == pytest.approx(alone.values['icr.y_left'])


def test_cli_pose_and_gyro_plots_and_a_diameter_as_radius_is_refused(tmp_path, capsys):
    bag = str(realdata.bag(GRASS[1]))
    common = [bag, '--ground-truth-topic', realdata.TOPIC, '--track-width', str(WIDTH)]
    status = identify_icr.main(common + ['--imu-topic', GYRO, '--sprocket-radius', '0.3',
                                         '--output', str(tmp_path / 'g.yaml'), '--plot',
                                         str(tmp_path / 'g.png')])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert 'needs a ground-truth pose' not in err
    assert (tmp_path / 'g.png').stat().st_size > 0
    assert 'hold-out:' in out and 'diff_drive_controller:' in out and 'standard errors' in out
    status = identify_icr.main(common + ['--sprocket-radius', '0.6', '--output',
                                         str(tmp_path / 'd.yaml')])
    out, err = capsys.readouterr()
    assert status == 3
    assert 'scale.left ended on its lower bound 0.5' in err
    assert 'a diameter given as --sprocket-radius' in err
    assert not (tmp_path / 'd.yaml').exists()


def test_marmotte_on_snow_fits_with_pose_and_gyro():
    # The tracked robot: exit 4 before on the whole run ("chi = 1.289 is outside (0, 1]").
    # Fitted on the first 60 % of the run, scored on the rest.
    name = 'marmotte_snow_2024-01-25_12h15_part1'
    radius, width = 0.116702, 0.592723
    path = realdata.bag(name)
    rec = read_recording(path, EncoderSource(sprocket_radius=radius), imu_topic=GYRO,
                         ground_truth=GroundTruthSource(realdata.TOPIC))
    train, test = time_split(rec, 0.6)
    opts = replace(options([name], imu_topic=GYRO), sprocket_radius=radius,
                   track_width=width)
    both = icr_from_pose_and_gyro([train], opts, GYRO, width, radius)
    alone = icr_from_poses([train], replace(opts, imu_topic=None), width, radius)
    assert 0.0 < both.values['identification.chi'] <= 1.0
    assert 'imu_delay' in both.values
    refs = pose_references([name], [(test, None)])
    with tempfile.TemporaryDirectory() as tmp:
        models = [write(Path(tmp), k, f) for k, f in (('both', both), ('alone', alone))]
        report = evaluate_models(refs, models, ev.Settings(track_width=width, min_speed=0.1),
                                 sprocket_radius=radius, fuse_imu=True)
    models = report.content['models']
    for suffix in ('', '+imu'):
        for length in ('5', '10'):
            a = windows(models, 'alone' + suffix)[length]['mean_position_error_m']
            b = windows(models, 'both' + suffix)[length]['mean_position_error_m']
            assert b <= 1.02 * a, (suffix, length, b, a)


def test_imu_delay_the_same_on_firm_ground_and_refused_on_ice():
    # One logging set-up: the windowed Warthog bags. On ice the body follows the spinning
    # wheels late; timed against the tracks the gyro came out +0.49 s there (written before).
    delays = {}
    for terrain in ('sand_2024-09-25_14h13', 'asphalt_2024-09-20_09h09',
                    'gravel_2024-08-06_11h37_part1', 'ice_2024-07-30_16h30_part1'):
        rec = read_recording(realdata.bag(f'warthog_{terrain}'),
                             EncoderSource(sprocket_radius=RADIUS), imu_topic=GYRO,
                             ground_truth=GroundTruthSource(realdata.TOPIC))
        extras, _ = gyro_extras([rec], GYRO)
        delays[terrain.split('_')[0]] = (extras.values.get('imu_delay'), extras.lines)
    firm = [delays[t][0] for t in ('sand', 'asphalt', 'gravel')]
    assert max(firm) - min(firm) <= 0.03, firm
    ice, lines = delays['ice']
    assert ice is None
    assert any('the tracks slip too much to time the gyro' in line for line in lines)
