#!/usr/bin/env python3
"""
Check the suite and the nodes' stops under CPU load: ``make stress`` runs this.

1. Starts ``--busy`` CPU-bound processes (default: as many as the runs, ``--runs``).
2. Runs the whole test suite ``--runs`` times beside them, reruns off, and prints each
   run's closing line; the offline tools are signalled at 28 instants each there (four
   times the suite's own, ``TRACKED_KINEMATICS_STOP_SCALE=4``).
3. Stops each node's console script ``--stops`` times at random instants (SIGINT or
   SIGTERM, some signalled twice, in the first 1.5 s waiting for nothing, during the
   start-up or a 1 kHz input) and
   prints, per node, how many stops were clean and how many left a traceback, hung, or
   exited non-zero.

Exit status 0 only when every suite run passed and every stop was clean.

Examples::

    make stress                       # 2 runs beside 2 busy loops, 40 stops per node
    .venv/bin/python tools/stress.py --runs 1 --stops 10 --no-suite
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import random
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'test'))

from helpers import domains, stops  # noqa: E402 -- the test helpers, from the tree


def _busy(count: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, '-c', 'while True: pass'])
            for _ in range(count)]


def _suite(run: int) -> bool:
    started = time.monotonic()
    # Four times the suite's signal instants of every offline tool (28 per tool).
    env = {**os.environ, 'TRACKED_KINEMATICS_STOP_SCALE': '4',
           'TRACKED_KINEMATICS_ATTACKS': 'all', 'TRACKED_KINEMATICS_LONG': '1'}
    result = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:rerunfailures'],
                            cwd=ROOT, capture_output=True, text=True, env=env)
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    closing = lines[-1] if lines else '(no output)'
    failures = [line for line in lines if line.startswith(('FAILED', 'ERROR'))]
    print(f'suite run {run}: exit {result.returncode}, {closing} '
          f'({time.monotonic() - started:.0f} s)', flush=True)
    for line in failures:
        print(f'  {line}', flush=True)
    return result.returncode == 0


def _stops(count: int, seed: int) -> bool:
    rng = random.Random(seed)
    results = []
    with domains.acquire() as lease, tempfile.TemporaryDirectory() as tmp:
        env = {'ROS_DOMAIN_ID': str(lease.domain_id),
               'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
        os.environ.update(env)
        feeder = stops.Feeder(lease.domain_id)
        try:
            for k in range(count):
                for name in stops.NODES:
                    stop = stops.stop_once(name, rng, Path(tmp) / f'{name}_{k}', env=env)
                    results.append(stop)
                    if not stop.clean:
                        tail = '\n    '.join(stop.output.splitlines()[-8:])
                        print(f'  not clean: {name} {"+".join(stop.signals)} after '
                              f'{stop.delay:.2f} s (up: {stop.up}): exit {stop.status}\n'
                              f'    {tail}', flush=True)
        finally:
            feeder.close()
    print(stops.summary(results), flush=True)
    return all(stop.clean for stop in results)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split('\n\n')[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--runs', type=int, default=2, help='suite runs')
    parser.add_argument('--busy', type=int, default=None,
                        help='CPU-bound processes beside them (default: --runs)')
    parser.add_argument('--stops', type=int, default=40, help='stops per node')
    parser.add_argument('--seed', type=int, default=None, help='seed of the stop instants')
    parser.add_argument('--no-suite', action='store_true', help='only the stops')
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else random.SystemRandom().randrange(10**6)
    busy = _busy(args.runs if args.busy is None else args.busy)
    print(f'stress: {len(busy)} busy loops, {0 if args.no_suite else args.runs} suite runs, '
          f'{args.stops} stops per node (seed {seed})', flush=True)
    ok = True
    try:
        if not args.no_suite:
            for run in range(1, args.runs + 1):
                ok &= _suite(run)
        if args.stops > 0:
            ok &= _stops(args.stops, seed)
    finally:
        for process in busy:
            process.kill()
            process.wait()
    print('stress: ' + ('all clean' if ok else 'FAILURES above'), flush=True)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
