"""
Push ICRs into running nodes (cmd_vel_translator, odometry_node) by their parameter services.

Shared by icr_estimator and odometry_node (``push_to``): at most one push per ``push_period``,
only when a coordinate moved by more than ``push_min_change``, and the ICRs count as pushed
only once a node has accepted them. See docs/nodes/icr_estimator.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType
from rcl_interfaces.srv import SetParametersAtomically

NAMES = ('icr.y_left', 'icr.y_right', 'icr.x')
"""The parameters a push sets, in the order of the ICR tuples."""

# Seconds between two warnings about the same problem.
WARN_PERIOD = 5.0


class IcrPusher:
    """
    Set ``icr.y_left``, ``icr.y_right``, ``icr.x`` of the nodes in ``push_to``, rate-limited.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that owns the service clients (and whose clock rate-limits).
    on_pushed : callable, optional
        ``on_pushed(target, icr)`` after a node accepted the ICRs.

    """

    def __init__(self, node, on_pushed: Callable | None = None):
        self._node = node
        self._on_pushed = on_pushed
        self._clients: dict = {}
        self.pushed = None          # the ICRs last accepted
        self.count = 0              # pushes accepted
        self._last_ns = None

    def reset(self) -> None:
        """Forget what was pushed: the next ICRs are pushed whatever their change."""
        self.pushed = None

    def push(self, icr, values: Mapping[str, Any]) -> bool:
        """
        Push ``icr = (y_left, y_right, x)`` (m) if it is time and they changed; True if sent.

        ``values`` holds ``push_to``, ``push_period`` (s) and ``push_min_change`` (m).
        """
        targets = values['push_to']
        if not targets:
            return False
        node = self._node
        now_ns = node.get_clock().now().nanoseconds
        if (self._last_ns is not None
                and now_ns - self._last_ns < values['push_period'] * 1e9):
            return False
        if self.pushed is not None and max(
                abs(a - b) for a, b in zip(icr, self.pushed)) <= values['push_min_change']:
            return False
        request = SetParametersAtomically.Request()
        for name, value in zip(NAMES, icr):
            param = ParameterMsg(name=name)
            param.value.type = ParameterType.PARAMETER_DOUBLE
            param.value.double_value = float(value)
            request.parameters.append(param)
        self._last_ns = now_ns
        sent = False
        for target in targets:
            client = self._clients.get(target)
            if client is None:
                client = node.create_client(
                    SetParametersAtomically, f'/{target.strip("/")}/set_parameters_atomically')
                self._clients[target] = client
            if not client.service_is_ready():
                node.get_logger().warning(f'cannot push the ICRs: {client.srv_name} is not '
                                          'available', throttle_duration_sec=WARN_PERIOD)
                continue
            future = client.call_async(request)
            future.add_done_callback(
                lambda f, target=target, icr=tuple(icr): self._pushed_to(target, icr, f))
            sent = True
        return sent

    def prepare(self, targets) -> None:
        """Create the clients of ``targets`` now, so that the first push finds them ready."""
        for target in targets:
            if target not in self._clients:
                self._clients[target] = self._node.create_client(
                    SetParametersAtomically, f'/{target.strip("/")}/set_parameters_atomically')

    def _pushed_to(self, target, icr, future) -> None:
        result = future.result()
        logger = self._node.get_logger()
        if result is None or not result.result.successful:
            reason = 'no answer' if result is None else result.result.reason
            logger.warning(f'{target} refused the ICRs {icr}: {reason}',
                           throttle_duration_sec=WARN_PERIOD)
            return
        self.pushed = icr
        self.count += 1
        if self._on_pushed is not None:
            self._on_pushed(target, icr)
        logger.info(
            f'pushed icr.y_left {icr[0]:.3f}, icr.y_right {icr[1]:.3f}, icr.x {icr[2]:.3f} m '
            f'to {target}', throttle_duration_sec=WARN_PERIOD)
