"""
identify_icr as a library: recordings in, the terrain values, the report and the table out.

As evo's ``main_ape``/``main_rpe`` return a result that its command lines only print and
save, :func:`icr_from_poses` (a ground-truth pose: the fit of the segments, or spin-in-place
runs, :mod:`.poses`) and :func:`icr_from_references` (a gyro, GNSS or a measured straight,
:mod:`.references`) take recordings already read and return an :class:`IcrReport`
(:mod:`.report`); the ``identify_icr`` command line parses, reads the bags, prints
``report.text`` and writes ``report.values`` and ``report.report`` through its outputs.
"""

from .poses import icr_from_poses
from .references import icr_from_references, WHY_HELD
from .report import IcrReport, TOOL

__all__ = ['IcrReport', 'TOOL', 'WHY_HELD', 'icr_from_poses', 'icr_from_references']
