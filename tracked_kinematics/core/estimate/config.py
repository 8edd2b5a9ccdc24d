"""Settings and outcomes of the slip-parameter EKF (:class:`.ekf.SlipEstimator`)."""

from __future__ import annotations

from dataclasses import dataclass
import math

from .._checks import require_numbers


@dataclass(frozen=True, slots=True)
class EstimatorConfig:
    """
    Noise model, windows and gates of :class:`SlipEstimator`, checked when made.

    Each is the icr_estimator parameter of the same name (docs/nodes/icr_estimator.md, "Parameters"
    and "On real pose sources", which also say which are the paper's). Units: ``pose_std_xy`` m,
    ``pose_std_yaw`` rad, ``travel_std`` m per m travelled, ``process_std`` parameter units /
    sqrt(s), windows and times s, ``prior_std`` track widths.
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

    def __post_init__(self):
        require_numbers(self, finite=('pose_delay',),
                        positive=('pose_std_xy', 'pose_std_yaw', 'initial_std', 'window',
                                  'max_window', 'min_coverage', 'prior_std', 'prior_time',
                                  'fallback_span'),
                        non_negative=('travel_std', 'process_std', 'min_window',
                                      'fallback_margin'),
                        unbounded=('prior_std',))
        for name in ('adaptive_noise', 'fallback'):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f'{name} must be true or false, got {getattr(self, name)!r}')
        if not isinstance(self.noise_memory, int) or isinstance(self.noise_memory, bool) \
                or self.noise_memory < 20:
            raise ValueError(f'noise_memory must be an integer >= 20, got '
                             f'{self.noise_memory!r}')
        if self.fallback_margin >= 1.0:
            raise ValueError(f'fallback_margin must be in [0, 1), got {self.fallback_margin!r}')
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f'gate_probability must be in (0, 1), got {self.gate_probability!r}')
        if not self.min_window <= self.window < self.max_window:
            raise ValueError(f'windows must satisfy min_window ({self.min_window}) <= window '
                             f'({self.window}) < max_window ({self.max_window})')
        if not isinstance(self.max_outliers, int) or self.max_outliers < 1:
            raise ValueError(f'max_outliers must be an integer >= 1, got {self.max_outliers!r}')
        if self.min_coverage > 1.0:
            raise ValueError(f'min_coverage must be in (0, 1], got {self.min_coverage!r}')


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
