"""
The offline ring: bags, output files and the command-line tools (rosbags + core).

A tool's console script takes SIGINT, SIGTERM and SIGHUP from the package's first line
(``tracked_kinematics/__init__.py`` calls :func:`.signals.install_for_tool`), before numpy,
scipy and rosbags are imported: a signal during the imports ends the process at once, with
its exit status and one line as at any later moment (nothing has been written yet).
"""
