"""
Benchmark: what the gyro-aided covariance is made of on held-out runs, how far its coverage moves.

The published covariance of odometry_node with ``imu_topic`` (evaluate_model ``--fuse-imu``'s
``+imu`` row: the terrain file's noise model without its track terms, with the gyro-aided
odometry's own ``slip``, ``timing`` and ``drift`` (``covariance.gyro_aided.*``, which identify_icr
fits on the training data's gyro-aided windows), the tracks' random walk, the gyro's heading
with its bias, the time error at both ends), replayed with ``~/reset``
every 5 s and 10 s on held-out data, as :func:`..core.evaluate.consistency.
gyro_window_consistency` does, with four reset schedules a quarter window apart (the first
reset at a piece's start, then 1/4, 1/2 and 3/4 of a window later). Printed per case and
window length: the share of the windows inside the 50 % / 95 % ellipses per schedule and
pooled, the mean NEES, the mean squared error against the mean trace, and each term's share of
the mean trace (each term replayed alone; ``gyro`` is the heading's share from the gyro's noise,
bias and scale, with no term of the file).

Cases (identify_icr's pose fit, which finds the gyro, through its command line): ``snow``, the
Marmotte's run fitted on its first 55 % and scored on the rest (test/offline/
test_realdata_consistency.py's protocol); ``snow_reversed``, fitted on the last 45 % and scored
on the first 55 %; ``grass``, each Warthog grass run scored with a file fitted on the two
others (pooled). docs/nodes/odometry_node.md, "Consistency of the published covariance", has
the figures.

Run: ``python benchmarks/bench_gyro_covariance.py [REALDATA_FOLDER] [CASE ...]``.
"""

import contextlib
from dataclasses import replace
import io
from pathlib import Path
import sys
import tempfile

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))

from helpers.realdata import from_argv, split_bag  # noqa: E402 -- the test helpers, from the tree
import numpy as np  # noqa: E402
from tracked_kinematics.core import evaluate as ev  # noqa: E402
from tracked_kinematics.core.covariance import TrackNoise  # noqa: E402
from tracked_kinematics.core.evaluate.consistency import gyro_reset_windows  # noqa: E402
from tracked_kinematics.core.noise_model import consistency, NoiseModel  # noqa: E402
from tracked_kinematics.offline.bags import (  # noqa: E402
    EncoderSource, GroundTruthSource, read_recording)
from tracked_kinematics.offline.cli import identify_icr  # noqa: E402
from tracked_kinematics.offline.model_evaluation import (  # noqa: E402
    pose_references, TerrainModel)
from tracked_kinematics.params import track_noise_from_values  # noqa: E402

MARMOTTE = ('marmotte_snow_2024-01-25_12h15_part1', 0.116702, 0.592723)
GRASS = ('warthog_grass_2024-07-18_16h59', 'warthog_grass_2024-07-29_14h04',
         'warthog_grass_2024-08-08_16h11')
WARTHOG = (0.3, 1.08)
CASES = ('snow', 'snow_reversed', 'grass')
LENGTHS = (5.0, 10.0)
OFFSETS = (0.0, 0.25, 0.5, 0.75)
MIN_SPEED = 0.1
TRAIN_SHARE = 0.55
TERMS = ('turn', 'slip', 'timing', 'scale', 'drift')


def folds(case, base: Path, tmp: Path):
    """Yield (training bags, held-out bag, sprocket radius, track width) of a case."""
    if case == 'grass':
        for held in GRASS:
            yield [base / n for n in GRASS if n != held], base / held, *WARTHOG
        return
    name, radius, width = MARMOTTE
    first, rest = split_bag(base / name, tmp, TRAIN_SHARE)
    if case == 'snow':
        yield [first], rest, radius, width
    else:
        yield [rest], first, radius, width


def fit(train, out: Path, radius, width) -> Path:
    """Return the terrain file identify_icr's pose fit writes for the training bags."""
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        status = identify_icr.main([*map(str, train), '--ground-truth-topic', '/icp/pose',
                                    '--sprocket-radius', str(radius), '--track-width',
                                    str(width), '--output', str(out)])
    if status != 0:
        raise RuntimeError(printed.getvalue())
    return out


def held_out(bag, terrain: Path, radius, width):
    """Return the held-out recording (the pose's delay removed), its pieces and the model."""
    recording = read_recording(bag, EncoderSource(sprocket_radius=radius),
                               ground_truth=GroundTruthSource('/icp/pose'),
                               imu_topic='/imu/data')
    data = pose_references([bag], [(recording, None)], 'auto').data[0]
    model = TerrainModel(terrain)
    settings = ev.Settings(LENGTHS, track_width=width, min_speed=MIN_SPEED)
    pieces = ev.evaluate([data], [ev.Candidate(model.name, model.icr, model.drivetrain)],
                         settings).pieces
    return data.recording, pieces, model


def windows(rec, pieces, model, length, offset, noise, terms, gyro_terms=None):
    """
    Replay the gyro-aided odometry reset every ``length`` s, from ``offset`` s into each piece.

    ``gyro_terms``: the terms while the heading is the gyro's (default ``terms``). Returns the
    final position errors (W, 2) and the published position covariances (W, 2, 2), as
    :func:`gyro_window_consistency` scores them.
    """
    return gyro_reset_windows(rec, pieces, model.icr, model.gyro, noise, terms, gyro_terms,
                              length, MIN_SPEED, offset)[:2]


def shares(scored, length):
    """Return each term's share of the mean trace on the first schedule, in %."""
    none = NoiseModel(track=0.0, floor=0.0)
    still = TrackNoise(0.0, 0.0, 0.0)
    traces = {}
    for rec, pieces, model in scored:
        terms = model.gyro_noise.without_tracks()
        alone = {'gyro': (still, none), 'tracks': (track_noise_from_values(model.values), none)}
        alone.update({t: (still, replace(none, **{t: getattr(terms, t)})) for t in TERMS})
        gyro = windows(rec, pieces, model, length, 0.0, still, none)[1]
        for name, (noise, term) in alone.items():
            cov = windows(rec, pieces, model, length, 0.0, noise, term)[1]
            if name != 'gyro':
                cov = cov - gyro
            traces.setdefault(name, []).append(np.trace(cov, axis1=1, axis2=2))
    total = sum(np.concatenate(t).mean() for t in traces.values())
    return {name: 100.0 * np.concatenate(t).mean() / total for name, t in traces.items()}


def run_case(case, base: Path, tmp: Path):
    scored = []
    tmp = tmp / case
    tmp.mkdir()
    for k, (train, test, radius, width) in enumerate(folds(case, base, tmp)):
        terrain = fit(train, tmp / f'{case}{k}.yaml', radius, width)
        scored.append(held_out(test, terrain, radius, width))
    for length in LENGTHS:
        cells, everything = [], []
        for offset in OFFSETS:
            found = [windows(rec, pieces, model, length, offset * length,
                             track_noise_from_values(model.values), model.noise.without_tracks(),
                             model.gyro_noise.without_tracks())
                     for rec, pieces, model in scored]
            e = np.concatenate([f[0] for f in found])
            p = np.concatenate([f[1] for f in found])
            everything.append((e, p))
            c = consistency(e, p)
            cells.append(f'{100 * c["inside_50"]:3.0f} / {100 * c["inside_95"]:3.0f}')
        e = np.concatenate([f[0] for f in everything])
        p = np.concatenate([f[1] for f in everything])
        c = consistency(e, p)
        ratio = np.mean(np.sum(e * e, 1)) / np.mean(np.trace(p, axis1=1, axis2=2))
        part = ', '.join(f'{n} {s:.1f}' for n, s in shares(scored, length).items())
        print(f'{case} {length:g} s: schedules {" | ".join(cells)} %; pooled '
              f'{100 * c["inside_50"]:.0f} / {100 * c["inside_95"]:.0f} %, NEES '
              f'{c["mean_nees"]:.2f} ({c["windows"]} windows), |e|^2 / trace {ratio:.2f}; '
              f'% of the trace: {part}', flush=True)


def main():
    """Run the cases given (all by default)."""
    base, cases = from_argv(sys.argv[1:], CASES)
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            run_case(case, base, Path(tmp))
    return 0


if __name__ == '__main__':
    sys.exit(main())
