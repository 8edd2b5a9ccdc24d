"""Timing helper shared by the benchmark scripts (not a benchmark itself)."""

import time


def best_of(func, repeats: int):
    """Return the smallest wall time of ``repeats`` calls of ``func``, and the last result."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - start)
    return min(times), result
