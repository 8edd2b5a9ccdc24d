"""
The gyro on ice (issue 35, item 4): its bias found in motion where the tracks slip most.

The Warthog ice bag of ../shared/realdata (2-s pieces of the calibration routine, never
standing still) split in time as bench_gyro_sets.py does: identify_icr's pose fit on the first
55 %, the rest replayed through the gyro-aided odometry as odometry_node runs it. Skipped
without the data.
"""

from helpers import realdata
import pytest
from tracked_kinematics.core import evaluate as ev
from tracked_kinematics.core.gyro import GYRO, replay
from tracked_kinematics.offline.bags import EncoderSource, GroundTruthSource, read_recording
from tracked_kinematics.offline.cli import identify_icr
from tracked_kinematics.offline.identification import fit
from tracked_kinematics.offline.model_evaluation import (
    evaluate_models, pose_references, TerrainModel)
from tracked_kinematics.offline.terrain_file import terrain_text

RADIUS, WIDTH = 0.3, 1.08


@pytest.fixture(scope='module')
def ice(tmp_path_factory):
    tmp = tmp_path_factory.mktemp('ice')
    train, test = realdata.split_bag(realdata.bag('warthog_ice_2024-07-30_16h30_part1'), tmp,
                                     0.55)
    args = identify_icr.build_parser().parse_args(
        [str(train), '--ground-truth-topic', realdata.TOPIC, '--sprocket-radius',
         str(RADIUS), '--track-width', str(WIDTH), '--terrain', 'ice', '--accept-uncertain',
         '--output', 'unused.yaml'])
    found = fit(identify_icr.options_from_args(args))
    path = tmp / 'ice.yaml'
    path.write_text(terrain_text(found.values, tool='test', date=found.date))
    recording = read_recording(test, EncoderSource(sprocket_radius=RADIUS),
                               ground_truth=GroundTruthSource(realdata.TOPIC),
                               imu_topic='/imu/data')
    return TerrainModel(path), test, recording


def test_the_bias_found_on_ice_is_not_the_tracks_slip_and_the_gyro_is_used(ice):
    # Before: -0.19 rad/s called known at +-0.02 (the gyro's mean rate is the tracks'
    # within 0.001 rad/s); measured now +0.005 +- 0.046.
    model, _, rec = ice
    _, _, odo = replay(rec.enc_t, rec.left, rec.right, rec.gyro_t, rec.gyro_rate, model.icr,
                       model.gyro, terms=model.noise.without_tracks())
    assert abs(odo.bias) <= 3.0 * odo.bias_std
    assert odo.bias_known and odo.source == GYRO


def test_on_ice_the_heading_is_the_gyros(ice):
    # Before: the gyro-aided heading error after 1 s was the encoders' (22.05 against
    # 22.16 deg: the gyro's weight was nil); measured now 14.5 deg (the plain gyro 8.1).
    model, test, recording = ice
    refs = pose_references([test], [(recording, None)], 'auto')
    report = evaluate_models(refs, [model], ev.Settings((0.5, 1.0), track_width=WIDTH,
                                                        min_speed=0.1),
                             sprocket_radius=RADIUS, fuse_imu=True)
    models = report.content['models']
    for window in ('0.5', '1'):
        alone = models[model.name]['odometry']['windows'][window]
        aided = models[f'{model.name}+imu']['odometry']['windows'][window]
        assert aided['mean_heading_error_rad'] < 0.8 * alone['mean_heading_error_rad']
        # The position: the reference inside these pieces is poor (bench_gyro_short_pieces:
        # its own heading gives 1.09 times the encoders' error), no worse than 1.05 times.
        assert aided['mean_position_error_m'] <= 1.05 * alone['mean_position_error_m']
