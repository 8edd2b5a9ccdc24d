"""
Gyro-aided odometry: the names of :mod:`.gyro`, where it lives now (split in parts).

Kept so that ``tracked_kinematics.core.gyro_odometry`` still imports.
"""

from .gyro import (ENCODERS, ERROR, fit_gyro_scale, GYRO, GyroConfig, GyroOdometry, MIN_CHI,
                   NOT_A_FAULT, OK, replay, WARN)

__all__ = ['ENCODERS', 'ERROR', 'fit_gyro_scale', 'GYRO', 'GyroConfig', 'GyroOdometry',
           'MIN_CHI', 'NOT_A_FAULT', 'OK', 'replay', 'WARN']
