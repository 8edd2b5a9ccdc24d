"""
Delay of the ground-truth stamps behind the encoders, estimated without a motion model.

A pose source stamped on receipt (lidar ICP, a localiser's output logged as it arrives) is
late: the pose stamped ``t`` is where the vehicle was at ``t - delay``. Compared at face
value with the encoders, every window of ground truth is matched with encoder travel
``delay`` s too late, which inflates every error measured against it (issue 16).

The estimate needs no model of the vehicle: over short spans (``span``, 0.5 s) of ground
truth, the heading change and the forward displacement move with the ideal heading change
``(d_right - d_left) / B`` and the mean travel ``(d_left + d_right) / 2`` of the encoders
over the same span, whatever the slip (a scale and an offset do not change a correlation).
For every candidate delay the encoder spans are shifted, and the delay of the highest
correlation is taken, in blocks of ``block`` seconds (the latency of a mapper changes as it
falls behind and catches up), for the heading and the forward motion separately wherever
the block turns or changes speed; the estimate is the median of the blocks', its standard
error ``1.4826 MAD / sqrt(n)``. Ground-truth jumps (a step longer than 0.5 m plus the
fastest track's travel) are left out.

This is our method, not a paper's; on ../shared/realdata it finds 0.09, 0.28, 0.19 and 0.19 s
(Husky wet grass, the three Warthog runs) against the 0.11, 0.26, 0.24, 0.19 s of that
directory's README (a gyro-based estimate where there is a gyro). It is a stand-in behind
one function, :func:`estimate_delay`, for identify_icr's estimator (issue 16) to replace.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ExcitationError
from ..identify import Recording

JUMP = 0.5
"""A ground-truth step longer than this (m) plus the fastest track's travel is a jump."""


@dataclass(frozen=True)
class DelayEstimate:
    """
    The delay of the ground-truth stamps behind the encoders.

    Attributes
    ----------
    seconds : float
        Delay, s (> 0: the ground truth is late; subtract it from its stamps).
    std : float
        Standard error, s.
    blocks : int
        Block estimates the median was taken over.
    method : str
        How it was found, for reports.

    """

    seconds: float
    std: float
    blocks: int
    method: str = 'correlation of ground-truth heading and forward increments with encoders'


def shift_ground_truth(recording: Recording, delay: float) -> Recording:
    """Return the recording with ``delay`` s taken off its ground-truth stamps."""
    if delay == 0.0:
        return recording
    return Recording(recording.enc_t, recording.left, recording.right,
                     recording.gt_t - float(delay), recording.gt_x, recording.gt_y,
                     recording.gt_yaw, recording.name)


def _correlations(signal, t, i, j, enc_t, cumulative, delays):
    """Correlation of ``signal`` (per span) with the encoder spans at every delay."""
    shifted = np.interp(t[np.concatenate([i, j])][None, :] - delays[:, None], enc_t,
                        cumulative)
    encoder = shifted[:, len(i):] - shifted[:, :len(i)]
    g = signal - signal.mean()
    e = encoder - encoder.mean(axis=1, keepdims=True)
    norm = np.sqrt((e ** 2).sum(axis=1) * (g ** 2).sum())
    return np.divide(e @ g, norm, out=np.zeros(len(delays)), where=norm > 0)


def _peak(values, delays) -> float:
    """Delay of the highest value, refined by a parabola through its neighbours."""
    k = int(np.argmax(values))
    if 0 < k < len(values) - 1:
        a, b, c = values[k - 1:k + 2]
        curvature = a - 2.0 * b + c
        if curvature < 0.0:
            return float(delays[k] + 0.5 * (a - c) / curvature * (delays[1] - delays[0]))
    return float(delays[k])


def estimate_delay(recording: Recording, track_width: float, *, low: float = -0.3,
                   high: float = 1.0, step: float = 0.005, span: float = 0.5,
                   block: float = 20.0) -> DelayEstimate:
    """
    Estimate the delay of a recording's ground-truth stamps behind its encoders.

    Parameters
    ----------
    recording : Recording
        Encoders and ground truth on one clock.
    track_width : float
        m (the ideal heading change of the encoders; its value does not matter).
    low, high, step : float
        Delays searched, s.
    span : float
        Ground-truth spans compared, s (from each sample to the first one this much later).
    block : float
        Length of the blocks estimated separately, s.

    Raises
    ------
    ExcitationError
        When no block turns or changes speed enough to show a delay.

    """
    rec = recording
    # Ground truth whose shifted spans stay on the encoders for every delay searched.
    inside = (rec.gt_t >= rec.enc_t[0] + high) & (rec.gt_t <= rec.enc_t[-1] + low)
    t = rec.gt_t[inside]
    yaw = np.unwrap(rec.gt_yaw[inside])
    x, y = rec.gt_x[inside], rec.gt_y[inside]
    j = np.searchsorted(t, t + span)
    i = np.flatnonzero(j < len(t))
    j = j[i]
    heading = (rec.right - rec.left) / track_width
    travel = 0.5 * (rec.left + rec.right)
    d_left = np.interp(t[j], rec.enc_t, rec.left) - np.interp(t[i], rec.enc_t, rec.left)
    d_right = np.interp(t[j], rec.enc_t, rec.right) - np.interp(t[i], rec.enc_t, rec.right)
    step_length = np.hypot(x[j] - x[i], y[j] - y[i])
    ok = ((t[j] - t[i]) <= 2.0 * span) & (
        step_length <= JUMP + np.maximum(np.abs(d_left), np.abs(d_right)))
    i, j = i[ok], j[ok]
    turn = yaw[j] - yaw[i]
    c, s = np.cos(yaw[i]), np.sin(yaw[i])
    forward = c * (x[j] - x[i]) + s * (y[j] - y[i])
    delays = np.arange(low, high + 0.5 * step, step)
    found = []
    if len(i):
        for start in np.arange(t[i[0]], t[i[-1]] + 1e-9, block):
            sel = (t[i] >= start) & (t[i] < start + block)
            if np.count_nonzero(sel) < 20:
                continue
            for signal, cumulative, spread in ((turn, heading, 0.02), (forward, travel, 0.02)):
                if np.std(signal[sel]) < spread:
                    continue
                found.append(_peak(_correlations(signal[sel], t, i[sel], j[sel], rec.enc_t,
                                                 cumulative, delays), delays))
    if not found:
        raise ExcitationError(
            f'{rec.name or "recording"}: too little turning or change of speed to estimate '
            'the ground-truth delay; give it in seconds (--ground-truth-delay)')
    found = np.array(found)
    median = float(np.median(found))
    mad = float(np.median(np.abs(found - median)))
    std = max(1.4826 * mad / np.sqrt(len(found)), step)
    return DelayEstimate(median, float(std), len(found))
