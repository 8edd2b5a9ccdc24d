"""
The offline ring: bags, output files and the command-line tools (rosbags + core).

When a console script of an offline tool starts, this is the first of the package to run,
before numpy, scipy and rosbags are imported (most of a second). It takes SIGINT, SIGTERM
and SIGHUP at once (:func:`.signals.install_for_tool`): a signal during the imports ends the
process at once, with its exit status and one line as at any later moment (nothing has been
written yet), instead of a KeyboardInterrupt traceback or death by the signal. Only the
tools' processes get this; importing the package elsewhere (tests, scripts) changes nothing.
"""

from tracked_kinematics.offline import signals as _signals

if _signals.tool_process():
    _signals.install_for_tool()
