"""
Benchmark: the out-of-the-box demo (issue 7), end to end. Prints the figures; goal in brackets.

Runs the ``tracked_kinematics_demo`` console script with its defaults (180 s calibration
drive, identify_icr, four held-out paths of 60 s) three times in a fresh process in a
temporary directory, and prints the wall time of each step as the demo reports it, the
process's start-up (imports), and the total measured from outside. [total < 120 s]
"""

from pathlib import Path
import re
import subprocess
import sys
import tempfile
import time

BIN = Path(sys.executable).parent
STEP = re.compile(r'^(\d)\. (.*?)\s+(\d+\.\d) s$')


def run_once(directory):
    """Run the demo once; return the step times and the total wall time."""
    start = time.perf_counter()
    result = subprocess.run([str(BIN / 'tracked_kinematics_demo'), '--output', 'out'],
                            cwd=directory, capture_output=True, text=True, timeout=600)
    total = time.perf_counter() - start
    if result.returncode != 0:
        sys.exit(f'bench_demo: the demo failed: {result.stderr.strip()}')
    steps = {}
    for line in result.stdout.splitlines():
        match = STEP.match(line)
        if match:
            steps[int(match.group(1))] = float(match.group(3))
    return steps, total


def main():
    """Print the figures."""
    names = {1: 'simulate + write calibration bag', 2: 'identify_icr (read, fit, plot)',
             3: 'held-out paths (simulate, write, read, odometry, plot)'}
    runs = []
    for _ in range(3):
        with tempfile.TemporaryDirectory() as tmp:
            runs.append(run_once(tmp))
    print('tracked_kinematics_demo with its defaults, 3 runs (s):')
    for k, name in names.items():
        figures = ', '.join(f'{steps[k]:5.1f}' for steps, _ in runs)
        print(f'  {k}. {name:<56}{figures}')
    rest = ', '.join(f'{total - sum(steps.values()):5.1f}' for steps, total in runs)
    print(f'     {"start-up, imports, process exit":<56}{rest}')
    totals = ', '.join(f'{total:5.1f}' for _, total in runs)
    print(f'     {"total wall time [< 120 s]":<56}{totals}')


if __name__ == '__main__':
    main()
