"""
Whether the data can identify a model: enough motion, turning and straight driving.

Turning identifies the tread ICRs, straight driving the encoder scales (Martinez et al. 2005, sec.
4.2, eqs. 20-21).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .segments import Segments
from ..errors import ExcitationError
from ..models import MotionModel


@dataclass(frozen=True)
class Excitation:
    """How much the data move (m), turn (rad) and drive straight (m, turning radius above 5 m)."""

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


def ros_names(model: MotionModel, names) -> str:
    """Return parameters of ``model`` by their ROS names (:class:`..models.Parameter`), joined."""
    return ', '.join(model.parameter(n).ros_name for n in names)


def excited_by(model: MotionModel, kind: str) -> list[str]:
    """Return the parameters of ``model`` that ``kind`` of driving identifies, in order."""
    return [n for n in model.param_names if model.parameter(n).excited_by == kind]


def check_excitation(model: MotionModel, excitation: Excitation) -> None:
    """
    Raise :class:`ExcitationError` when the data cannot identify the model's parameters.

    Thresholds are deliberately low (:data:`MIN_TURNING`, :data:`MIN_STRAIGHT`): the fit checks its
    own standard errors afterwards.
    """
    if excitation.moving < MIN_MOVING_SEGMENTS:
        raise ExcitationError(
            f'too little motion: {excitation.moving} of {excitation.segments} segments move '
            f'(need {MIN_MOVING_SEGMENTS}); drive longer, or check the encoder topic and '
            'sprocket radius')
    turning = excited_by(model, 'turning')
    if turning and excitation.turning < MIN_TURNING:
        raise ExcitationError(
            f'too little turning to identify {ros_names(model, turning)}: the data turn '
            f'{excitation.turning:.2f} rad in total (need {MIN_TURNING:.1f}); drive curves '
            'and turns in place')
    straight = excited_by(model, 'straight')
    if straight and excitation.straight < MIN_STRAIGHT:
        raise ExcitationError(
            f'too little straight driving to identify {ros_names(model, straight)}: '
            f'{excitation.straight:.2f} m of nearly straight motion (need '
            f'{MIN_STRAIGHT:.1f}); drive straight forwards and backwards too')
