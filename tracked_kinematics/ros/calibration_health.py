"""
calibration_drive's health on ``/diagnostics``: which inputs it needs, and when.

Its encoders and its reference (pose or IMU) are needed from the start (without them the
drive cannot start); the deadman (topic or joystick) while the drive moves the robot
(``running`` or ``returning``), and with ``auto_start`` also before it starts (it waits for
the deadman). The supervisor's state and reason are added as key/values.
Kept apart from the node, whose module holds the drive's safety.
"""

from __future__ import annotations

from collections.abc import Sequence

from tracked_kinematics.ros.health import Health, Report

DRIVING = ('running', 'returning')


def watch_calibration_inputs(node, encoder_inputs: Sequence, inputs: Sequence) -> Health:
    """
    Return the calibration drive's :class:`Health`, watching its inputs.

    Parameters
    ----------
    node : CalibrationDriveNode
        The node (its ``supervisor`` is read at every update).
    encoder_inputs : sequence of InputTopic
        The encoder topics.
    inputs : sequence of InputTopic
        The reference first, then the deadmen.

    """
    health = Health(node)
    health.watch(*encoder_inputs, inputs[0])
    auto_start = node.supervisor.config.auto_start
    health.watch(*inputs[1:], needed=lambda: node.supervisor.state in DRIVING or (
        auto_start and node.supervisor.state == 'idle'))

    def drive(report: Report) -> None:
        last = node.supervisor.last
        report.add('state', last.state)
        report.add('reason', last.reason)

    health.add(drive)
    return health
