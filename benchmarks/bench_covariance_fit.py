"""
Benchmark: the fitted odometry noise model on the real bags of ../shared/realdata (issue 30).

Prints figures. For each Warthog grass run held out in turn:

1. identify_icr (the command line) on the two other runs: the terrain file's ICRs;
2. the noise model (:mod:`tracked_kinematics.core.noise_model`) fitted on the two other runs,
   each scored with the ICRs identified on the other one (leave one out:
   :func:`~tracked_kinematics.core.noise_model.held_out_windows`);
3. on the held-out run, through the windows evaluate_model scores (its ground-truth delay
   estimated and removed, windows of 5 s and 10 s in which the tracks move): the share of
   final position errors inside the published 50 % and 95 % ellipses and the mean NEES, for
   today's default noise (the track random walk, 1e-3 m^2/m) and for the fitted model.
   [target: 35-65 % inside the 50 % ellipse, 85-98 % inside the 95 % one]

Then the same pooled over the three held-out runs (the set); the Husky wet-grass run (no
second run: noise fitted on the held-out blocks of its first half, to its pose errors and
to its position errors only, checked on its second half); and what the gyro alone
determines (the heading's noise: ``track``, ``turn`` and ``timing`` fitted on the gyro of
two Warthog runs, ``slip`` held; the heading intervals checked on the third).

Run: ``python benchmarks/bench_covariance_fit.py [REALDATA_FOLDER]`` (default
``<repository>/../shared/realdata``, or ``$TRACKED_KINEMATICS_REALDATA``). About 2 min.
"""

import os
from pathlib import Path
import subprocess
import sys
import tempfile

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

from tracked_kinematics.core import identify as ident  # noqa: E402,I100
from tracked_kinematics.core import noise_model as nm  # noqa: E402
from tracked_kinematics.core.evaluate import noise  # noqa: E402
from tracked_kinematics.offline.bags import (  # noqa: E402
    EncoderSource, GroundTruthSource, read_recording)
from tracked_kinematics.offline.model_evaluation import (  # noqa: E402
    gyro_references, pose_references, TerrainModel)

WARTHOG = ('warthog_grass_2024-07-18_16h59', 'warthog_grass_2024-07-29_14h04',
           'warthog_grass_2024-08-08_16h11')
HUSKY = 'husky_wetgrass_part1'
VEHICLES = {'warthog': (0.3, 1.08), 'husky': (0.15875, 0.5384615384615384)}
LENGTHS = (5.0, 10.0)
TOPIC = '/icp/pose'


def folder() -> Path:
    """Return the folder of the real bags."""
    if len(sys.argv) > 1:
        return Path(sys.argv[1])
    named = os.environ.get('TRACKED_KINEMATICS_REALDATA')
    return Path(named) if named else ROOT.parent / 'shared' / 'realdata'


def identify_icr(bags, radius, width, out: Path):
    """Run identify_icr on bags; return the terrain file's ICR model."""
    cmd = [sys.executable, '-m', 'tracked_kinematics.offline.cli.identify_icr', *map(str, bags),
           '--ground-truth-topic', TOPIC, '--sprocket-radius', str(radius),
           '--track-width', str(width), '--output', str(out)]
    subprocess.run(cmd, check=True, capture_output=True, env={**os.environ,
                                                              'PYTHONPATH': str(ROOT)})
    return TerrainModel(out).icr


def fitter(width):
    """Return ``recordings -> IcrParams``: identify_icr's fit, the delay already removed."""
    return lambda recordings: ident.identify(recordings, 'icr_scales', width,
                                             ground_truth_delay=0.0,
                                             accept_uncertain=True).icr


def figures(c) -> str:
    """Return '50 % / 95 % / NEES' of a consistency result."""
    return f'{100 * c["inside_50"]:3.0f} % {100 * c["inside_95"]:3.0f} % {c["mean_nees"]:6.2f}'


def in_band(c) -> bool:
    """Whether a consistency result meets the acceptance target."""
    return 0.35 <= c['inside_50'] <= 0.65 and 0.85 <= c['inside_95'] <= 0.98


def row(label, windows, model) -> str:
    """Return one table row: each window length's figures."""
    cells = []
    for length in LENGTHS:
        c = windows.of_length(length).consistency(model)
        cells.append(f'{figures(c)} {"ok" if in_band(c) else "--"} n={c["windows"]:<5d}')
    return f'    {label:<34}' + ' | '.join(cells)


def header() -> str:
    """Return the table header."""
    return (f'    {"":<34}' + ' | '.join(f'{f"{w:g} s: in 50 %  in 95 %  NEES":<37}'
                                         for w in LENGTHS))


def pose_recordings(base, names, found):
    """Return the recordings with their ground-truth delay removed (evaluate_model's)."""
    return [d.recording for d in
            pose_references([base / n for n in names], [found[n] for n in names], 'auto').data]


def warthog(base, found, tmp):
    """Hold each Warthog run out in turn; return the pooled held-out windows per model."""
    radius, width = VEHICLES['warthog']
    pooled = {'today': [], 'fitted': []}
    for held in WARTHOG:
        train = [n for n in WARTHOG if n != held]
        icr = identify_icr([base / n for n in train], radius, width, tmp / f'{held}.yaml')
        windows = noise.held_out_windows(pose_recordings(base, train, found), fitter(width),
                                         LENGTHS, track_width=width)
        fit = noise.fit_noise(windows)
        test = noise.recording_windows(pose_recordings(base, [held], found), icr, LENGTHS,
                                       track_width=width)
        m = fit.model
        print(f'bench_covariance_fit: held out {held}; fitted on the other two '
              f'({fit.windows} windows, ~{fit.independent:.0f} independent): track '
              f'{m.track:.2e} m^2/m, turn {m.turn:.2e} rad^2/rad, slip {m.slip:.2e} m^2/rad, '
              f'timing {m.timing:.2e} s^2 (sigma {np.sqrt(m.timing):.3f} s)')
        print(header())
        for name, model in (('today (track 1e-3 m^2/m)', nm.NoiseModel()), ('fitted', m)):
            print(row(name, test, model))
            pooled['today' if name.startswith('today') else 'fitted'].append((test, model))
    print('bench_covariance_fit: Warthog grass, the three held-out runs together')
    print(header())
    for name, items in pooled.items():
        cells = []
        for length in LENGTHS:
            parts = [(w.of_length(length), m) for w, m in items]
            c = nm.consistency(np.concatenate([w.errors[:, :2] for w, _ in parts]),
                               np.concatenate([nm.covariances(w.bases, m) for w, m in parts]))
            cells.append(f'{figures(c)} {"ok" if in_band(c) else "--"} n={c["windows"]:<5d}')
        print(f'    {name:<34}' + ' | '.join(cells))


def husky(base):
    """Fit on the first half of the Husky run (held-out blocks), check on the second half."""
    radius, width = VEHICLES['husky']
    found = (read_recording(base / HUSKY, EncoderSource(sprocket_radius=radius),
                            ground_truth=GroundTruthSource(TOPIC)), None)
    (rec,) = pose_recordings(base, [HUSKY], {HUSKY: found})
    middle = 0.5 * (rec.enc_t[0] + rec.enc_t[-1])
    from tracked_kinematics.core.identify.holdout import crop_recording
    first = crop_recording(rec, rec.enc_t[0], middle)
    second = crop_recording(rec, middle, rec.enc_t[-1])
    windows = noise.held_out_windows([first], fitter(width), LENGTHS, track_width=width)
    icr = fitter(width)([first])
    test = noise.recording_windows([second], icr, LENGTHS, track_width=width)
    print(f'bench_covariance_fit: {HUSKY}: fitted on the held-out blocks of the first half, '
          'checked on the second half')
    print(header())
    print(row('today (track 1e-3 m^2/m)', test, nm.NoiseModel()))
    for errors in ('pose', 'position'):
        m = noise.fit_noise(windows, errors=errors).model
        print(row(f'fitted to {errors} errors', test, m))
        print(f'      track {m.track:.2e}, turn {m.turn:.2e}, slip {m.slip:.2e}, '
              f'timing {m.timing:.2e}')


def gyro(base):
    """Fit the heading-rate noise on the gyro of two Warthog runs, check on the third."""
    radius, width = VEHICLES['warthog']
    encoders = EncoderSource(sprocket_radius=radius)
    found = {n: read_recording(base / n, encoders, imu_topic='/imu/data') for n in WARTHOG}
    refs = gyro_references([base / n for n in WARTHOG], [found[n] for n in WARTHOG], width)
    recs = dict(zip(WARTHOG, (d.recording for d in refs.data)))
    print('bench_covariance_fit: gyro only (heading reference): track, turn and timing '
          'fitted on the gyro of two runs (the ICRs of their gyro calibration), slip held at '
          'the prior; heading errors of the third inside the 50 % / 95 % intervals, mean '
          'normalised squared error (1 if consistent)')
    for held in WARTHOG:
        train = [n for n in WARTHOG if n != held]
        icr = ident.fit_recordings([found[n] for n in train], width).icr
        windows = noise.recording_windows([recs[n] for n in train], icr, LENGTHS,
                                          track_width=width)
        fit = noise.fit_noise(windows, free=('track', 'turn', 'timing'),
                              errors='heading')
        test = noise.recording_windows([recs[held]], icr, LENGTHS, track_width=width)
        m = fit.model
        cells = [figures(test.of_length(w).heading_consistency(m)) for w in LENGTHS]
        print(f'    held out {held}: track {m.track:.2e}, turn {m.turn:.2e}, timing '
              f'{m.timing:.2e}; ' + ' | '.join(f'{w:g} s: {c}' for w, c in zip(LENGTHS, cells)))


def main():
    """Run the Warthog rotation, the Husky and the gyro fit."""
    base = folder()
    if not (base / 'README.md').is_file():
        print(f'bench_covariance_fit: no real data in {base}; give the folder as the argument')
        return 1
    radius, _ = VEHICLES['warthog']
    found = {n: (read_recording(base / n, EncoderSource(sprocket_radius=radius),
                                ground_truth=GroundTruthSource(TOPIC)), None)
             for n in WARTHOG}
    with tempfile.TemporaryDirectory() as tmp:
        warthog(base, found, Path(tmp))
    husky(base)
    gyro(base)
    return 0


if __name__ == '__main__':
    sys.exit(main())
