"""
The ROS 2 ring: thin nodes around the core (rclpy).

When a node's console script starts, its modules (rclpy, numpy, scipy; calibration_drive's
offline code) take most of a second to import, before :func:`tracked_kinematics.ros.main.run`
can handle signals. The package's ``__init__`` makes SIGINT and SIGTERM end the process
quietly with exit status 0 from its first lines (:func:`exit_quietly`), as one at any later
moment does, instead of a KeyboardInterrupt traceback or death by the signal. Only the node
executables get this; importing the package elsewhere (tests, tools) changes nothing.
"""

from tracked_kinematics import exit_quietly, NODE_EXECUTABLES  # noqa: F401 -- of the nodes
