"""
Benchmark: identify_icr on the real robot bags of ../shared/realdata (issue 16). Prints figures.

Per bag (and for the three Warthog bags together), ground truth from lidar ICP stamped on
receipt:

1. The delay of the ground-truth stamps behind the encoders that identify_icr finds, with
   its standard error, against the README's figure. [within 0.03 s]
2. The identification's wall time (delay, segments, fits, hold-out).
3. Mean held-out position error over 10 s windows of ideal drive, the tuned
   diff_drive_controller and every fitted model: on the stamps as recorded (delay
   estimated and removed), on the stamps corrected by the README's latency (no delay
   removed), and on the stamps as recorded with no delay removed; the ratio of the first to
   the second. [icr_scales within 10 %]

Run: ``python benchmarks/bench_realdata.py [REALDATA_FOLDER]`` (default
``<repository>/../shared/realdata``, or ``$TRACKED_KINEMATICS_REALDATA``).
"""

import os
from pathlib import Path
import sys
import time

ROOT = Path(__file__).resolve().parent.parent

from tracked_kinematics.core import identify as ident  # noqa: E402,I100
from tracked_kinematics.offline.bags import (  # noqa: E402
    EncoderSource, GroundTruthSource, read_recordings)

# name: (sprocket radius m, track width m, README latency s)
BAGS = {
    'warthog_grass_2024-07-18_16h59': (0.3, 1.08, 0.26),
    'warthog_grass_2024-07-29_14h04': (0.3, 1.08, 0.24),
    'warthog_grass_2024-08-08_16h11': (0.3, 1.08, 0.19),
    'husky_wetgrass_part1': (0.15875, 0.5384615384615384, 0.11),
}
MODELS = ('ideal', 'tuned_ddc') + ident.FIT_MODELS


def folder() -> Path:
    """Return the folder of the real bags."""
    if len(sys.argv) > 1:
        return Path(sys.argv[1])
    named = os.environ.get('TRACKED_KINEMATICS_REALDATA')
    return Path(named) if named else ROOT.parent / 'shared' / 'realdata'


def windows(result):
    """Mean held-out 10 s window position error of every model, m (None: no windows)."""
    out = {}
    for name in MODELS:
        e = result.evaluation(name)
        out[name] = e.windows.position_mean if e and e.windows and e.windows.n else None
    return out


def run(label, names, base):
    """Identify one set of bags three ways and print the figures."""
    radius, width, _ = BAGS[names[0]]
    readme = [BAGS[n][2] for n in names]
    recordings = read_recordings([base / n for n in names], EncoderSource(sprocket_radius=radius),
                                 ground_truth=GroundTruthSource('/icp/pose'))
    started = time.perf_counter()
    auto = ident.identify(recordings, 'icr_scales', width, ground_truth_delay='auto',
                          accept_uncertain=True)
    wall = time.perf_counter() - started
    stamps = [ident.correct_ground_truth([r], d)[0] for r, d in zip(recordings, readme)]
    corrected = ident.identify(stamps, 'icr_scales', width, ground_truth_delay=0.0,
                               accept_uncertain=True)
    raw = ident.identify(recordings, 'icr_scales', width, ground_truth_delay=0.0,
                         accept_uncertain=True)
    phases = ', '.join(f'{k} {v:.2f}' for k, v in auto.seconds.items())
    for name, d, known in zip(names, auto.delays or [auto.delay], readme):
        which = label if name == label else f'{label}: {name}'
        print(f'bench_realdata: {which}: delay {d.delay:.3f} s +- {d.std:.3f} '
              f'({d.uncertainty}) against README {known:.2f} s: off by {d.delay - known:+.3f} '
              's [0.03]')
    if auto.delays:
        print(f'bench_realdata: {label}: pooled delay {auto.delay.delay:.3f} s '
              f"+- {auto.delay.std:.3f} (each bag's own removed)")
    print(f'bench_realdata: {label}: identification {wall:.2f} s ({phases})')
    t = auto.time
    held = auto.holdout
    print(f'bench_realdata: {label}: {t.covered:.0f} s of data, {t.driving:.0f} s driving, '
          f'{auto.jumps} ground-truth jumps; hold-out {len(held.folds)} fold(s), '
          f'{auto.evaluation("ideal").windows.n} windows of 10 s')
    rows = {k: windows(r) for k, r in (('raw, delay removed', auto),
                                       ('README-corrected', corrected),
                                       ('raw, no delay removed', raw))}
    print(f'bench_realdata: {label}: mean 10 s window position error (m):')
    print(f'    {"model":<22}' + ''.join(f'{k:>24}' for k in rows) + f'{"ratio 1/2":>11}')
    for name in MODELS:
        values = [rows[k][name] for k in rows]
        ratio = (f'{values[0] / values[1]:.3f}' if values[0] is not None and values[1]
                 else '-')
        print(f'    {name:<22}' + ''.join(f'{v:>24.3f}' if v is not None else f'{"-":>24}'
                                          for v in values) + f'{ratio:>11}')
    ddc = ident.ddc_parameters(auto.ddc.p, width, radius)
    print(f'bench_realdata: {label}: tuned DDC wheel_separation_multiplier '
          f'{ddc["wheel_separation_multiplier"]:.3f}, wheel radius multipliers '
          f'{ddc["left_wheel_radius_multiplier"]:.3f} / '
          f'{ddc["right_wheel_radius_multiplier"]:.3f}; icr_scales chi {auto.icr.chi:.3f}, '
          f'icr.x {auto.icr.x:+.3f} m')


def main():
    """Run every bag, then the Warthog bags together."""
    base = folder()
    if not (base / 'README.md').is_file():
        print(f'bench_realdata: no real data in {base}; give the folder as the argument')
        return 1
    for name in BAGS:
        run(name, [name], base)
    run('warthog x3', [n for n in BAGS if n.startswith('warthog')], base)
    return 0


if __name__ == '__main__':
    sys.exit(main())
