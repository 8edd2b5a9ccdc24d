"""
odometry_node: track encoders to nav_msgs/Odometry through the tread-ICR kinematics.

A thin adapter: :class:`~tracked_kinematics.ros.encoder_input.EncoderInput` gives travel
steps, :class:`~tracked_kinematics.core.odometry.Odometry` integrates them (or, with an
``imu_topic``, :class:`~tracked_kinematics.core.gyro.GyroOdometry`, fed the gyro's
samples too; both called the same way), this node fills ``odom`` and the transform. See
docs/nodes/odometry_node.md.
"""

from __future__ import annotations

from collections.abc import Mapping
import gc
import math
import sys
from typing import Any

from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry as OdometryMsg
from rclpy.exceptions import InvalidHandle
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from tracked_kinematics.core.covariance import message_twist_covariance
from tracked_kinematics.core.gyro import ENCODERS, ERROR as GYRO_ERROR, GYRO, GyroOdometry
from tracked_kinematics.core.gyro import NOT_A_FAULT
from tracked_kinematics.core.integration import quaternion_from_yaw
from tracked_kinematics.core.kinematics import eccentricity, IcrParams, steering_efficiency
from tracked_kinematics.core.noise_model import NoiseModel
from tracked_kinematics.core.odometry import Odometry
from tracked_kinematics.params import (gyro_config_from_values, gyro_noise_model_from_values,
                                       icr_from_values, noise_model_from_values,
                                       TERRAIN_PARAMS, track_noise_from_values)
from tracked_kinematics.params.node_tables import NODE_PARAMS
from tracked_kinematics.ros.encoder_input import (
    check_encoder_values, EncoderInput, WARN_PERIOD)
from tracked_kinematics.ros.health import ERROR, Health, WARN
from tracked_kinematics.ros.icr_push import IcrPusher
from tracked_kinematics.ros.imu_input import ImuInput
from tracked_kinematics.ros.imu_reader import raw_stamp_key
from tracked_kinematics.ros.input_topic import CHECK_PERIOD, InputTopic, steady_timer
from tracked_kinematics.ros.main import run
from tracked_kinematics.ros.odometry_message import OdometrySerializer
from tracked_kinematics.ros.parameters import TableNode
from tracked_kinematics.ros.services import reset_service

NODE_NAME = 'odometry_node'


#: Labels of the ``~/icr`` message, icr_estimator's ``icr_estimate`` layout.
ICR_LAYOUT = ('y_left', 'y_right', 'x', 'chi', 'e')

# Reasons the gyro is not used that are no fault of the IMU (no warning, no WARN level).
_NOT_A_FAULT = NOT_A_FAULT


PARAMS = NODE_PARAMS[NODE_NAME]


def _terms(values: Mapping[str, Any]) -> NoiseModel:
    """Return the turn, slip, timing and scale terms (the tracks' are the random walk's)."""
    return noise_model_from_values(values).without_tracks()


def _gyro_terms(values: Mapping[str, Any]) -> NoiseModel:
    """Return the terms while the heading is the gyro's (``covariance.gyro_aided.*``)."""
    return gyro_noise_model_from_values(values).without_tracks()


gyro_config = gyro_config_from_values
"""How the node reads its gyro (:func:`~tracked_kinematics.params.gyro_config_from_values`)."""


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
        self._gyro = bool(values['imu_topic'])
        noise = track_noise_from_values(values)
        if self._gyro:
            self.odometry = GyroOdometry(self._icr(values), gyro_config(values), noise,
                                         _terms(values))
        else:
            self.odometry = Odometry(self._icr(values), noise, _terms(values))
        self._source = ENCODERS
        self._pusher = None
        self.imu = None
        self._publisher = self.create_publisher(
            OdometryMsg, 'odom', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self._serializer = None
        self._broadcaster = None
        self._transform = None
        self._tf_warned = False
        self._last_publish_ns = None
        self._twist_span = 0.0  # s of encoder steps since the last published twist
        self.encoder = None
        self._imu_input = ImuInput(self, values) if self._gyro else None
        self._apply(values)
        self.encoder = EncoderInput(self, values, self._on_step, check_timer=False)
        self.health = Health(self, timer=False)  # updated by _check, on the timer below
        self.health.watch(*self.encoder.inputs)
        self.health.add(self._report_heading)
        if self._gyro:
            # The gyro is not needed (the encoders carry on without it): its absence is the
            # heading source's WARN, not an ERROR.
            self._imu_reader = self._imu_input.reader
            self.imu = InputTopic(self, Imu, values['imu_topic'], self._on_imu,
                                  order_key=raw_stamp_key, raw=True)
            self.health.watch(self.imu, needed=False)
            self._imu_input.topic = self.imu
            self.health.add(self._imu_input.report)
            self._icr_publisher = self.create_publisher(Float64MultiArray, '~/icr', 10)
            self._pusher = IcrPusher(self)
            self._pusher.pushed = self._model_icrs()
            self._pusher.prepare(values['push_to'])
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
            + ('' if self._broadcaster is None else ' with TF')
            + ('' if self.imu is None else
               f'; heading from the gyro on {self.imu.topic_name} (imu_delay '
               f'{values["imu_delay"]:g} s, gyro_scale {values["gyro_scale"]:g}, slip '
               + ('adapted' if values['adapt_slip'] else 'not adapted')
               + (f', pushed to {", ".join(values["push_to"])}' if values['push_to'] else '')
               + ')'))

    def _check(self) -> None:
        self.encoder.check()
        if self.imu is not None:
            self.imu.check()
            self._publish_icr()
        self._check_output()
        self.health.update()

    def _model_icrs(self) -> tuple:
        icr = self.odometry.model
        return (icr.y_left, icr.y_right, icr.x)

    def _publish_icr(self) -> None:
        """Publish the ICRs in force on ``~/icr`` (adapted or not); push them if asked to."""
        icr = self.odometry.icr
        data = [icr.y_left, icr.y_right, icr.x,
                steering_efficiency(icr.track_width, icr.y_left, icr.y_right),
                eccentricity(icr.y_left, icr.y_right)]
        if not all(map(math.isfinite, data)):
            return
        msg = Float64MultiArray()
        msg.layout.dim = [MultiArrayDimension(label=','.join(ICR_LAYOUT), size=5, stride=5)]
        msg.data = data
        self._icr_publisher.publish(msg)
        # A gyro refused (it disagrees with the tracks) adapts nothing and pushes nothing.
        if data[3] <= 1.0 and self.odometry.level != GYRO_ERROR:
            self._pusher.push(tuple(data[:3]), self.params.values)

    def _report_heading(self, report) -> None:
        """Add the heading source (and the gyro's state) to the node's health."""
        odometry = self.odometry
        if self.imu is None:
            report.add('heading source', ENCODERS)
            report.add('heading source reason', 'imu_topic is empty')
            return
        reason = odometry.reason
        report.add('heading source', odometry.source)
        report.add('heading source reason', reason or 'the gyro is healthy, its bias known')
        report.add('gyro bias (rad/s)', f'{odometry.bias:.6g}')
        report.add('gyro bias sigma (rad/s)', f'{odometry.bias_std:.3g}')
        report.add('gyro against the tracks', f'{odometry.check.verdict} (ratio '
                   f'{odometry.check.ratio:.3g})')
        report.add('gyro noise (rad/s/sqrt(Hz))', f'{odometry.gyro_noise:.3g}')
        icr = odometry.icr
        report.add('icr.y_left in force (m)', f'{icr.y_left:.6g}')
        report.add('icr.y_right in force (m)', f'{icr.y_right:.6g}')
        report.add('icr.x in force (m)', f'{icr.x:.6g}')
        report.add('heading source switches', odometry.switches)
        if self._pusher.count:
            report.add('icr pushes accepted', self._pusher.count)
        if odometry.level == GYRO_ERROR:
            report.merge(ERROR, f'gyro refused, heading from the encoders: {reason}')
        elif odometry.source == ENCODERS and not reason.startswith(_NOT_A_FAULT):
            report.merge(WARN, f'heading from the encoders: {reason}')

    def _take_imu(self) -> None:
        """
        Take the Imu messages that wait, in this encoder message's turn of the executor.

        A turn costs far more than the message (the IMU's own turns cost the flood about as
        much per message as an encoder message); a take that finds none costs about 1 us.
        Not while the input switches subscriptions (it orders the two then).
        """
        imu = self.imu
        if imu.switching:
            return
        handle = imu.subscription.handle
        count = imu.count
        while True:
            try:
                with handle:
                    taken = handle.take_message(Imu, True)
            except InvalidHandle:  # destroyed: the node is shutting down
                return
            if taken is None:
                return
            count.tick()
            self._on_imu(taken[0])

    def _on_imu(self, data: bytes) -> None:
        sample = self._imu_input.take(data)  # (t, heading rate), or None: not to be used
        if sample is not None:
            self._gyro_sample(sample)

    def _gyro_sample(self, sample) -> None:
        samples = self.odometry.samples
        dropped = samples.dropped
        self._imu_input.taken(self.odometry.imu(*sample), self.odometry.reason,
                              samples.dropped - dropped)
        if self.odometry.source != self._source:
            self._switched()

    def _switched(self) -> None:
        """Say once (throttled) that the heading source changed, and why."""
        source = self._source = self.odometry.source
        if source == GYRO:
            self.get_logger().info(f'heading from the gyro ({self.imu.topic_name})',
                                   throttle_duration_sec=WARN_PERIOD)
            return
        reason = self.odometry.reason
        if reason.startswith(_NOT_A_FAULT):
            return
        self.get_logger().warning(
            f'{self.imu.topic_name}: {reason}: heading from the encoders until the gyro is '
            'healthy again (the pose continues, no jump)', throttle_duration_sec=WARN_PERIOD)

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
        odometry = self.odometry
        terms = _terms(values)
        gyro_terms = _gyro_terms(values) if self._gyro else None
        odometry.set_timing(terms, gyro_terms)
        if self._imu_input is not None:
            self._imu_input.configure(values)
        if self._gyro:
            icr = self._icr(values)
            if icr != odometry.model:
                odometry.set_model(icr)  # the adaptation restarts from the new model
                if self._pusher is not None:
                    self._pusher.pushed = self._model_icrs()
            odometry.config = gyro_config(values)
            odometry.set_noise(track_noise_from_values(values), terms, gyro_terms)
        else:
            odometry.set_model(self._icr(values), track_noise_from_values(values), terms)
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
        if self._gyro:
            for sample in self._imu_input.encoder_step(self.encoder.stamp_ns):
                self._gyro_sample(sample)   # held until an encoder step
            self._take_imu()
            # On the gyro's time origin (whole seconds): epoch seconds lose precision.
            reader = self._imu_reader
            stamp_ns = self.encoder.stamp_ns
            if reader.origin is None:
                reader.origin = stamp_ns // 1_000_000_000
            t = (stamp_ns - reader.origin * 1_000_000_000) * 1e-9
        else:
            t = stamp_s
        accepted = self.odometry.step(t, d_left, d_right, dt)
        if self.odometry.source != self._source:
            self._switched()
        if not accepted:
            self.get_logger().warning(
                f'encoder step refused by the odometry (travel {d_left!r}, {d_right!r} m over '
                f'{dt!r} s: beyond 1e9 m, or a speed or pose that is not finite): skipped, '
                'nothing integrated or published', throttle_duration_sec=WARN_PERIOD)
            return
        self._twist_span += dt
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
        # The core's publish: the pose covariance with the time error at both ends of the
        # interval since the last reset, as evaluate_model scores it.
        (x, y, theta), pose_covariance, twist, twist_covariance = self.odometry.publish()
        # Per message: the covariance of the mean over the message's own interval, so that a
        # filter fusing every message believes the odometry as much at any rate.
        twist_covariance = message_twist_covariance(twist_covariance, self._twist_span)
        self._twist_span = 0.0
        if not all(map(math.isfinite, twist + twist_covariance)):
            self.get_logger().warning(
                f'non-finite twist {twist} not published', throttle_duration_sec=WARN_PERIOD)
            return False
        # The yaw as a quaternion with w >= 0 (theta itself is continuous, not wrapped).
        _, _, qz, qw = quaternion_from_yaw(theta)
        if qw < 0.0:
            qz, qw = -qz, -qw
        self._publisher.publish(self._serializer.serialize(
            sec, nanosec, x, y, qz, qw, pose_covariance, twist, twist_covariance))
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
        # The pose and its accumulated covariance are zero; the core keeps the time error at
        # the start (the rates then, in the new frame). The twist window restarts too.
        self.odometry.reset()
        self._twist_span = 0.0
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
