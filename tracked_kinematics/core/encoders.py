"""
From encoder readings to nominal track travel, for the three input kinds drivers publish.

- joint positions (rad, cumulative): exact travel ``radius * delta angle``;
- joint or track velocities: travel by the trapezoidal rule between samples;
- tick counters (integers that wrap around at 2^bits): unwrapped increments.

Everything is vectorised over samples; a node calls the same functions on two samples.
Travel is *nominal* (encoder) travel: the scale corrections of the kinematic model turn it
into true travel (Martinez eqs. 18-21).
"""

from __future__ import annotations

import numpy as np


def mean_over_joints(values) -> np.ndarray:
    """
    Average the joints of one side (several sprockets or wheels per track).

    Parameters
    ----------
    values : array_like, shape (N, J) or (N,)
        One column per joint of the side.

    Returns
    -------
    ndarray, shape (N,)

    """
    values = np.asarray(values, dtype=float)
    return values if values.ndim == 1 else values.mean(axis=-1)


def travel_from_positions(positions, radius: float) -> np.ndarray:
    """
    Nominal track travel between consecutive joint positions.

    Parameters
    ----------
    positions : array_like, shape (N,)
        Cumulative sprocket angle, rad.
    radius : float
        Sprocket radius, m.

    Returns
    -------
    ndarray, shape (N - 1,)
        Travel over each interval, m.

    """
    return np.diff(np.asarray(positions, dtype=float)) * radius


def travel_from_velocities(velocities, stamps, scale: float = 1.0) -> np.ndarray:
    """
    Nominal track travel from sampled speeds, by the trapezoidal rule.

    Parameters
    ----------
    velocities : array_like, shape (N,)
        Joint angular velocities (rad/s, with ``scale`` = sprocket radius) or track speeds
        (m/s, with ``scale`` = 1).
    stamps : array_like, shape (N,)
        Sample times, s.
    scale : float
        Factor from the velocity unit to m/s.

    Returns
    -------
    ndarray, shape (N - 1,)
        Travel over each interval, m.

    """
    velocities = np.asarray(velocities, dtype=float)
    dt = np.diff(np.asarray(stamps, dtype=float))
    return 0.5 * (velocities[1:] + velocities[:-1]) * dt * scale


def counter_increments(counts, bits: int) -> np.ndarray:
    """
    Increments of a wrapping tick counter.

    The counter is taken to be a ``bits``-bit integer (signed or unsigned, the increments
    are the same) that wraps around; any increment is read as the smallest in magnitude,
    so a counter must be sampled at least twice per half range.

    Parameters
    ----------
    counts : array_like of int, shape (N,)
        Raw counter values.
    bits : int
        Counter width (32 for std_msgs/Int32, 64 for Int64).

    Returns
    -------
    ndarray of int64, shape (N - 1,)

    """
    counts = np.asarray(counts)
    if bits >= 64:
        # Wrapping int64 arithmetic gives the modular difference directly.
        with np.errstate(over='ignore'):
            return np.diff(counts.astype(np.int64))
    modulus = 1 << bits
    half = 1 << (bits - 1)
    diff = np.diff(counts.astype(np.int64))
    return (diff + half) % modulus - half


def travel_from_ticks(tick_increments, ticks_per_revolution: float, radius: float) -> np.ndarray:
    """
    Nominal track travel of tick increments: ``ticks / ticks_per_rev * 2 pi * radius``.

    Parameters
    ----------
    tick_increments : array_like
        Counter increments (:func:`counter_increments`).
    ticks_per_revolution : float
        Ticks per sprocket revolution (after any gearing).
    radius : float
        Sprocket radius, m.

    Returns
    -------
    ndarray
        Travel, m.

    """
    return np.asarray(tick_increments, dtype=float) * (2.0 * np.pi * radius
                                                       / ticks_per_revolution)
