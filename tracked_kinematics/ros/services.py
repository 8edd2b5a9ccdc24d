"""The ``~/reset`` service (std_srvs/Trigger) that odometry_node and icr_estimator share."""

from __future__ import annotations

from collections.abc import Callable

from std_srvs.srv import Trigger


def reset_service(node, reset: Callable[[], None], message: str):
    """Create ``~/reset``: call ``reset()``, answer success with ``message`` and log it."""
    def handle(request, response):
        reset()
        response.success = True
        response.message = message
        node.get_logger().info(message)
        return response

    return node.create_service(Trigger, '~/reset', handle)
