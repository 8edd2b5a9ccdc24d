"""
Benchmark: ICR identification (issue 6). Prints the figures; goals in brackets.

1. The paper's data size (Martinez sec. 5.3): 1807 segments of 0.27 s, encoders every
   0.03 s; least-squares fit of the default model, icr_scales. [< 0.5 s]
2. The same data: least squares against differential evolution (the derivative-free global
   search standing in for the paper's genetic algorithm): time and final cost.
3. A one-hour log, encoders at 100 Hz and ground truth at 10 Hz, written to an mcap bag
   and run through the identify_icr console script with its defaults (read, compare all
   models on held-out blocks, fit, write): wall time and peak memory of the process.
   [< 60 s, < 1 GB]
"""

from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))

from helpers.vehicle_sim import AURIGA, B, simulate, write_bag  # noqa: E402,I100
from timing import best_of  # noqa: E402
from tracked_kinematics.core import identify as ident  # noqa: E402
from tracked_kinematics.core.models import ConstantIcr  # noqa: E402


def paper_sized():
    """1807 segments of 0.27 s with 9 encoder steps each, light ground-truth noise."""
    rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=1808 * 0.27,
                   enc_rate=1 / 0.03, gt_rate=1 / 0.27, seed=5)
    rng = np.random.default_rng(1)
    noisy = ident.Recording(rec.enc_t, rec.left, rec.right, rec.gt_t,
                            rec.gt_x + rng.normal(0, 0.002, len(rec.gt_t)),
                            rec.gt_y + rng.normal(0, 0.002, len(rec.gt_t)),
                            rec.gt_yaw + rng.normal(0, 0.002, len(rec.gt_t)))
    segments = ident.build_segments([noisy], None)
    return segments.select(segments.travel >= 0.01)


def main():
    """Run the three benchmarks and print their figures."""
    segments = paper_sized()
    model = ident.build_model('icr_scales', B)
    seconds, lsq = best_of(lambda: ident.fit(model, segments), 5)
    print(f'bench_identify: paper size ({len(segments)} segments of 0.27 s, '
          f'{len(segments.dt)} encoder steps): icr_scales least squares {seconds:.3f} s '
          f'[goal < 0.5 s], {lsq.nfev} evaluations; chi {lsq.icr.chi:.4f} (true 0.5398)')

    weight, scale = lsq.heading_weight, lsq.f_scale
    for name in ('icr', 'icr_scales'):
        m = ident.build_model(name, B)
        same_cost = {'heading_weight': weight, 'f_scale': scale, 'check': False}
        t_lsq, r_lsq = best_of(lambda: ident.fit(m, segments, **same_cost), 1)
        t_de, r_de = best_of(lambda: ident.fit(m, segments, method='de', rounds=1,
                                               **same_cost), 1)
        print(f'bench_identify: {name}: least squares {t_lsq:.2f} s cost {r_lsq.cost:.6g} '
              f'({r_lsq.nfev} evaluations) | differential evolution {t_de:.2f} s cost '
              f'{r_de.cost:.6g} ({r_de.nfev} evaluations)')

    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'one_hour'
        start = time.perf_counter()
        rec = simulate(ConstantIcr(B), np.array(AURIGA), duration=3600.0, enc_rate=100.0,
                       gt_rate=10.0, seed=7, gt_phase=0.004)
        write_bag(bag, rec, 'mcap', gt_noise=(0.003, 0.003))
        size = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
        print(f'bench_identify: wrote a one-hour bag ({len(rec.enc_t)} JointState + '
              f'{len(rec.gt_t)} PoseStamped, {size:.0f} MB) in '
              f'{time.perf_counter() - start:.0f} s')
        command = [str(Path(sys.executable).parent / 'identify_icr'), str(bag),
                   '--ground-truth-topic', '/mocap/pose', '--output', str(Path(tmp) / 'out.yaml'),
                   '--sprocket-radius', '0.1', '--track-width', str(B)]
        start = time.perf_counter()
        run = subprocess.run(command, capture_output=True, text=True)
        wall = time.perf_counter() - start
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        if run.returncode != 0:
            print(run.stdout + run.stderr)
            raise SystemExit('identify_icr failed')
        fitted = [line for line in run.stdout.splitlines() if line.startswith('written ICR')]
        print(f'bench_identify: one-hour log read and fitted by identify_icr in {wall:.1f} s '
              f'[goal < 60 s], peak RSS {peak_mb:.0f} MB [goal < 1024 MB]')
        print(f'bench_identify: {fitted[0] if fitted else ""}')


if __name__ == '__main__':
    main()
