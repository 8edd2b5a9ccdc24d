"""
calibration_drive's health on ``/diagnostics``: which inputs it needs, and when.

Its encoders and its reference (pose or IMU) are needed from the start (without them the
drive cannot start); the deadman (topic or joystick) while the drive moves the robot
(``running`` or ``returning``), and with ``auto_start`` also before it starts (it waits for
the deadman). The supervisor's state and reason are added as key/values.
Kept apart from the node, whose module holds the drive's safety.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from tracked_kinematics.ros.health import Health, Report

DRIVING = ('running', 'returning')


def watch_calibration_inputs(node, encoder_inputs: Sequence, reference,
                             deadmen: Iterable[tuple[str, str]]) -> tuple[Health, list]:
    """
    Return the calibration drive's :class:`Health` and the counts of its deadman topics.

    Parameters
    ----------
    node : CalibrationDriveNode
        The node (its ``supervisor`` is read at every update).
    encoder_inputs : sequence of InputTopic
        The encoder topics.
    reference : InputTopic
        The pose or IMU topic.
    deadmen : iterable of (str, str)
        Topic and type name of each deadman subscription (plain subscriptions: their
        callbacks must tick the returned counts, in the same order).

    """
    health = Health(node)
    health.watch(*encoder_inputs, reference)
    auto_start = node.supervisor.config.auto_start

    def needed() -> bool:
        state = node.supervisor.state
        return state in DRIVING or (auto_start and state == 'idle')

    counts = [health.watch_topic(topic, [kind], needed=needed) for topic, kind in deadmen]

    def drive(report: Report) -> None:
        last = node.supervisor.last
        report.add('state', last.state)
        report.add('reason', last.reason)

    health.add(drive)
    return health, counts
