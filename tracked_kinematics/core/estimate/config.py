"""Settings and outcomes of the slip-parameter EKF (:class:`.ekf.SlipEstimator`)."""

from __future__ import annotations

from dataclasses import dataclass
import math


@dataclass(frozen=True, slots=True)
class EstimatorConfig:
    """
    Noise model, windows and gates of :class:`SlipEstimator`, checked when made.

    Each is the icr_estimator parameter of the same name (docs/nodes/icr_estimator.md, "Parameters"
    and "On real pose sources", which also say which are the paper's). Units: ``pose_std_xy`` m,
    ``pose_std_yaw`` rad, ``travel_std`` m per m travelled, ``process_std`` parameter units /
    sqrt(s), windows and times s, ``prior_std`` track widths. ``track_noise`` (m^2/m),
    ``turn_noise`` (rad^2/rad) and ``slip_noise`` (m^2/rad) are the terrain file's noise model
    (``covariance.k_left``/``k_right``, ``covariance.turn``, ``covariance.slip``,
    :mod:`..noise_model`), added to a window's model error (0: none, as before).
    """

    pose_std_xy: float = 0.02
    pose_std_yaw: float = 0.01
    travel_std: float = 0.01
    process_std: float = 0.1
    initial_std: float = 1.0
    window: float = 1.0
    min_window: float = 0.05
    max_window: float = 5.0
    gate_probability: float = 0.9999
    max_outliers: int = 3
    min_coverage: float = 0.9
    pose_delay: float = 0.0
    adaptive_noise: bool = True
    noise_memory: int = 300
    prior_std: float = 0.05
    prior_time: float = 5.0
    fallback: bool = True
    fallback_span: float = 30.0
    fallback_margin: float = 0.1
    track_noise: float = 0.0
    turn_noise: float = 0.0
    slip_noise: float = 0.0

    def __post_init__(self):
        # Each field's range is checked where it enters (icr_estimator's parameter table);
        # the order of the windows is no single parameter's range, so it is checked here.
        if not self.min_window <= self.window < self.max_window:
            raise ValueError(f'windows must satisfy min_window ({self.min_window}) <= window '
                             f'({self.window}) < max_window ({self.max_window})')


@dataclass(frozen=True, slots=True)
class Outcome:
    """
    What :meth:`SlipEstimator.add_pose` did with a measurement.

    ``status`` is ``'updated'``, ``'anchored'``, ``'deferred'``, ``'short'`` or a refusal
    (``'non_finite'``, ``'stale'``, ``'gap'``, ``'outlier'``, ``'invalid'``); ``reason`` one log
    line; ``nis`` the normalised innovation squared (NaN when none).
    """

    status: str
    reason: str = ''
    nis: float = math.nan

    @property
    def accepted(self) -> bool:
        """Tell whether the measurement updated the parameters."""
        return self.status == 'updated'

    @property
    def refused(self) -> bool:
        """Tell whether the measurement was judged bad (it did not touch the state)."""
        return self.status in ('non_finite', 'stale', 'gap', 'outlier', 'invalid')
