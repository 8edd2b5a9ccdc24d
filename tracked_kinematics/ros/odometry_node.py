"""
odometry_node: track encoders to nav_msgs/Odometry through the tread-ICR kinematics.

A thin adapter: :class:`~tracked_kinematics.ros.encoder_input.EncoderInput` gives travel
steps, :class:`~tracked_kinematics.core.odometry.Odometry` integrates them, this node fills
``odom`` and the transform. See docs/nodes/odometry_node.md.
"""

from __future__ import annotations

from collections.abc import Mapping
import gc
import math
import sys
from typing import Any

from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry as OdometryMsg
from rclpy.qos import QoSProfile, ReliabilityPolicy
from tracked_kinematics.core.covariance import TrackNoise
from tracked_kinematics.core.integration import quaternion_from_yaw
from tracked_kinematics.core.kinematics import IcrParams
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.params import (ENCODER_INPUT_PARAMS, frame_id, icr_from_values,
                                       non_negative, ParamSpec, TERRAIN_PARAMS,
                                       zero_or_at_least)
from tracked_kinematics.ros.encoder_input import (
    check_encoder_values, EncoderInput, WARN_PERIOD)
from tracked_kinematics.ros.health import Health
from tracked_kinematics.ros.input_topic import CHECK_PERIOD, steady_timer
from tracked_kinematics.ros.main import run
from tracked_kinematics.ros.odometry_message import OdometrySerializer
from tracked_kinematics.ros.parameters import TableNode
from tracked_kinematics.ros.services import reset_service

NODE_NAME = 'odometry_node'


_DEFAULT_NOISE = TrackNoise()

ODOMETRY_PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec('odom_frame', 'odom', 'Frame of the published pose (header.frame_id)',
              check=frame_id),
    ParamSpec('base_frame', 'base_link', 'Frame of the vehicle (child_frame_id)',
              check=frame_id),
    ParamSpec('publish_tf', True, 'Also broadcast the odom_frame -> base_frame transform'),
    ParamSpec('publish_rate', 0.0,
              'Highest rate of odom messages, by message time; 0 publishes on every encoder '
              'step', 'Hz', zero_or_at_least(0.01, 'Hz'), low=0.0, high=10000.0),
    ParamSpec('covariance.k_left', _DEFAULT_NOISE.k_left,
              'Variance of the left track travel per metre travelled', 'm^2/m', non_negative,
              low=0.0, high=1.0),
    ParamSpec('covariance.k_right', _DEFAULT_NOISE.k_right,
              'Variance of the right track travel per metre travelled', 'm^2/m',
              non_negative, low=0.0, high=1.0),
    ParamSpec('covariance.floor', _DEFAULT_NOISE.floor,
              'Variance added to each track travel per encoder sample', 'm^2', non_negative,
              low=0.0, high=1.0),
)

PARAMS = TERRAIN_PARAMS + ENCODER_INPUT_PARAMS + ODOMETRY_PARAMS


def _noise(values: Mapping[str, Any]) -> TrackNoise:
    return TrackNoise(values['covariance.k_left'], values['covariance.k_right'],
                      values['covariance.floor'])


def validate(values: Mapping[str, Any]) -> IcrParams:
    """
    Check the node's parameters as a whole; return the kinematic model they give.

    Raises
    ------
    ValueError
        For an invalid kinematic model (``y_left <= y_right``, chi outside (0, 1], ...),
        a joint on both sides, or equal frames; the message names the parameters.

    """
    icr = icr_from_values(values)
    check_encoder_values(values)
    if values['odom_frame'] == values['base_frame']:
        raise ValueError(f'odom_frame and base_frame must differ, both are '
                         f'{values["odom_frame"]!r}')
    return icr


def _terrain(values: Mapping[str, Any]) -> tuple:
    return tuple(values.get(spec.name) for spec in TERRAIN_PARAMS)


class OdometryNode(TableNode):
    """
    Odometry of a tracked vehicle from its track encoders.

    A :class:`~tracked_kinematics.ros.parameters.TableNode` of :data:`PARAMS`; ``ParameterError``
    when the parameters given at start are invalid.
    """

    # The model validate built, with the terrain values it came from: the start and every
    # accepted change build it once, in validate, and take that one into use.
    _validated: tuple | None = None

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, PARAMS, self._validate, **kwargs)

    def _validate(self, values: Mapping[str, Any]) -> None:
        self._validated = (_terrain(values), validate(values))

    def _icr(self, values: Mapping[str, Any]) -> IcrParams:
        terrain = _terrain(values)
        if self._validated is None or self._validated[0] != terrain:
            self._validated = (terrain, icr_from_values(values))
        return self._validated[1]

    def _start(self, values: Mapping[str, Any]) -> None:
        self.odometry = Odometry(self._icr(values), _noise(values))
        self._publisher = self.create_publisher(
            OdometryMsg, 'odom', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self._serializer = None
        self._broadcaster = None
        self._transform = None
        self._tf_warned = False
        self._last_publish_ns = None
        self.encoder = None
        self._apply(values)
        self.encoder = EncoderInput(self, values, self._on_step, check_timer=False)
        self.health = Health(self, timer=False)  # updated by _check, on the timer below
        self.health.watch(*self.encoder.inputs)
        reset_service(self, self._reset, 'odometry reset: pose (0, 0, 0), covariance zero')
        # One timer for the input's checks and the output's: every timer of the node costs
        # each turn of the executor (each message) a little.
        self._check_timer = steady_timer(self, CHECK_PERIOD, self._check)
        self._warned_publishers = 0
        icr = self.odometry.icr
        derived = [name for name in ('icr.y_left', 'icr.y_right')
                   if name not in self.params.explicit]
        self.get_logger().info(
            f'ICR model: chi {icr.chi:.3f}, e {icr.eccentricity:.3f} (icr.y_left '
            f'{icr.y_left:g} m, icr.y_right {icr.y_right:g} m, icr.x {icr.x:g} m, '
            f'track_width {icr.track_width:g} m'
            + (f'; {" and ".join(derived)} from track_width' if derived else '')
            + f'), scales {icr.scale_left:g} / {icr.scale_right:g}, sprocket_radius '
            f'{values["sprocket_radius"]:g} m; {self.encoder.describe()}; publishing '
            f'{self._publisher.topic_name} ({values["odom_frame"]} -> {values["base_frame"]}) '
            + (f'at up to {values["publish_rate"]:g} Hz' if values['publish_rate'] > 0
               else 'at the input rate')
            + ('' if self._broadcaster is None else ' with TF'))

    def _check(self) -> None:
        self.encoder.check()
        self._check_output()
        self.health.update()

    def _check_output(self) -> None:
        """Warn when another node publishes on the odometry topic too (two instances)."""
        try:
            infos = self.get_publishers_info_by_topic(self._publisher.topic_name)
        except Exception:  # noqa: BLE001 -- the graph is gone during shutdown
            return
        if len(infos) <= 1:
            self._warned_publishers = 0
            return
        if len(infos) == self._warned_publishers:
            return
        self._warned_publishers = len(infos)
        names = ', '.join(sorted(f'{info.node_namespace.rstrip("/")}/{info.node_name}'
                                 for info in infos))
        self.get_logger().warning(
            f'{len(infos)} publishers on {self._publisher.topic_name} ({names}): another node '
            'publishes odometry there too, so consumers see both (two odometry_node '
            'instances? remap one, or stop it)')

    def _apply(self, values: Mapping[str, Any]) -> None:
        """Take (new) parameter values into use from the next encoder step on."""
        self.odometry.set_model(self._icr(values), _noise(values))
        if self.encoder is not None:
            self.encoder.configure(values)
        rate = values['publish_rate']
        self._min_period_ns = round(1e9 / rate) if rate > 0.0 else 0
        frames = (values['odom_frame'], values['base_frame'])
        if self._serializer is None or self._serializer.frames != frames:
            self._serializer = OdometrySerializer(*frames)
        self._setup_tf(values['publish_tf'])
        if self._transform is not None:
            self._transform.header.frame_id = values['odom_frame']
            self._transform.child_frame_id = values['base_frame']

    def _setup_tf(self, enabled: bool) -> None:
        if not enabled:
            self._broadcaster = None
            return
        if self._broadcaster is not None:
            return
        try:
            from tf2_ros import TransformBroadcaster
        except ImportError as err:
            if not self._tf_warned:
                self._tf_warned = True
                self.get_logger().warning(
                    f'publish_tf is true but tf2_ros cannot be imported ({err}): no '
                    'odom -> base_link transform will be broadcast. Install tf2_ros '
                    '(ros-jazzy-tf2-ros) or set publish_tf to false.')
            return
        self._broadcaster = TransformBroadcaster(self)
        self._transform = TransformStamped()

    def _on_step(self, stamp_s: float, d_left: float, d_right: float, dt: float) -> None:
        if not self.odometry.update(d_left, d_right, dt):
            self.get_logger().warning(
                f'encoder step refused by the odometry (travel {d_left!r}, {d_right!r} m over '
                f'{dt!r} s: beyond 1e9 m, or a speed or pose that is not finite): skipped, '
                'nothing integrated or published', throttle_duration_sec=WARN_PERIOD)
            return
        # Rate cap by message time, in integer nanoseconds so that it is exact; a stamp
        # before the last published one (time went back) publishes at once.
        encoder = self.encoder
        now_ns = encoder.stamp_ns
        last = self._last_publish_ns
        if (self._min_period_ns and last is not None
                and 0 <= now_ns - last < self._min_period_ns):
            return
        if self._publish(*encoder.stamp_fields):
            self._last_publish_ns = now_ns

    def _publish(self, sec: int, nanosec: int) -> bool:
        odometry = self.odometry
        x, y, theta = odometry.pose
        twist, twist_covariance = odometry.take_twist()
        if not all(map(math.isfinite, twist + twist_covariance)):
            self.get_logger().warning(
                f'non-finite twist {twist} not published', throttle_duration_sec=WARN_PERIOD)
            return False
        # The yaw as a quaternion with w >= 0 (theta itself is continuous, not wrapped).
        _, _, qz, qw = quaternion_from_yaw(theta)
        if qw < 0.0:
            qz, qw = -qz, -qw
        self._publisher.publish(self._serializer.serialize(
            sec, nanosec, x, y, qz, qw, odometry.covariance_upper, twist, twist_covariance))
        if self._broadcaster is not None:
            transform = self._transform
            transform.header.stamp = self.encoder.stamp
            transform.transform.translation.x = x
            transform.transform.translation.y = y
            transform.transform.rotation.z = qz
            transform.transform.rotation.w = qw
            self._broadcaster.sendTransform(transform)
        return True

    def _reset(self) -> None:
        self.odometry.reset()
        self._last_publish_ns = None


def _long_lived_node() -> OdometryNode:
    node = OdometryNode()
    # Everything built so far (modules, messages' type support, the node) lives as long as
    # the process: take it out of the garbage collector's full passes, which otherwise stall
    # the callbacks for milliseconds now and then.
    gc.freeze()
    return node


def main(args=None):
    """Run odometry_node (console script ``odometry_node``)."""
    sys.exit(run(_long_lived_node, NODE_NAME, args, PARAMS, __doc__))
