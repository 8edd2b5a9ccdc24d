"""
identify_icr as a library: options in, the terrain values, the report and the table out.

As evo's ``main_ape``/``main_rpe`` return a result that its command lines only print and
save, :func:`fit` (:mod:`.api`) takes :class:`FitOptions`, reads the bags and returns a
:class:`FitResult` (:mod:`.report`); :func:`write_fit` writes it. The ``identify_icr``
command line, ``calibration_drive`` and the demo all call it. Behind it,
:func:`icr_from_poses` (a ground-truth pose: the fit of the segments, or spin-in-place runs,
:mod:`.poses`) and :func:`icr_from_references` (a gyro, GNSS or a measured straight,
:mod:`.references`) take recordings already read.
"""

from .api import check_options, fit, FitOptions, MODELS, write_fit
from .poses import icr_from_poses
from .references import icr_from_references, WHY_HELD
from .report import FitResult, TOOL

__all__ = ['FitOptions', 'FitResult', 'MODELS', 'TOOL', 'WHY_HELD', 'check_options', 'fit',
           'icr_from_poses', 'icr_from_references', 'write_fit']
