"""
Settings and outcomes of the slip-parameter EKF (:class:`.ekf.SlipEstimator`).

:class:`EstimatorConfig` holds the noise model, the windows and the gates (checked where they
enter: icr_estimator's parameters); :class:`Outcome` says what the filter did with one pose
measurement. :mod:`.ekf` explains each setting (which are the EKF paper's and which are ours).
"""

from __future__ import annotations

from dataclasses import dataclass
import math


@dataclass(frozen=True, slots=True)
class EstimatorConfig:
    """
    Noise model, windows and gates of :class:`SlipEstimator`.

    Attributes
    ----------
    pose_std_xy : float
        Standard deviation of each measured position coordinate, m.
    pose_std_yaw : float
        Standard deviation of each measured heading, rad.
    travel_std : float
        Model and encoder error per metre travelled in the window (m/m): adds
        ``(travel_std * travel)^2`` to the position variance and ``2 (travel_std *
        travel / track_width)^2`` to the heading variance of a window.
    process_std : float
        Random-walk standard deviation of each parameter, per square-root second
        (parameter units / sqrt(s)); larger follows terrain changes faster, noisier.
    initial_std : float
        Standard deviation of the initial parameters (parameter units).
    window : float
        Length of the window, s: each pose is compared with the newest accepted pose at
        least this old (the paper's "last few seconds"). Windows of consecutive poses
        overlap when poses come faster; a longer window averages the pose noise down.
    min_window : float
        Shortest window, s: a pose measurement closer than this to the previous one is
        ignored.
    max_window : float
        Poses older than this are forgotten; after a longer outage the next pose starts a
        new window without an update.
    gate_probability : float
        Chi-square probability of the innovation gate (0.9999 refuses one good window in
        10,000).
    max_outliers : int
        Consecutive gated windows after which the filter re-anchors and widens its
        covariance to ``initial_std``.
    min_coverage : float
        Fraction of a window the encoder steps must cover; less is an encoder gap.
    pose_delay : float
        Delay of the pose stamps behind the encoders, s (a pose source stamped on receipt:
        ``identify_icr``'s ``ground_truth_delay``); subtracted from every pose stamp.
    adaptive_noise : bool
        Raise ``travel_std`` to what the innovations of the last ``noise_memory`` moving
        windows show (never below the configured value).
    noise_memory : int
        Moving windows (those whose tracks travel at least a tenth of the track width) the
        adaptive noise is estimated from; it starts after 20.
    prior_std : float
        Spread of the parameters about start values taken from a terrain file, as a fraction
        of the track width (parameter units per metre of track width); ``inf`` for the
        paper's random walk. Not used when the filter starts from ideal drive.
    prior_time : float
        Memory of the prior, s: a departure from the start values that the data stop
        supporting fades in this time. With the prior, the parameters follow this
        Ornstein-Uhlenbeck process instead of the random walk of ``process_std``.
    fallback : bool
        Stand behind start values taken from a terrain file until the filter predicts the
        recent windows better (see :attr:`SlipEstimator.estimate`); not used when the
        filter starts from ideal drive.
    fallback_span : float
        Seconds of recent windows the fallback compares, s.
    fallback_margin : float
        Fraction by which the filter's recent prediction cost must be below that of the
        start values for its state to be used (0.1: 10 % lower).

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
        # Each field's range is checked where it enters (icr_estimator's parameter table);
        # the order of the windows is no single parameter's range, so it is checked here.
        if not self.min_window <= self.window < self.max_window:
            raise ValueError(f'windows must satisfy min_window ({self.min_window}) <= window '
                             f'({self.window}) < max_window ({self.max_window})')


@dataclass(frozen=True, slots=True)
class Outcome:
    """
    What :meth:`SlipEstimator.add_pose` did with a measurement.

    Attributes
    ----------
    status : str
        ``'updated'``, ``'anchored'`` (first pose, or a new anchor without update),
        ``'deferred'`` (waiting for encoder data up to its stamp), ``'short'`` (window
        below ``min_window``), or a refusal: ``'non_finite'``, ``'stale'``, ``'gap'``,
        ``'outlier'``, ``'invalid'`` (the update would make the ICRs unphysical).
    reason : str
        One line for a log, empty when updated.
    nis : float
        Normalised innovation squared of the window (NaN when none was computed).

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
