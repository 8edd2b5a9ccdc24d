"""
Benchmark: the gyro-aided odometry on every set of ../shared/realdata that has a gyro (issue 35).

Per set, a terrain file is fitted by identify_icr's library with the tool's own options (its
command line parsed: :func:`fit_options`; its pose fit, which finds the bag's gyro: the ICRs,
the noise model, ``imu_delay``, ``gyro_scale``) on training data and
the held-out data scored by evaluate_model's library with ``--fuse-imu``: the Warthog grass
runs leave one run out; the single-run sets (Warthog asphalt, sand, gravel, ice; Marmotte
snow) are split in time, the first 55 % of the bag's time to fit, the rest to score (copied
into two bags: the held-out part starts mid-drive, as a node restarted while the robot
drives). The tuned
diff_drive_controller is identify_icr's ``tuned_ddc`` fit of the same training data, scored
as an ICR file. Printed per set: mean final position error after 5 s and 10 s of the tuned
DDC, the encoders and the gyro-aided odometry, the targets of issue 35, and the coverage of
the published covariance (inside the 50 % / 95 % ellipses, mean NEES) of both rows, and per
set pooled over its held-out data.

Run: ``python benchmarks/bench_gyro_sets.py [REALDATA_FOLDER] [SET ...]`` (sets: grass,
asphalt, sand, gravel, ice, snow).
"""

import math
from pathlib import Path
import sys
import tempfile

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))

from helpers.realdata import from_argv, split_bag  # noqa: E402 -- the test helpers, from the tree
from tracked_kinematics.core import evaluate as ev  # noqa: E402
from tracked_kinematics.core import identify as ident  # noqa: E402
from tracked_kinematics.offline.bags import (  # noqa: E402
    EncoderSource, GroundTruthSource, read_recording)
from tracked_kinematics.offline.cli import identify_icr  # noqa: E402
from tracked_kinematics.offline.identification import fit as fit_icr, FitOptions  # noqa: E402
from tracked_kinematics.offline.model_evaluation import (  # noqa: E402
    evaluate_models, pose_references, TerrainModel)
from tracked_kinematics.offline.terrain_file import terrain_text  # noqa: E402
from tracked_kinematics.params import values_from_icr  # noqa: E402

SETS = {
    'grass': (('warthog_grass_2024-07-18_16h59', 'warthog_grass_2024-07-29_14h04',
               'warthog_grass_2024-08-08_16h11'), 0.3, 1.08),
    'asphalt': (('warthog_asphalt_2024-09-20_09h09',), 0.3, 1.08),
    'sand': (('warthog_sand_2024-09-25_14h13',), 0.3, 1.08),
    'gravel': (('warthog_gravel_2024-08-06_11h37_part1',), 0.3, 1.08),
    'ice': (('warthog_ice_2024-07-30_16h30_part1',), 0.3, 1.08),
    'snow': (('marmotte_snow_2024-01-25_12h15_part1',), 0.116702, 0.592723),
}
WINDOWS = (5.0, 10.0)
#: The windowed Warthog bags hold 2-s pieces of driving (README of realdata): never scored
#: across a gap (pieces of about 1.5 s with ground truth), so their windows are 0.5 s and 1 s.
SHORT = (0.5, 1.0)
WINDOWED = ('asphalt', 'sand', 'gravel', 'ice')
MIN_SPEED = 0.1
TRAIN_SHARE = 0.55


def folds(base: Path, names, tmp: Path):
    """Yield (training bags, held-out bag, label) for a set."""
    if len(names) > 1:
        for k, name in enumerate(names):
            yield [base / n for j, n in enumerate(names) if j != k], base / name, name
        return
    train, test = split_bag(base / names[0], tmp, TRAIN_SHARE)
    yield [train], test, f'{names[0]} (last {100 - 100 * TRAIN_SHARE:.0f} %)'


def score(bag, files, radius, width, windows):
    """Evaluate the files on a bag with --fuse-imu; return the report's models."""
    encoders = EncoderSource(sprocket_radius=radius)
    recording = read_recording(bag, encoders, ground_truth=GroundTruthSource('/icp/pose'),
                               imu_topic='/imu/data')
    references = pose_references([bag], [(recording, None)], 'auto')
    report = evaluate_models(references, [TerrainModel(f) for f in files],
                             ev.Settings(windows, track_width=width, min_speed=MIN_SPEED),
                             sprocket_radius=radius, fuse_imu=True)
    return report.content['models']


def fit_options(train, radius, width, label) -> FitOptions:
    """
    Return identify_icr's options for a pose fit of the training bags, from its command line.

    Through its parser, so that every default is the tool's: the library's own defaults differ
    (``IdentifyOptions.ground_truth_delay`` is 0, identify_icr's ``auto``). Fitted with the
    library's, the ICP's 0.2-s latency stayed in the pose and the noise model's ``timing`` took
    it up (0.018-0.11 s^2 instead of 0.006-0.013): the gyro-aided covariance was too large
    (82 / 97 % of the grass windows inside the 50 / 95 % ellipses after 5 s, 93 / 100 % on
    snow) where identify_icr's files give 45 / 94 % and 69 / 98 %.
    """
    args = identify_icr.build_parser().parse_args(
        [*map(str, train), '--ground-truth-topic', '/icp/pose', '--sprocket-radius',
         str(radius), '--track-width', str(width), '--terrain', label, '--accept-uncertain',
         '--output', 'unused.yaml'])
    return identify_icr.options_from_args(args)


def run_set(label, base: Path, tmp: Path):
    names, radius, width = SETS[label]
    encoders = EncoderSource(sprocket_radius=radius)
    pooled = {}
    for k, (train, test, name) in enumerate(folds(base, names, tmp)):
        found = fit_icr(fit_options(train, radius, width, label))
        terrain = tmp / f'{label}{k}.yaml'
        terrain.write_text(terrain_text(found.values, tool='bench', date=found.date))
        recs = [read_recording(p, encoders, ground_truth=GroundTruthSource('/icp/pose'))
                for p in train]
        fit = ident.identify(recs, 'icr_scales', width, ground_truth_delay='auto',
                             accept_uncertain=True)
        ddc = ident.build_model('tuned_ddc', width).as_icr(fit.ddc.p)
        tuned = tmp / f'ddc_{label}{k}.yaml'
        tuned.write_text(terrain_text(values_from_icr(ddc, radius), tool='bench', date=''))
        windows = SHORT if label in WINDOWED else WINDOWS
        models = score(test, [tuned, terrain], radius, width, windows)
        short, long = (f'{w:g}' for w in windows)
        rows = {'tuned DDC': models[tuned.stem], 'encoders': models[terrain.stem],
                'gyro-aided': models[f'{terrain.stem}+imu']}
        print(f'{label}: held out {name}: imu_delay {found.values.get("imu_delay", 0):+.3f} s, '
              f'gyro_scale {found.values.get("gyro_scale", 1):.4f}')
        err = {}
        for row, m in rows.items():
            cells = []
            for w in (short, long):
                win = m['odometry']['windows'][w]
                err[row, w] = win['mean_position_error_m']
                c = win.get('consistency')
                if c and c['inside_50'] is not None:
                    acc = pooled.setdefault((row, w), [0.0, 0.0, 0])
                    acc[0] += c['inside_50'] * c['windows']
                    acc[1] += c['inside_95'] * c['windows']
                    acc[2] += c['windows']
                cover = ('' if not c or c['inside_50'] is None else
                         f' {100 * c["inside_50"]:3.0f} / {100 * c["inside_95"]:3.0f} % '
                         f'NEES {c["mean_nees"]:5.2f} (n {c["windows"]})')
                cells.append(f'{w:>2} s: {win["mean_position_error_m"]:.3f} m '
                             f'{math.degrees(win["mean_heading_error_rad"]):5.2f} deg{cover}')
            print(f'    {row:<12}' + ' | '.join(cells))
        gyro = rows['gyro-aided'].get('gyro', {})
        print(f'    gyro at the end: {gyro.get("source_at_end")}, switches '
              f'{gyro.get("switches")}')
        r10d = err['gyro-aided', long] / err['tuned DDC', long]
        r10e = err['gyro-aided', long] / err['encoders', long]
        r5e = err['gyro-aided', short] / err['encoders', short]
        half = err['encoders', long] < 0.5 * err['tuned DDC', long]
        print(f'    targets: {long} s / DDC {r10d:.3f} [<= 0.85]'
              + (f', or {long} s / encoders {r10e:.3f} [<= 1.05: the encoders under half the '
                 'DDC]' if half else f', {long} s / encoders {r10e:.3f}')
              + f'; {short} s / encoders {r5e:.3f} [<= 1.05]', flush=True)
    print(f'{label}: the held-out data pooled, inside the 50 % / 95 % ellipses [35-65 / 85-98 %]:')
    for row in ('encoders', 'gyro-aided'):
        print(f'    {row:<12}' + ' | '.join(
            f'{w:>2} s: {100 * a / n:3.0f} / {100 * b / n:3.0f} % (n {n})'
            for (r, w), (a, b, n) in pooled.items() if r == row and n), flush=True)


def main():
    """Run the sets given (all by default)."""
    base, labels = from_argv(sys.argv[1:], SETS)
    with tempfile.TemporaryDirectory() as tmp:
        for label in labels:
            run_set(label, base, Path(tmp))
    return 0


if __name__ == '__main__':
    sys.exit(main())
