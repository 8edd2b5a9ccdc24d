"""
calibration_drive (console script): the node of ``ros/`` with the finisher of ``offline/``.

The node (:class:`tracked_kinematics.ros.calibration_drive_node.CalibrationDriveNode`) drives the
protocol and records; :class:`tracked_kinematics.offline.calibration_files.CalibrationFiles`
checks the output paths at start and writes the bag, the terrain file and the report at the
end. The node ends the process with the finisher's exit status (0: written; 2: an output or
input problem; 3: too little excitation; 4: the fit failed, as identify_icr's; 0 after a
signal, as every node). A signal stops the node through run() (the node is destroyed, and
publishes its zero command, before the context shuts down) and ends a fit under way.
Reference: docs/nodes/calibration_drive.md.
"""

from __future__ import annotations

import signal
import sys

from tracked_kinematics.offline.calibration_files import CalibrationFiles
from tracked_kinematics.ros import calibration_drive_node as node
from tracked_kinematics.ros.main import run


def _exit(status: int) -> None:
    raise SystemExit(status)


def _make_node():
    made = node.CalibrationDriveNode(finisher=CalibrationFiles, on_exit=_exit)
    # A signal also ends a fit under way at once (its worker process), then goes on
    # to the handler run() installed (a stop request). run() restores its own at the end.
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous = signal.getsignal(sig)

        def handler(signum, frame, previous=previous):
            made.cancel()
            if callable(previous):
                previous(signum, frame)
        signal.signal(sig, handler)
    return made


def main(args=None):
    """Run calibration_drive (console script ``calibration_drive``)."""
    sys.exit(run(_make_node, node.NODE_NAME, args, node.PARAMS, node.__doc__))
