"""Trajectory generation: the canonical references (Fink & Stump Table V) and the planner."""

from .planner import path_deviation, Plan, Planner, reach
from .trajectories import (
    CANONICAL, canonical, curvature_profile, Reference, reference, trapezoid_profile)
from ..errors import PlanningError

__all__ = [
    'CANONICAL', 'Plan', 'Planner', 'PlanningError', 'Reference', 'canonical',
    'curvature_profile', 'path_deviation', 'reach', 'reference', 'trapezoid_profile',
]
