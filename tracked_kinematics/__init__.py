"""
Slip-aware odometry, velocity control and ICR calibration for tracked robots.

Its first lines take SIGINT and SIGTERM by the executable's name, before anything heavy is
imported: a node quits with status 0, an offline tool with the signal's status and one line.
See docs/testing.md ("Stops at any instant").
"""

import os as _os
import signal as _signal
import sys as _sys

NODE_EXECUTABLES = ('odometry_node', 'cmd_vel_translator', 'icr_estimator', 'tracked_simulator',
                    'calibration_drive', 'calibration_deadman', 'play_bag')
"""Console scripts that run a node (setup.py): a signal before run() is a quiet exit 0."""
TOOL_EXECUTABLES = ('simulate_bag', 'identify_icr', 'identify_drivetrain', 'evaluate_model',
                    'icr_map', 'plan_trajectory', 'convert_diff_drive_params',
                    'tracked_kinematics_demo')
"""Console scripts of the offline tools (setup.py): a signal ends them with its status."""


def exit_quietly(signum, frame):
    """Leave at once with status 0: a node executable's handler until run() starts."""
    # Nothing has started yet (no ROS context, no output): leave at once. An exception
    # raised here could surface inside a C extension's initialisation as an ImportError.
    _os._exit(0)


def _take_stop_signals(argv0: str) -> None:
    """Install the stop-signal handler of the console script ``argv0``, if it is one."""
    name = _os.path.basename(argv0)
    try:
        if name in NODE_EXECUTABLES:
            for signum in (_signal.SIGINT, _signal.SIGTERM):
                _signal.signal(signum, exit_quietly)
        elif name in TOOL_EXECUTABLES:
            early = []
            for signum in (_signal.SIGINT, _signal.SIGTERM, _signal.SIGHUP):
                _signal.signal(signum, lambda signum, frame: early.append(signum))
            from tracked_kinematics.offline import signals  # the standard library only
            signals.install_for_tool(early)
    except ValueError:  # not the main thread of the main interpreter: not a console script
        pass


_take_stop_signals(_sys.argv[0] if getattr(_sys, 'argv', None) else '')
