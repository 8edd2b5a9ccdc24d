"""
The services the nodes share: ``~/reset`` (std_srvs/Trigger).

odometry_node and icr_estimator answer ``~/reset`` the same way: the node's own reset, then
success with a fixed message, which the node also logs.
"""

from __future__ import annotations

from collections.abc import Callable

from std_srvs.srv import Trigger


def reset_service(node, reset: Callable[[], None], message: str):
    """
    Create the node's ``~/reset`` service.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that answers.
    reset : callable
        ``reset()``, called in the service callback (the executor).
    message : str
        What the answer says and the node logs (info) after each reset.

    Returns
    -------
    rclpy.service.Service
        The service.

    """
    def handle(request, response):
        reset()
        response.success = True
        response.message = message
        node.get_logger().info(message)
        return response

    return node.create_service(Trigger, '~/reset', handle)
