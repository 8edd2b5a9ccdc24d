"""
The delays of the gyro and the pose stamps behind the encoders (step 2 of the calibration).

Both by :func:`..delay.estimate_delay` (heading channel; the gyro integrated); ``imu_delay`` > 0
means the gyro is stamped late.
"""

from __future__ import annotations

import math

import numpy as np

from .headings import gyro_heading
from ..delay import DelayEstimate, estimate_delay, fixed_delay
from ...integration import wrap_angle
from ...recording import Recording


def _delay_of_gyro(rec_list, imu_delay):
    """Estimate (or take) the gyro's delay behind the encoders, as the pose delay is."""
    if not isinstance(imu_delay, str):
        return fixed_delay(float(imu_delay or 0.0))
    if imu_delay != 'auto':
        raise ValueError(f"imu_delay must be seconds or 'auto', got {imu_delay!r}")
    fake = []
    for rec in rec_list:
        t, heading = gyro_heading(rec, 0.0)
        # Headings every ~0.1 s: the estimator regresses increments between samples.
        step = max(1, int(round(0.1 / max(float(np.median(np.diff(t))), 1e-6))))
        t, heading = t[::step], heading[::step]
        zeros = np.zeros(t.size)
        fake.append(Recording(rec.enc_t, rec.left, rec.right, t, zeros, zeros,
                              wrap_angle(heading), name=rec.name))
    return estimate_delay(fake, channels=('heading',))


def _delay_of_pose(rec_list, pose_delay):
    """Estimate (or take) the pose's delay behind the encoders (:func:`..delay.estimate_delay`)."""
    if not isinstance(pose_delay, str):
        return fixed_delay(float(pose_delay or 0.0))
    if pose_delay != 'auto':
        raise ValueError(f"pose_delay must be seconds or 'auto', got {pose_delay!r}")
    return estimate_delay(rec_list)


def sensor_delays(recs, imu_delay, pose_delay):
    """
    Return the delays of the gyro and of the pose behind the encoders, estimated or given.

    Parameters
    ----------
    recs : list of Recording
        The recordings; those with a gyro give its delay, those with a pose the pose's.
    imu_delay, pose_delay : float or 'auto'
        s, or 'auto' to estimate (:func:`_delay_of_gyro`, :func:`_delay_of_pose`).

    Returns
    -------
    imu, pose : DelayEstimate
        Zero delays for a reference that no recording has.

    """
    gyro_recs = [r for r in recs if r.gyro_t is not None]
    imu = _delay_of_gyro(gyro_recs, imu_delay) if gyro_recs else fixed_delay(0.0)
    pose_recs = [r for r in recs if r.pose is not None]
    pose = _delay_of_pose(pose_recs, pose_delay) if pose_recs else fixed_delay(0.0)
    return imu, pose


def delay_report(d: DelayEstimate) -> dict:
    """Return a delay as the report gives it (JSON-ready; no infinite standard error)."""
    std = float(d.std)
    return {'delay': float(d.delay), 'std': std if math.isfinite(std) else None,
            'determined': bool(d.determined), 'problem': d.problem,
            'uncertainty': d.uncertainty}
