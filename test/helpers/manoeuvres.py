"""Scripted manoeuvres the odometry tests drive, in the core and through the node alike."""

import numpy as np

MANOEUVRES = ('straight', 'spin', 'turn', 's_curve')


def track_speeds(name, tau, period, swing):
    """
    Return the track speeds (m/s) of a scripted manoeuvre at the times ``tau`` (s).

    ``straight`` (0.5 m/s), ``spin`` (-0.4 / 0.4 m/s), ``turn`` (0.2 / 0.6 m/s), or the
    S-curve (any other name): about 0.4 m/s, the turn rate following a sine of ``period``
    seconds, ``swing`` m/s each side.
    """
    if name == 'straight':
        return np.full(tau.size, 0.5), np.full(tau.size, 0.5)
    if name == 'spin':
        return np.full(tau.size, -0.4), np.full(tau.size, 0.4)
    if name == 'turn':
        return np.full(tau.size, 0.2), np.full(tau.size, 0.6)
    wave = swing * np.sin(2 * np.pi * tau / period)
    return 0.4 - wave, 0.4 + wave
