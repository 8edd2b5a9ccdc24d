"""
Identification: fit motion models and drive trains to logged data.

The face of the sub-package; the modules behind it hold the derivations and references.
"""

from ._identification import *  # noqa: F401,F403  (split into modules: issue 13)
from .drivetrain import DriveData, fit_drivetrain  # noqa: F401
