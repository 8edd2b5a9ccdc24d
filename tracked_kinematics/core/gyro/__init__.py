"""
Gyro-aided odometry, in parts a reader can hold.

:mod:`.gyro_config` how the gyro is read (:class:`GyroConfig`, the plausibility limits);
:mod:`.samples` the samples on the encoders' clock (gates, stamp order, a bounded buffer);
:mod:`.bias` the bias and turn gain against the tracks, and the noise density;
:mod:`.agreement` whether the gyro sees the tracks' turns (sign, scale);
:mod:`.pose_bias` the bias's share of the pose covariance; :mod:`.fusion` the odometry
(:class:`GyroOdometry`); :mod:`.replay` a recording through it.
"""

from .agreement import AgreementCheck
from .bias import TurnBias
from .fusion import GyroOdometry, MIN_CHI, NOT_A_FAULT
from .gyro_config import (ENCODERS, ERROR, GYRO, GyroConfig, OK, PLAUSIBLE_RATE_JUMP,
                          PLAUSIBLE_YAW_RATE, WARN)
from .replay import fit_gyro_scale, replay

__all__ = ['AgreementCheck', 'ENCODERS', 'ERROR', 'fit_gyro_scale', 'GYRO', 'GyroConfig',
           'GyroOdometry', 'MIN_CHI', 'NOT_A_FAULT', 'OK', 'PLAUSIBLE_RATE_JUMP',
           'PLAUSIBLE_YAW_RATE', 'replay', 'TurnBias', 'WARN']
