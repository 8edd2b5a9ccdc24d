"""
calibration_drive (console script): the node of ``ros/`` with the finisher of ``offline/``.

The node (:class:`tracked_kinematics.ros.calibration_drive.CalibrationDriveNode`) drives the
protocol and records; :class:`tracked_kinematics.offline.calibration_files.CalibrationFiles`
checks the output paths at start and writes the bag, the terrain file and the report at the
end. The node ends the process with the finisher's exit status (0: written; 2: an output or
input problem; 3: too little excitation; 4: the fit failed, as identify_icr's). rclpy's own
SIGINT / SIGTERM handlers are taken out, so that a signal ends ``spin`` with the context
still valid and the node's last act, publishing a zero command, reaches cmd_vel_translator.
Reference: docs/nodes/calibration_drive.md.
"""

from __future__ import annotations

import sys

import rclpy
from tracked_kinematics.offline.calibration_files import CalibrationFiles
from tracked_kinematics.ros import calibration_drive as node
from tracked_kinematics.ros.main import run


def _exit(status: int) -> None:
    raise SystemExit(status)


def _make_node():
    # rclpy's handlers shut the context down at the signal, before the node could publish
    # its zero command; main's own handler (a KeyboardInterrupt) is what remains.
    rclpy.signals.uninstall_signal_handlers()
    return node.CalibrationDriveNode(finisher=CalibrationFiles, on_exit=_exit)


def main(args=None):
    """Run calibration_drive (console script ``calibration_drive``)."""
    sys.exit(run(_make_node, node.NODE_NAME, args, node.PARAMS, node.__doc__))
