"""
How the gyro is read, trusted and checked: :class:`GyroConfig` and the plausibility limits.

The limits of a ground vehicle that set the default gates (docs/nodes/odometry_node.md,
"Plausibility gates"): no tracked or skid-steer robot turns faster than
:data:`PLAUSIBLE_YAW_RATE` (a pivot at 2 m/s of track speed on a 0.4-m track width is 10 rad/s),
and none changes its yaw rate by more than :data:`PLAUSIBLE_RATE_JUMP` between two samples
(a yaw acceleration of 100 rad/s^2, three times what a friction coefficient of 1 allows a
0.6-m robot, over 50 ms, a 20-Hz IMU's period).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from .._checks import require_numbers

GYRO = 'gyro'
ENCODERS = 'encoders'

OK = 'ok'
WARN = 'warn'
ERROR = 'error'

#: rad/s: the default ``saturation``: beyond any ground vehicle's yaw rate.
PLAUSIBLE_YAW_RATE = 10.0

#: rad/s: the default ``max_jump``: beyond any change of a ground vehicle's yaw rate
#: between two samples of a 20-Hz IMU.
PLAUSIBLE_RATE_JUMP = 5.0

#: s: sums of step durations are compared with their thresholds this much early, so that
#: regular steps whose durations differ in the last bit (a node's ``ns * 1e-9`` against a
#: replay's ``t1 - t0``) cross them at the same step.
SUM_TOLERANCE = 1e-9


@dataclass(frozen=True, slots=True)
class GyroConfig:
    """
    How the gyro is read, trusted and checked.

    Attributes
    ----------
    imu_delay : float
        s, the gyro's stamps behind the encoders' (identify_icr's ``imu_delay``).
    gyro_scale : float
        Measured rate over true rate.
    gyro_bias : float
        rad/s, the bias before anything is measured (the terrain file's ``gyro_bias``).
    gyro_bias_sigma : float
        rad/s, the uncertainty of ``gyro_bias`` (1 sigma); 0: no prior, the bias unknown
        until a standstill or the drive measures it.
    gyro_noise : float
        rad/s/sqrt(Hz): white rate noise, until standstills have measured it.
    measure_noise : bool
        Measure the noise density at standstill and use it instead of ``gyro_noise``.
    scale_std : float
        Relative uncertainty of the gyro's scale (1 sigma).
    model_yaw_rel_std : float
        Relative error of the model's heading increments in turns (slip), 1 sigma.
    model_yaw_var_per_m : float
        rad^2 per metre travelled: the model's heading error on straights (veer).
    bias_time : float
        s: the bias may drift by the noise of a standstill this long (its memory).
    still_speed : float
        m/s, track speeds below which the tracks stand still.
    still_time : float
        s of standstill before the bias is learnt (the robot settles).
    timeout : float
        s without a gyro sample (beyond a positive ``imu_delay``) after which it is stale.
    saturation : float
        rad/s, readings at or beyond are implausible (inf: none).
    max_jump : float
        rad/s, largest plausible change between consecutive samples (inf: any).
    recover_time : float
        s of healthy samples before the gyro is used again.
    adapt : bool
        Adapt the ICR spread online.
    adapt_turn : float
        rad turned over which the adaptation forgets (its memory, in turning).
    adapt_segment : float
        s, the gyro and the tracks are compared over segments this long.
    adapt_prior : float
        Relative uncertainty (1 sigma) of the file's turn gain ``1 / (y_left - y_right)``.
    bias_std : float
        rad/s: the gyro is used once the bias is known to this (1 sigma), or sooner where
        the tracks' measured heading error outweighs the bias's (``GyroOdometry.bias_known``).
    bias_horizon : float
        s over which a bias error counts in the fusion's weight (the odometry's horizon).

    """

    imu_delay: float = 0.0
    gyro_scale: float = 1.0
    gyro_bias: float = 0.0
    gyro_bias_sigma: float = 0.0
    gyro_noise: float = 0.01
    measure_noise: bool = True
    scale_std: float = 0.01
    model_yaw_rel_std: float = 0.1
    model_yaw_var_per_m: float = 1e-4
    bias_time: float = 60.0
    still_speed: float = 0.005
    still_time: float = 0.3
    timeout: float = 0.5
    saturation: float = PLAUSIBLE_YAW_RATE
    max_jump: float = PLAUSIBLE_RATE_JUMP
    recover_time: float = 0.5
    adapt: bool = False
    adapt_turn: float = 30.0
    adapt_segment: float = 1.0
    adapt_prior: float = 0.3
    bias_std: float = 0.03
    bias_horizon: float = 10.0

    def __post_init__(self):
        require_numbers(self, finite=('imu_delay', 'gyro_bias'),
                        positive=('gyro_scale', 'bias_time', 'bias_std', 'timeout', 'adapt_turn',
                                  'adapt_segment', 'saturation', 'max_jump', 'adapt_prior',
                                  'bias_horizon'),
                        non_negative=('gyro_noise', 'gyro_bias_sigma', 'scale_std',
                                      'model_yaw_rel_std', 'model_yaw_var_per_m', 'still_speed',
                                      'still_time', 'recover_time'),
                        unbounded=('saturation', 'max_jump'))
        for name in ('adapt', 'measure_noise'):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f'{name} must be a bool, got {getattr(self, name)!r}')
        if abs(self.imu_delay) > 60.0:
            raise ValueError(f'imu_delay must be within 60 s, got {self.imu_delay!r}')


def time_limit(config: GyroConfig) -> float:
    """Return s: a gyro stamp this far from the encoders' time is on another clock."""
    return max(5.0, 4.0 * (config.timeout + abs(config.imu_delay)))


def finite_square(x: float) -> float:
    """Return ``x * x``, inf where it overflows (``**`` raises OverflowError on floats)."""
    return x * x if math.isfinite(x) else math.inf
