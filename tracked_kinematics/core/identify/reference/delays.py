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


IMU_DELAY_STD_LIMIT = 0.02
"""s: the largest standard error of an estimated ``imu_delay`` used as known. On the windowed
Warthog bags of ../shared/realdata the gyro is timed to 0.001-0.003 s on sand, asphalt and
gravel (-0.13 s); on ice, where the body follows the spinning wheels late, to 0.083 s at
+0.49 s (heading r 0.88 against 0.99): that is slip, not the clock."""


def imu_delay_problem(imu: DelayEstimate) -> str:
    """
    Return why the gyro's delay cannot be used as known, or '' when it can.

    A delay given is known; an estimated one when it is determined and its standard error is at
    most :data:`IMU_DELAY_STD_LIMIT`. Timed against the tracks, the gyro's delay absorbs the
    body's lag behind slipping tracks: a clock offset it is not.
    """
    if imu.uncertainty == 'given':
        return ''
    if not imu.determined:
        return f'not determined ({imu.problem})'
    if imu.std <= IMU_DELAY_STD_LIMIT:
        return ''
    heading = imu.correlation.get('heading', math.nan)
    return (f'{imu.delay:+.3f} s +- {imu.std:.3f} s (need +- {IMU_DELAY_STD_LIMIT:g} s; '
            f'heading r {heading:.2f}): the tracks slip too much to time the gyro against '
            'them')


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
