"""
The icr_estimator's EKF replayed over a recording, as the node would run it.

The node (docs/nodes/icr_estimator.md, ``model: icr``) starts
:class:`~tracked_kinematics.core.estimate.ekf.SlipEstimator` from the terrain file's tread
ICRs, feeds it every encoder step scaled by the file's ``scale.*`` and every pose as it
arrives, and predicts with the estimate it stands behind
(:attr:`~tracked_kinematics.core.estimate.ekf.SlipEstimator.estimate`). The replay does the
same in time order: encoder steps at their stamps, each pose at the time it arrived (its
corrected stamp plus the ground-truth delay, which the filter takes off again as
``pose_delay``). The estimate in force at a time is the one after the last event before it:
what a prediction or an odometry step starting then could have used.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from ..estimate.ekf import EstimatorConfig, SlipEstimator
from ..identify import Recording
from ..kinematics import IcrParams
from ..models import ConstantIcr


@dataclass(frozen=True)
class OnlineRun:
    """
    The estimates of one replay.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Times from which each estimate is in force, s (the first is ``-inf``).
    icr : ndarray, shape (N, 3)
        ``(y_left, y_right, x)`` in force from each time, m.
    scales : tuple of float
        The terrain file's ``(scale_left, scale_right)``, applied to the encoders.
    outcomes : dict
        How many pose measurements ended how (``updated``, ``outlier``, ...).
    noise_scale : float
        The adaptive noise factor at the end.
    trusted : float
        Fraction of the poses after which the filter's state was the estimate (the rest:
        the start values, see ``fallback``).

    """

    t: np.ndarray
    icr: np.ndarray
    scales: tuple
    outcomes: dict
    noise_scale: float
    trusted: float

    def params_at(self, times):
        """Return ``(y_left, y_right, x, scale_left, scale_right)`` in force at ``times``."""
        k = np.searchsorted(self.t, np.asarray(times, dtype=float), side='right') - 1
        icr = self.icr[np.maximum(k, 0)]
        return icr[:, 0], icr[:, 1], icr[:, 2], self.scales[0], self.scales[1]


def replay(recording: Recording, icr: IcrParams, delay: float = 0.0,
           config: EstimatorConfig | None = None) -> OnlineRun:
    """
    Run the EKF over a recording whose ground-truth stamps are corrected by ``delay``.

    Parameters
    ----------
    recording : Recording
        Ground truth on the encoders' clock (delay taken off).
    icr : IcrParams
        The terrain file: start values of the ICRs, and the encoder scales.
    delay : float
        The ground-truth delay, s: poses arrive that much after their corrected stamps.
    config : EstimatorConfig, optional
        The node's noise, windows and gates (default: its defaults); ``pose_delay`` is set
        to ``delay``.

    """
    model = ConstantIcr(icr.track_width, with_scales=False)
    config = replace(config or EstimatorConfig(), pose_delay=float(delay))
    est = SlipEstimator(model, model.from_icr(icr), config)
    rec = recording
    scale_left, scale_right = icr.scale_left, icr.scale_right
    step_t = rec.enc_t[1:]
    d_left = (scale_left * np.diff(rec.left)).tolist()
    d_right = (scale_right * np.diff(rec.right)).tolist()
    step_dt = np.diff(rec.enc_t).tolist()
    arrival = rec.gt_t + delay
    events = np.concatenate([step_t, arrival])
    order = np.argsort(events, kind='stable').tolist()
    n_steps = len(step_t)
    times = events.tolist()
    poses = np.column_stack([rec.gt_x, rec.gt_y, rec.gt_yaw]).tolist()
    changed_t, changed = [-np.inf], [est.estimate.copy()]
    outcomes: Counter = Counter()
    trusted = 0
    for e in order:
        if e < n_steps:
            outcome = est.add_step(times[e], d_left[e], d_right[e], step_dt[e])
            if outcome is None:
                continue
        else:
            outcome = est.add_pose(times[e], *poses[e - n_steps])
            trusted += est.estimate is est.p
        outcomes[outcome.status] += 1
        current = est.estimate
        if not np.array_equal(current, changed[-1]):
            changed_t.append(times[e])
            changed.append(current.copy())
    return OnlineRun(np.asarray(changed_t), np.asarray(changed), (scale_left, scale_right),
                     dict(outcomes), float(est.noise_scale),
                     trusted / max(1, len(arrival)))
