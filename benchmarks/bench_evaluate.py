"""
Benchmark: evaluate_model on the real bags of ../shared/realdata, and its cost per hour.

For each bag, the terrain files a user would have: identify_icr's icr_scales fit of the same
data (in-sample), for the Warthog also the fit of the two other runs (held out), with
identify_drivetrain's first-order drive train of all three Warthog runs; then the
evaluate_model console script's whole run (read, ground-truth delay, odometry windows, RPE,
2-s predictions from the encoders and from the commands, the icr_estimator EKF replayed from
each file) prints its table. Last, the wall time of each phase per hour of data.

The realdata directory is ``$TRACKED_KINEMATICS_REALDATA``, else ``../shared/realdata`` beside
the repository; without it the benchmark says so and stops.
"""

import contextlib
import io
import os
from pathlib import Path
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
REALDATA = Path(os.environ.get('TRACKED_KINEMATICS_REALDATA', ROOT.parent / 'shared' / 'realdata'))

from tracked_kinematics.core import evaluate as ev  # noqa: E402
from tracked_kinematics.core import identify as ident  # noqa: E402
from tracked_kinematics.core.kinematics import IcrParams  # noqa: E402
from tracked_kinematics.offline.bags import (  # noqa: E402
    CommandSource, EncoderSource, GroundTruthSource, read_recording, read_recordings)
from tracked_kinematics.offline.cli import evaluate_model  # noqa: E402
from tracked_kinematics.offline.model_evaluation import commands_of  # noqa: E402
from tracked_kinematics.params import (  # noqa: E402
    values_from_drivetrain, values_from_icr, write_params_file)

HUSKY = ('husky_wetgrass_part1', 0.15875, 0.5384615384615384)
WARTHOG = ('warthog_grass_2024-07-18_16h59', 'warthog_grass_2024-07-29_14h04',
           'warthog_grass_2024-08-08_16h11')
WARTHOG_RADIUS, WARTHOG_WIDTH = 0.3, 1.08
GT = GroundTruthSource('/icp/pose')


def _fit(bags, radius, width):
    recordings = read_recordings([REALDATA / b for b in bags],
                                 EncoderSource(sprocket_radius=radius), ground_truth=GT)
    return ident.identify(recordings, 'icr_scales', width, holdout=0.0).icr


def _terrain(path, icr, radius, drivetrain=None):
    values = values_from_icr(icr, radius)
    if drivetrain is not None:
        values.update(values_from_drivetrain(drivetrain))
    write_params_file(path, values)
    return str(path)


def terrain_files(folder: Path):
    """Identify the terrain files of every bag: ``{bag: [files]}``."""
    files = {}
    name, radius, width = HUSKY
    files[name] = [_terrain(folder / 'husky_wetgrass.yaml', _fit([name], radius, width), radius)]
    drives = read_recordings([REALDATA / b for b in WARTHOG],
                             EncoderSource(sprocket_radius=WARTHOG_RADIUS),
                             commands=CommandSource())
    drivetrain = ident.fit_drivetrain(drives).drivetrain
    everything = _fit(WARTHOG, WARTHOG_RADIUS, WARTHOG_WIDTH)
    for bag in WARTHOG:
        others = [b for b in WARTHOG if b != bag]
        held = _fit(others, WARTHOG_RADIUS, WARTHOG_WIDTH)
        files[bag] = [
            _terrain(folder / 'warthog_held_out.yaml', held, WARTHOG_RADIUS, drivetrain),
            _terrain(folder / 'warthog_all_runs.yaml', everything, WARTHOG_RADIUS, drivetrain)]
        folder = folder / bag
        folder.mkdir()
    return files


def tables(files):
    """Run evaluate_model on each bag; print its table."""
    for bag, params in files.items():
        radius = HUSKY[1] if bag == HUSKY[0] else WARTHOG_RADIUS
        print(f'\n=== {bag} ===')
        start = time.perf_counter()
        status = evaluate_model.main([str(REALDATA / bag), '--ground-truth-topic', '/icp/pose',
                                      '--params', *params, '--sprocket-radius', str(radius),
                                      '--online'])
        print(f'(exit {status}, {time.perf_counter() - start:.1f} s)')


def cost():
    """Wall time of each phase per hour of data, over all four bags."""
    phases = dict.fromkeys(('read', 'delay', 'score (3 models)', 'replay (EKF)'), 0.0)
    seconds = 0.0
    for bag, radius, width in [HUSKY] + [(b, WARTHOG_RADIUS, WARTHOG_WIDTH) for b in WARTHOG]:
        start = time.perf_counter()
        rec = read_recording(REALDATA / bag, EncoderSource(sprocket_radius=radius),
                             ground_truth=GT, commands=CommandSource('auto', track_width=width))
        found = commands_of(rec)
        phases['read'] += time.perf_counter() - start
        seconds += rec.duration
        start = time.perf_counter()
        delay = ident.estimate_delay([rec]).delay
        phases['delay'] += time.perf_counter() - start
        rec = ident.correct_ground_truth([rec], delay)[0]
        icr = _fit([bag], radius, width)
        start = time.perf_counter()
        run = ev.replay(rec, icr, delay)
        phases['replay (EKF)'] += time.perf_counter() - start
        data = [ev.Data(rec, ev.Commands(*found))]
        candidates = [ev.Candidate('ideal', IcrParams.ideal(width)),
                      ev.Candidate('file', icr), ev.Candidate('online', icr, runs=(run,))]
        start = time.perf_counter()
        ev.evaluate(data, candidates)
        phases['score (3 models)'] += time.perf_counter() - start
    hours = seconds / 3600.0
    print(f'\ncost per hour of data ({seconds:.0f} s of bags): '
          + ', '.join(f'{name} {value / hours:.1f} s' for name, value in phases.items())
          + f'; total {sum(phases.values()) / hours:.1f} s')


def main():
    if not REALDATA.is_dir():
        print(f'bench_evaluate: no real data at {REALDATA} (set TRACKED_KINEMATICS_REALDATA)')
        return
    with tempfile.TemporaryDirectory() as tmp:
        with contextlib.redirect_stdout(io.StringIO()):
            files = terrain_files(Path(tmp))
        tables(files)
    cost()


if __name__ == '__main__':
    sys.exit(main())
