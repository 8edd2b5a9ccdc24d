"""
The offline ring: bags, output files and the command-line tools (rosbags + core).

Tools take their signals from the package's first line (:func:`.signals.install_for_tool`).
"""
