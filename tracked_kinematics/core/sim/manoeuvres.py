"""
Manoeuvre sets: commanded nominal track speeds ``(N, 2)`` (m/s) for simulated runs.

One row per command period, held, from rest to rest; random sets take a ``numpy.random.Generator``.
See docs/tools/simulate_bag.md, "Manoeuvres".
"""

from __future__ import annotations

import math

import numpy as np

MANOEUVRES = ('random', 'sweep', 'spin', 'mixed')


def _ideal_to_tracks(v, w, track_width):
    """Track speeds of an ideal differential drive for forward speed v and turn rate w."""
    half = 0.5 * track_width
    return np.column_stack([v - half * w, v + half * w])


def _limit(speeds, max_speed):
    """Scale both tracks down together where one exceeds the limit (keeps the curvature)."""
    peak = np.max(np.abs(speeds), axis=1, keepdims=True)
    return speeds * np.minimum(1.0, max_speed / np.maximum(peak, 1e-12))


def random_drive(duration: float, dt: float, max_speed: float, rng: np.random.Generator,
                 smoothing: float = 0.4) -> np.ndarray:
    """
    Manual-like driving over ``duration`` s: random joystick gestures, smoothed.

    Gestures of 1-6 s (straights, arcs, pivots, spins, stops, one in six backwards) with the outer
    track at 30-100 % of ``max_speed`` (m/s), through a first-order filter of time constant
    ``smoothing`` (s); the run ends with a stop of ``5 x smoothing``.
    """
    n = _samples(duration, dt)
    targets = np.zeros((n, 2))
    k = 0
    kinds = ('straight', 'arc', 'tight', 'pivot', 'spin', 'stop')
    weights = np.array([0.25, 0.3, 0.15, 0.1, 0.1, 0.1])
    while k < n:
        length = int(round(rng.uniform(1.0, 6.0) / dt))
        kind = kinds[rng.choice(len(kinds), p=weights)]
        outer = rng.uniform(0.3, 1.0) * max_speed
        ratio = {'straight': rng.uniform(0.95, 1.0), 'arc': rng.uniform(0.5, 0.95),
                 'tight': rng.uniform(0.0, 0.5), 'pivot': rng.uniform(-0.6, 0.0),
                 'spin': -1.0, 'stop': 0.0}[kind]
        pair = np.array([outer, ratio * outer]) if kind != 'stop' else np.zeros(2)
        if rng.uniform() < 0.5:
            pair = pair[::-1]
        if kind not in ('spin', 'stop') and rng.uniform() < 1.0 / 6.0:
            pair = -pair
        targets[k:k + length] = pair
        k += length
    # End with a stop long enough for the filter to settle (5 time constants), then at rest.
    targets[-max(1, int(round(5.0 * smoothing / dt))):] = 0.0
    a = math.exp(-dt / smoothing)
    from scipy import signal   # lazily: 0.4 s to import
    smooth = signal.lfilter([1.0 - a], [1.0, -a], targets, axis=0)
    smooth[-1] = 0.0
    return np.clip(smooth, -max_speed, max_speed)


def trapezoid(duration: float, peak: float, rate: float, dt: float) -> np.ndarray:
    """Trapezoid 0 -> ``peak`` -> 0 at ``rate`` per s over ``duration`` s (or a triangle)."""
    t = (np.arange(_samples(duration, dt)) + 0.5) * dt
    ramp = rate * np.minimum(t, duration - t)
    return np.sign(peak) * np.minimum(abs(peak), ramp)


def fink_stump_sweep(dt: float, track_width: float, max_speed: float, speeds=None,
                     curvatures=None, path_length: float = 4.0, accel: float = 5.0,
                     curvature_rate: float = 1.0, pause: float = 1.0) -> np.ndarray:
    """
    Trapezoidal speed x curvature sweep of Fink & Stump, sec. IV-B.

    Each ``(v_trav, kappa_trav)`` (m/s, 1/m) whose faster track is within ``max_speed`` gives a
    path of about ``path_length`` m with trapezoids at ``accel`` (m/s^2) and ``curvature_rate``
    (1/(m s)), tracks at ``v (1 -+ kappa B / 2)``, ``pause`` s between paths. Defaults: the paper's
    Packbot grid, speeds scaled to ``max_speed``. ValueError if no pair fits.
    """
    if speeds is None:
        speeds = np.linspace(0.25, 1.0, 16) * max_speed
    if curvatures is None:
        magnitudes = np.array([0.25, 0.5, 0.75, 1.0, 1.5, 2.0])
        curvatures = np.ravel(np.column_stack([magnitudes, -magnitudes]))
    rest = np.zeros((_samples(pause, dt), 2))
    pieces = []
    for v in np.asarray(speeds, float):
        for kappa in np.asarray(curvatures, float):
            if v * (1.0 + 0.5 * abs(kappa) * track_width) > max_speed * (1.0 + 1e-9):
                continue
            duration = path_length / v + v / accel
            v_t = trapezoid(duration, v, accel, dt)
            k_t = trapezoid(duration, kappa, curvature_rate, dt)
            pieces += [_ideal_to_tracks(v_t, v_t * k_t, track_width), rest]
    if not pieces:
        raise ValueError(f'no (speed, curvature) pair of the sweep keeps both tracks within '
                         f'{max_speed} m/s')
    return np.vstack([rest] + pieces)


def spin_in_place(dt: float, max_speed: float, levels=(0.25, 0.5, 0.75, 1.0),
                  hold: float = 4.0, pause: float = 1.0) -> np.ndarray:
    """
    Spins in place: ``(-V, V)`` then ``(V, -V)`` held ``hold`` s per level (Martinez eq. 16).

    ``levels`` are fractions of ``max_speed`` (m/s); ``pause`` s of rest between spins.
    """
    rest = np.zeros((_samples(pause, dt), 2))
    pieces = [rest]
    for level in levels:
        speed = float(level) * max_speed
        for sign in (1.0, -1.0):
            pieces += [np.tile([-sign * speed, sign * speed], (_samples(hold, dt), 1)), rest]
    return np.vstack(pieces)


def mixed(duration: float, dt: float, track_width: float, max_speed: float,
          rng: np.random.Generator) -> np.ndarray:
    """Mix random driving (45 %), sweep paths (40 %) and spins (15 %), for identification."""
    n = _samples(duration, dt)
    sweep = fink_stump_sweep(dt, track_width, max_speed, pause=0.5)
    # Split the sweep into its trajectories at the rests.
    moving = np.any(sweep != 0.0, axis=1)
    edges = np.flatnonzero(np.diff(moving.astype(int)))
    items = [sweep[a + 1:b + 1] for a, b in zip(edges[::2], edges[1::2])]
    rest = np.zeros((_samples(0.5, dt), 2))
    pieces, total = [], 0
    while total < n:
        pick = rng.uniform()
        if pick < 0.45:
            block = random_drive(20.0, dt, max_speed, rng)
        elif pick < 0.85:
            block = items[rng.integers(len(items))]
        else:
            speed = rng.uniform(0.3, 1.0) * max_speed * rng.choice([-1.0, 1.0])
            block = np.tile([-speed, speed], (_samples(rng.uniform(2.0, 5.0), dt), 1))
        pieces += [block, rest]
        total += len(block) + len(rest)
    out = np.vstack(pieces)[:n]
    out[-len(rest):] = 0.0
    return out


def manoeuvre(name: str, duration: float, dt: float, track_width: float, max_speed: float,
              rng: np.random.Generator) -> np.ndarray:
    """
    Commands of a named set (``'random'``, ``'sweep'``, ``'spin'``, ``'mixed'``) for ``duration``.

    Fixed sequences are repeated (Fink & Stump ran every trajectory twice) or cut to fit.
    """
    n = _samples(duration, dt)
    if name == 'random':
        return random_drive(duration, dt, max_speed, rng)
    if name == 'mixed':
        return mixed(duration, dt, track_width, max_speed, rng)
    if name == 'sweep':
        cycle = fink_stump_sweep(dt, track_width, max_speed)
    elif name == 'spin':
        cycle = spin_in_place(dt, max_speed)
    else:
        raise ValueError(f'unknown manoeuvre set {name!r}; choose one of {", ".join(MANOEUVRES)}')
    out = np.tile(cycle, (-(-n // len(cycle)), 1))[:n]
    # End at rest even when the cut falls inside a trajectory.
    out[-min(n, _samples(1.0, dt)):] = 0.0
    return out


def _samples(duration, dt) -> int:
    duration, dt = float(duration), float(dt)
    if not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f'duration must be a finite number > 0 s, got {duration!r}')
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f'dt must be a finite number > 0 s, got {dt!r}')
    return max(1, int(round(duration / dt)))
