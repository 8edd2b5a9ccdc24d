"""
calibration_drive's health on ``/diagnostics``: which inputs it needs, and when.

Encoders and reference from the start; the deadman while the drive moves the robot (and
before, with ``auto_start``). See docs/diagnostics.md.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from tracked_kinematics.ros.health import Health, Report

DRIVING = ('running', 'returning')


def watch_calibration_inputs(node, encoder_inputs: Sequence, reference,
                             deadmen: Iterable[tuple[str, str]]) -> tuple[Health, list]:
    """
    Return the calibration drive's :class:`Health` and the counts of its deadman topics.

    ``deadmen`` holds (topic, type name) of each deadman subscription; their callbacks must tick
    the returned counts, in the same order.
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
