"""The ``main`` of every node: init, construct, spin, shut down, exit status."""

from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from tracked_kinematics.ros.parameters import ParameterError


def run(node_factory: Callable[[], 'rclpy.node.Node'], name: str, args=None) -> int:
    """
    Run one node until shutdown; return the process exit status.

    Invalid parameters at start are reported on one line through the ROS logger and give
    exit status 2, as ros2_controllers' nodes refuse to configure with bad parameters.

    Parameters
    ----------
    node_factory : callable
        Builds the node (after ``rclpy.init``).
    name : str
        Logger name used when the node could not be built.
    args : list of str, optional
        Command-line arguments (``--ros-args ...``); default ``sys.argv``.

    """
    rclpy.init(args=args)
    node = None
    try:
        node = node_factory()
        rclpy.spin(node)
    except ParameterError as err:
        rclpy.logging.get_logger(name).fatal(str(err))
        return 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
