"""
cmd_vel_translator: body twist commands to track speed setpoints through the tread ICRs.

What runs between navigation (Nav2, teleop) and the track motor drivers, in place of the
command path of diff_drive_controller. The maths is :mod:`tracked_kinematics.core.command`;
this node converts messages, keeps time and publishes at a fixed rate.

Topics
------
``cmd_vel`` (in)
    geometry_msgs/Twist, or TwistStamped with ``use_stamped: true``.
``left_track/setpoint``, ``right_track/setpoint`` (out, at ``rate``)
    std_msgs/Float64, nominal track speed in m/s (true speed / scale).
``joint_velocity_topic`` (out, at ``rate``, when the parameter is not empty)
    std_msgs/Float64MultiArray ``[left, right]``: sprocket speeds in rad/s, for a
    ros2_control ``velocity_controllers/JointGroupVelocityController``.

Time
----
Ramps and the command timeout run on the node's clock (``use_sim_time`` works: a paused
simulation holds the setpoints). A command is in force from its *arrival*, also in stamped
mode: the header stamp says when the sender made it, but on a robot whose clocks disagree a
stamp-based age would stop a healthy stream or keep a dead one.

The fixed-rate publishing runs in a thread of its own, paced on the steady clock, not in an
rclpy timer: each wake-up of rclpy's Python executor cost most of a millisecond of CPU on
the 2-core test machine, several per cent of a core at 50 Hz; the thread costs a fraction
of that. The executor only handles what arrives (commands, parameter requests). A lock
keeps the two apart.
"""

from __future__ import annotations

from collections.abc import Mapping
import math
import threading
import time
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from rclpy.node import Node
from std_msgs.msg import Float64, Float64MultiArray
from tracked_kinematics.core.command import CommandLimiter, CommandLimits
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.params import (COMMAND_LIMIT_PARAMS, icr_from_values, LIMIT_FIELDS,
                                       limits_from_values, ParamSpec, positive, TERRAIN_PARAMS)
from tracked_kinematics.ros.main import run
from tracked_kinematics.ros.parameters import ParameterTable

NODE_NAME = 'cmd_vel_translator'


TRANSLATOR_PARAMS: tuple[ParamSpec, ...] = TERRAIN_PARAMS + (
    ParamSpec('rate', 50.0, 'Rate at which the setpoints are published', 'Hz', positive),
    ParamSpec('cmd_timeout', 0.5,
              'Age of the last command beyond which the setpoints ramp to zero', 's', positive),
    ParamSpec('use_stamped', False, 'Subscribe to geometry_msgs/TwistStamped, not Twist',
              read_only=True),
    ParamSpec('joint_velocity_topic', '',
              'Topic of a Float64MultiArray [left, right] of sprocket speeds in rad/s (for a '
              'ros2_control velocity controller); empty = not published', read_only=True),
) + COMMAND_LIMIT_PARAMS


def model_from_values(values: Mapping[str, Any]) -> tuple[IcrParams, CommandLimits]:
    """
    Kinematic model and command limits from the node's parameter values.

    Raises
    ------
    ValueError
        When the terrain parameters do not make a valid model (message in ROS names).

    """
    return icr_from_values(values), limits_from_values(values)


def _describe_limits(limits: CommandLimits) -> str:
    set_limits = [f'{name} {getattr(limits, field):g}' for name, field in LIMIT_FIELDS.items()
                  if math.isfinite(getattr(limits, field))]
    return ', '.join(set_limits) or 'none'


class CmdVelTranslator(Node):
    """
    Subscribe to twist commands, publish limited track speed setpoints at a fixed rate.

    Parameters
    ----------
    **kwargs
        Forwarded to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ...).

    Raises
    ------
    tracked_kinematics.ros.parameters.ParameterError
        When the parameters given at start are invalid.

    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self._params = ParameterTable(self, TRANSLATOR_PARAMS, validate=model_from_values,
                                      on_change=self._on_change)
        icr, limits = model_from_values(self._params.values)
        self._limiter = CommandLimiter(icr, limits, self._params['cmd_timeout'])
        self._lock = threading.Lock()  # the limiter is shared by the executor and publisher
        self._radius = self._params['sprocket_radius']
        self._t0 = self.get_clock().now().nanoseconds
        self._was_stale = True
        self._lateral_noted = False

        self._left_msg, self._right_msg = Float64(), Float64()  # reused: fewer allocations
        self._joint_msg = Float64MultiArray()
        self._left_pub = self.create_publisher(Float64, 'left_track/setpoint', 10)
        self._right_pub = self.create_publisher(Float64, 'right_track/setpoint', 10)
        joint_topic = self._params['joint_velocity_topic']
        self._joint_pub = (self.create_publisher(Float64MultiArray, joint_topic, 10)
                           if joint_topic else None)
        self._stamped = self._params['use_stamped']
        self.create_subscription(TwistStamped if self._stamped else Twist, 'cmd_vel',
                                 self._on_command, 10)
        self._period = 1.0 / self._params['rate']
        self._stop = threading.Event()
        self.context.on_shutdown(self._stop.set)
        self._publisher_thread = threading.Thread(target=self._publish_loop,
                                                  name='setpoint_publisher', daemon=True)
        self._publisher_thread.start()

        self.get_logger().info(
            f'ICR model chi = {icr.chi:.3f}, e = {icr.eccentricity:.3f}, scales '
            f'({icr.scale_left:g}, {icr.scale_right:g}); publishing setpoints at '
            f'{1.0 / self._period:g} Hz, cmd_timeout {self._limiter.timeout:g} s, limits: '
            f'{_describe_limits(limits)}'
            + (f'; sprocket speeds (rad/s) on {self._joint_pub.topic_name}'
               if self._joint_pub else ''))

    def _now(self) -> float:
        """Node clock time since start, s."""
        return (self.get_clock().now().nanoseconds - self._t0) * 1e-9

    def _on_command(self, msg) -> None:
        twist = msg.twist if self._stamped else msg
        lin, ang = twist.linear, twist.angular
        if not all(map(math.isfinite, (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))):
            self.get_logger().warning(
                f'dropped a non-finite cmd_vel (linear {lin.x}, {lin.y}, {lin.z}; angular '
                f'{ang.x}, {ang.y}, {ang.z}); the last good command holds until cmd_timeout',
                throttle_duration_sec=1.0)
            return
        if lin.y != 0.0 and not self._lateral_noted:
            self._lateral_noted = True
            self.get_logger().warning(
                'cmd_vel has a lateral velocity (linear.y); a tracked vehicle cannot be '
                'commanded sideways, so linear.y is ignored (this note is shown once)')
        with self._lock:
            self._limiter.command(lin.x, ang.z, self._now())

    def _publish_loop(self) -> None:
        """Publish every period of the steady clock until the node or its context stops."""
        due = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            try:
                self._publish()
            except Exception as err:  # noqa: BLE001 -- keep the stream alive, say why
                if self._stop.is_set() or not self.context.ok():
                    return
                self.get_logger().error(f'publishing setpoints failed: {err!r}',
                                        throttle_duration_sec=1.0)
            due += self._period
            now = time.monotonic()
            if due < now - self._period:  # fell behind (stalled): no burst to catch up
                due = now

    def _publish(self) -> None:
        t = self._now()
        # A stall of this process must not turn into a jump: ramp over at most two periods.
        # (With simulated time a stall stops the clock too, so there is nothing to guard.)
        max_dt = math.inf if self.get_clock().ros_time_is_active else 2.0 * self._period
        with self._lock:
            left, right = self._limiter.update(t, max_dt=max_dt)
            stale = self._limiter.is_stale(t)
        if stale and not self._was_stale:
            self.get_logger().debug('no cmd_vel for cmd_timeout: ramping to zero')
        self._was_stale = stale
        self._left_msg.data, self._right_msg.data = left, right
        self._left_pub.publish(self._left_msg)
        self._right_pub.publish(self._right_msg)
        if self._joint_pub is not None:
            self._joint_msg.data = [left / self._radius, right / self._radius]
            self._joint_pub.publish(self._joint_msg)

    def _on_change(self, values: Mapping[str, Any]) -> None:
        icr, limits = model_from_values(values)
        with self._lock:
            self._limiter.icr = icr
            self._limiter.limits = limits
            self._limiter.timeout = values['cmd_timeout']
            self._radius = values['sprocket_radius']
            self._period = 1.0 / values['rate']
        self.get_logger().info(
            f'parameters changed: chi = {icr.chi:.3f}, e = {icr.eccentricity:.3f}, '
            f'{values["rate"]:g} Hz, cmd_timeout {values["cmd_timeout"]:g} s, limits: '
            f'{_describe_limits(limits)}')

    def destroy_node(self):
        """Stop the publishing thread, then destroy the node."""
        self._stop.set()
        if self._publisher_thread.is_alive():
            self._publisher_thread.join()
        super().destroy_node()


def main(args=None):
    """Run the node (console script ``cmd_vel_translator``)."""
    raise SystemExit(run(CmdVelTranslator, NODE_NAME, args, TRANSLATOR_PARAMS, __doc__))
