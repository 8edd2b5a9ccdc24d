"""Numerical core of tracked_kinematics: numpy/scipy only, no ROS, no file I/O."""

from .integration import arc_chord, compose, integrate, integrate_twist, relative_pose, wrap_angle
from .kinematics import forward, IcrParams, inverse, nominal_speeds, true_speeds
from .models import make_model, MODEL_NAMES, MotionModel

__all__ = [
    'IcrParams', 'MODEL_NAMES', 'MotionModel', 'arc_chord', 'compose', 'forward', 'integrate',
    'integrate_twist', 'inverse', 'make_model', 'nominal_speeds', 'relative_pose', 'true_speeds',
    'wrap_angle',
]
