"""
What real recordings do to a simulated one: late ground truth, bursts, pieces, noise, glitches.

Each function takes a :class:`Recording` of :mod:`helpers.vehicle_sim` (exact ground truth on
the encoders' clock) and returns what a logger would have written.
"""

import numpy as np

from tracked_kinematics.core.identify import Recording


def late(rec, delay):
    """Ground truth stamped ``delay`` s after the instant it describes (stamped on receipt)."""
    return Recording(rec.enc_t, rec.left, rec.right, rec.gt_t + delay, rec.gt_x, rec.gt_y,
                     rec.gt_yaw, name=rec.name)


def bursts(rec, start, end, period=1.0, lag=0.8):
    """
    Between ``start`` and ``end`` s, one pose a ``period``, ``lag`` s later than the others.

    As a lidar mapper that falls behind during fast driving: the poses of that stretch
    arrive late and seldom (the stamps are already on the receiving clock, e.g. after
    :func:`late`).
    """
    t = rec.gt_t
    inside = (t >= start) & (t < end)
    keep = ~inside
    picks = np.flatnonzero(inside)
    if len(picks):
        step = max(1, int(round(period / np.median(np.diff(t)))))
        keep[picks[::step]] = True
    stamps = np.where(inside, t + lag, t)[keep]
    order = np.argsort(stamps, kind='stable')
    stamps = stamps[order]
    unique = np.concatenate([[True], np.diff(stamps) > 0])
    pick = np.flatnonzero(keep)[order][unique]
    return Recording(rec.enc_t, rec.left, rec.right, stamps[unique], rec.gt_x[pick],
                     rec.gt_y[pick], rec.gt_yaw[pick], name=rec.name)


def noisy(rec, position=0.05, heading=np.radians(2.0), glitches=0.0, seed=0):
    """
    Ground truth with white noise per sample, and a fraction of glitches.

    A glitch (as lidar ICP on ice gives) moves one pose by 0.5 m and 0.3 rad (standard
    deviations).
    """
    rng = np.random.default_rng(seed)
    n = len(rec.gt_t)
    x = rec.gt_x + rng.normal(0.0, position, n)
    y = rec.gt_y + rng.normal(0.0, position, n)
    yaw = rec.gt_yaw + rng.normal(0.0, heading, n)
    bad = rng.random(n) < glitches
    x[bad] += rng.normal(0.0, 0.5, bad.sum())
    y[bad] += rng.normal(0.0, 0.5, bad.sum())
    yaw[bad] += rng.normal(0.0, 0.3, bad.sum())
    return Recording(rec.enc_t, rec.left, rec.right, rec.gt_t, x, y,
                     np.angle(np.exp(1j * yaw)), name=rec.name)


def pieces(rec, length=2.0, gap=1.0, encoders_late=0.3, one=False):
    """
    Cut the recording into pieces of ``length`` s every ``length + gap`` s.

    In each piece the ground truth starts ``encoders_late`` s before the encoders. ``one``:
    a single recording with gaps in both streams, else one recording per piece.
    """
    period = length + gap
    t0 = min(rec.enc_t[0], rec.gt_t[0])
    phase_e, phase_g = (rec.enc_t - t0) % period, (rec.gt_t - t0) % period
    enc = (phase_e >= encoders_late) & (phase_e < length)
    gt = phase_g < length
    if one:
        return [Recording(rec.enc_t[enc], rec.left[enc], rec.right[enc], rec.gt_t[gt],
                          rec.gt_x[gt], rec.gt_y[gt], rec.gt_yaw[gt], name=rec.name)]
    piece_e = ((rec.enc_t - t0) // period).astype(int)
    piece_g = ((rec.gt_t - t0) // period).astype(int)
    out = []
    for k in np.unique(piece_e[enc]):
        e, g = enc & (piece_e == k), gt & (piece_g == k)
        if e.sum() >= 2 and g.sum() >= 2:
            out.append(Recording(rec.enc_t[e], rec.left[e], rec.right[e], rec.gt_t[g],
                                 rec.gt_x[g], rec.gt_y[g], rec.gt_yaw[g],
                                 name=f'{rec.name}#{k}'))
    return out
