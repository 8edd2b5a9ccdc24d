"""
The icr_estimator's EKF replayed over a recording, as the node would run it.

Encoder steps (scaled by the terrain file) at their stamps, each pose when it arrived; the estimate
in force at a time is the one after the last event before it.
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
    The estimates of one replay: ``icr`` (N, 3; m) in force from each ``t`` (s; first -inf).

    ``trusted`` is the fraction of poses after which the filter's state (not the start values) was
    the estimate.
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
    Run the EKF over a recording from the terrain file ``icr``; poses arrive ``delay`` s late.

    ``config`` defaults to the node's; its ``pose_delay`` is set to ``delay``.
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
