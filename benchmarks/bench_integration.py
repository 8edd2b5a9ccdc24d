"""
Benchmark: odometry over 1,000,000 encoder samples through the ICR model.

From cumulative joint positions (what JointState carries) to poses: differences, scale
correction, forward kinematics, exact arc integration. Goal (issue 3): under 0.2 s.
Prints the best and median of several runs, in seconds.
"""

import statistics
import time

import numpy as np

from tracked_kinematics.core.integration import integrate
from tracked_kinematics.core.kinematics import forward, IcrParams, true_speeds

N = 1_000_000
REPEATS = 7


def odometry(pos_left, pos_right, radius, icr):
    """Poses after each encoder sample from cumulative sprocket angles."""
    d_left, d_right = true_speeds(np.diff(pos_left) * radius, np.diff(pos_right) * radius, icr)
    return integrate(*forward(d_left, d_right, icr))


def main():
    """Time the pipeline and print the figures."""
    rng = np.random.default_rng(0)
    rate = 100.0
    # Sprocket speeds of a random manoeuvring vehicle, rad/s, integrated to positions.
    omega = np.cumsum(rng.normal(0.0, 0.05, size=(2, N)), axis=1).clip(-10, 10)
    pos_left, pos_right = np.cumsum(omega / rate, axis=1)
    icr = IcrParams(0.42, 0.353, -0.425, 0.032, 1.0072, 1.0275)
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        x, y, theta = odometry(pos_left, pos_right, 0.1, icr)
        times.append(time.perf_counter() - start)
    assert np.all(np.isfinite(x[-1:]))
    print(f'bench_integration: {N:,} encoder samples -> poses: best {min(times):.3f} s, '
          f'median {statistics.median(times):.3f} s ({N / min(times) / 1e6:.1f} M samples/s); '
          'goal < 0.2 s')


if __name__ == '__main__':
    main()
