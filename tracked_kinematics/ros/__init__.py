"""
The ROS 2 ring: thin nodes around the core (rclpy).

When a node's console script starts, its modules (rclpy, numpy, scipy) take most of a second
to import, before :func:`tracked_kinematics.ros.main.run` can handle signals. A SIGINT or
SIGTERM in that time ends the process quietly with exit status 0, as one at any later moment
does, instead of a KeyboardInterrupt traceback or death by the signal. Only the node
executables get this; importing the package elsewhere (tests, tools) changes nothing.
"""

import os
import signal
import sys
import threading

NODE_EXECUTABLES = ('odometry_node', 'cmd_vel_translator', 'icr_estimator', 'tracked_simulator',
                    'calibration_drive', 'calibration_deadman')


def exit_quietly(signum, frame):
    """Leave at once with status 0: the handler while a node executable imports."""
    # Nothing has started yet (no ROS context, no output): leave at once. An exception
    # raised here could surface inside a C extension's initialisation as an ImportError.
    os._exit(0)


if (os.path.basename(sys.argv[0] if sys.argv else '') in NODE_EXECUTABLES
        and threading.current_thread() is threading.main_thread()):
    for _signal in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_signal, exit_quietly)
