"""
Whether the data can identify a model: enough motion, turning and straight driving.

Martinez et al. (2005), sec. 4.2, log paths "in which the vehicle is subject to diverse
rotational and translational speeds": turning identifies the tread ICRs and any turn-rate
parameter, straight driving the encoder scales (eqs. 20-21) and the forward-speed
parameters. :func:`check_excitation` refuses data that lack either before the fit;
:func:`.fitting.check_identified` checks the fit's own standard errors after it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .segments import Segments
from ..errors import ExcitationError
from ..models import MotionModel

# Parameters that need turning, and those that need straight driving, to be identified.
_TURNING_PARAMS = {'alpha', 'y_left', 'y_right', 'x', 'p1', 'p2', 'p3', 'p4', 'p5', 'p6',
                   'alpha2', 'alpha3', 'alpha5', 'alpha6', 'alpha8', 'alpha9',
                   'wheel_separation_multiplier'}
_STRAIGHT_PARAMS = {'scale_left', 'scale_right', 'alpha1', 'alpha4', 'alpha7',
                    'left_wheel_radius_multiplier', 'right_wheel_radius_multiplier'}
# ROS names of the parameters, for messages.
_ROS_NAMES = {'y_left': 'icr.y_left', 'y_right': 'icr.y_right', 'x': 'icr.x',
              'scale_left': 'scale.left', 'scale_right': 'scale.right', 'alpha': 'chi'}


@dataclass(frozen=True)
class Excitation:
    """
    How much the data move, turn and drive straight.

    Attributes
    ----------
    segments, moving : int
        Segments, and those whose tracks travel at least ``min_travel``.
    distance : float
        Ground-truth distance over moving segments, m.
    turning : float
        Sum of absolute ground-truth heading changes over moving segments, rad.
    straight : float
        Ground-truth distance over moving segments that are nearly straight (turning
        radius above 5 m), m.

    """

    segments: int
    moving: int
    distance: float
    turning: float
    straight: float

    @classmethod
    def of(cls, segments: Segments, min_travel: float):
        """Measure ``segments``."""
        moving = segments.travel >= min_travel
        dist = np.hypot(segments.truth[:, 0], segments.truth[:, 1])[moving]
        turn = np.abs(segments.truth[:, 2])[moving]
        straight = turn <= 0.2 * dist
        return cls(len(segments), int(moving.sum()), float(dist.sum()), float(turn.sum()),
                   float(dist[straight].sum()))


MIN_MOVING_SEGMENTS = 10
MIN_TURNING = 1.0      # rad, summed over moving segments
MIN_STRAIGHT = 1.0     # m of nearly straight driving


def _ros_names(names):
    return ', '.join(_ROS_NAMES.get(n, n) for n in names)


def check_excitation(model: MotionModel, excitation: Excitation) -> None:
    """
    Raise :class:`ExcitationError` when the data cannot identify the model's parameters.

    Turning identifies the ICRs (and any turn-rate parameter); straight driving identifies
    the encoder scales (the forward-speed parameters). The thresholds are deliberately low
    (:data:`MIN_TURNING` rad in total, :data:`MIN_STRAIGHT` m): the fit's own parameter
    uncertainty is checked afterwards (:func:`.fitting.fit`).
    """
    if excitation.moving < MIN_MOVING_SEGMENTS:
        raise ExcitationError(
            f'too little motion: {excitation.moving} of {excitation.segments} segments move '
            f'(need {MIN_MOVING_SEGMENTS}); drive longer, or check the encoder topic and '
            'sprocket radius')
    turning = [n for n in model.param_names if n in _TURNING_PARAMS]
    if turning and excitation.turning < MIN_TURNING:
        raise ExcitationError(
            f'too little turning to identify {_ros_names(turning)}: the data turn '
            f'{excitation.turning:.2f} rad in total (need {MIN_TURNING:.1f}); drive curves '
            'and turns in place')
    straight = [n for n in model.param_names if n in _STRAIGHT_PARAMS]
    if straight and excitation.straight < MIN_STRAIGHT:
        raise ExcitationError(
            f'too little straight driving to identify {_ros_names(straight)}: '
            f'{excitation.straight:.2f} m of nearly straight motion (need '
            f'{MIN_STRAIGHT:.1f}); drive straight forwards and backwards too')
