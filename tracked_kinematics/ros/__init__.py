"""
The ROS 2 ring: thin nodes around the core (rclpy).

Signals before :func:`tracked_kinematics.ros.main.run` are handled by the package's
``__init__``: see docs/testing.md ("Stops at any instant").
"""

from tracked_kinematics import exit_quietly, NODE_EXECUTABLES  # noqa: F401 -- of the nodes
