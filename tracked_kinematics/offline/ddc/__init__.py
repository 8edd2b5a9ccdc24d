"""
diff_drive_controller parameters -> the parameters of tracked_kinematics' nodes.

:mod:`.controllers` finds the DDC section, :mod:`.mapping` maps its keys, :mod:`.conversion`
renders the file and report, :mod:`.values` reads values as rcl does.
See docs/tools/convert_diff_drive_params.md.
"""

from tracked_kinematics.offline.errors import DdcError

from .controllers import DDC_TYPE, find_controller, load_controllers, Section
from .conversion import Conversion, NODE_KEYS, report_lines, TERRAIN_KEYS
from .mapping import convert, convert_file
from .rcl_values import fmt

__all__ = ['Conversion', 'DDC_TYPE', 'DdcError', 'NODE_KEYS', 'Section', 'TERRAIN_KEYS',
           'convert', 'convert_file', 'find_controller', 'fmt', 'load_controllers',
           'report_lines']
