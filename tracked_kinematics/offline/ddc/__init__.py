"""
diff_drive_controller parameters -> the parameters of tracked_kinematics' nodes.

:mod:`.controllers` reads a ros2_control controllers file and finds its DDC section,
:mod:`.mapping` maps that section's keys to ours (the kinematics, and why DDC's is a
tread-ICR model), :mod:`.conversion` holds the result and renders the parameter file and the
report, :mod:`.rcl_values` reads DDC values as rcl does. ``convert_diff_drive_params`` is the
command line; docs/tools/convert_diff_drive_params.md lists the mapping.
"""

from tracked_kinematics.offline.errors import DdcError

from .controllers import DDC_TYPE, find_controller, load_controllers, Section
from .conversion import Conversion, NODE_KEYS, report_lines, TERRAIN_KEYS
from .mapping import convert, convert_file
from .rcl_values import fmt

__all__ = ['Conversion', 'DDC_TYPE', 'DdcError', 'NODE_KEYS', 'Section', 'TERRAIN_KEYS',
           'convert', 'convert_file', 'find_controller', 'fmt', 'load_controllers',
           'report_lines']
