"""
Identification without a ground-truth pose: a gyro for heading, GNSS or a straight for distance.

:func:`fit_from_reference` (plain arrays, one recording) and :func:`fit_recordings` return a
:class:`ReferenceFit` with what the data determine and what is held at the base. The model (turn
gain, veer, gyro bias, distance scale) and what each sensor sees: docs/tools/identify_icr.md, "No
ground truth? Use the IMU".
"""

from .calibration import fit_from_reference, fit_recordings
from .heading_fit import CHI_REL_STD_LIMIT, HUBER_K, MIN_TURN, RATIO_STD_LIMIT
from .headings import heading_reference, MAX_STRAIGHT_TURN, MIN_MOVING_SEGMENTS
from .positions import DISTANCE_STD_LIMIT, POSITION_WINDOW, X_STD_LIMIT
from .recordings import (
    check_gyro, check_saturation, QUANTITIES, ReferenceFit, SATURATION_SHARE)

__all__ = [
    'CHI_REL_STD_LIMIT', 'DISTANCE_STD_LIMIT', 'HUBER_K', 'MAX_STRAIGHT_TURN',
    'MIN_MOVING_SEGMENTS', 'MIN_TURN', 'POSITION_WINDOW', 'QUANTITIES', 'RATIO_STD_LIMIT',
    'ReferenceFit', 'SATURATION_SHARE', 'X_STD_LIMIT', 'check_gyro',
    'check_saturation', 'fit_from_reference', 'fit_recordings', 'heading_reference',
]
