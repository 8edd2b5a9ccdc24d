"""
icr_estimator: online ICR estimation (EKF) and short-horizon prediction, as a node.

A thin adapter around :class:`~tracked_kinematics.core.estimate.ekf.SlipEstimator` and
:mod:`~tracked_kinematics.core.prediction`, with odometry_node's encoder input and a pose
source. See docs/nodes/icr_estimator.md.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
import math
import sys
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry, Path
import numpy as np
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from tracked_kinematics.core.estimate.ekf import EstimatorConfig, SlipEstimator
from tracked_kinematics.core.integration import (quaternion_from_yaw, seconds_to_stamp, stamp_ns,
                                                 yaw_from_quaternion)
from tracked_kinematics.core.kinematics import eccentricity, steering_efficiency
from tracked_kinematics.core.models import AdaptiveIcr, ConstantIcr
from tracked_kinematics.core.prediction import (
    commands_from_twist, hold_speeds, predict_from_commands, predict_path)
from tracked_kinematics.params import drivetrain_from_values, icr_from_values
from tracked_kinematics.params.node_tables import ESTIMATOR_POSE_TYPES, NODE_PARAMS
from tracked_kinematics.ros.encoder_input import (
    check_encoder_values, EncoderInput, WARN_PERIOD)
from tracked_kinematics.ros.health import Health
from tracked_kinematics.ros.icr_push import IcrPusher
from tracked_kinematics.ros.input_topic import CHECK_PERIOD, InputTopic, steady_timer
from tracked_kinematics.ros.main import run
from tracked_kinematics.ros.parameters import TableNode
from tracked_kinematics.ros.services import reset_service

NODE_NAME = 'icr_estimator'

POSE_TYPES = dict(zip(ESTIMATOR_POSE_TYPES,
                      (Odometry, PoseStamped, PoseWithCovarianceStamped, Imu), strict=True))
ICR_LAYOUT = ('y_left', 'y_right', 'x', 'chi', 'e')


# Longest predicted_path, in poses (prediction.horizon / prediction.dt).
MAX_PATH_POSES = 10_000

PARAMS = NODE_PARAMS[NODE_NAME]


def validate(values: Mapping[str, Any]) -> None:
    """Check the parameters as a whole; ValueError for a bad ICR model, encoders or windows."""
    icr_from_values(values)
    drivetrain_from_values(values)
    check_encoder_values(values)
    _config(values)
    poses = values['prediction.horizon'] / values['prediction.dt']
    if poses > MAX_PATH_POSES:
        raise ValueError(f'prediction.horizon / prediction.dt must be <= {MAX_PATH_POSES} '
                         f'poses, got {values["prediction.horizon"]:g} s / '
                         f'{values["prediction.dt"]:g} s = {poses:.6g}')


# Every field of EstimatorConfig is a parameter of the same name, but the noise model's: the
# terrain file's covariance.* (identify_icr writes them).
_NOISE_FIELDS = ('track_noise', 'turn_noise', 'slip_noise')
_CONFIG_FIELDS = tuple(f for f in EstimatorConfig.__dataclass_fields__ if f not in _NOISE_FIELDS)


def _config(values: Mapping[str, Any]) -> EstimatorConfig:
    track = 0.5 * (values['covariance.k_left'] + values['covariance.k_right'])
    return EstimatorConfig(**{name: values[name] for name in _CONFIG_FIELDS},
                           track_noise=track, turn_noise=values['covariance.turn'],
                           slip_noise=values['covariance.slip'])


def _yaw(q) -> float:
    return yaw_from_quaternion(q.x, q.y, q.z, q.w)


def _seconds(stamp) -> float:
    return stamp_ns(stamp.sec, stamp.nanosec) * 1e-9


def _stamp(seconds: float) -> Time:
    sec, nanosec = seconds_to_stamp(seconds)
    return Time(sec=sec, nanosec=nanosec)


class IcrEstimatorNode(TableNode):
    """
    Online ICR estimation and motion prediction for a tracked vehicle.

    A :class:`~tracked_kinematics.ros.parameters.TableNode` of :data:`PARAMS`; ``ParameterError``
    when the parameters given at start are invalid.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, PARAMS, validate, **kwargs)

    def _start(self, values: Mapping[str, Any]) -> None:
        self.encoder = None
        self._timer = None
        self.estimator = self._build_estimator(values)
        self.counts: Counter = Counter()
        self._logged: dict[str, int] = {}
        self._frame = ''
        self._command = None
        self._pusher = IcrPusher(self, lambda target, icr: self.counts.update(('pushed',)))
        self._apply(values)
        self.encoder = EncoderInput(self, values, self._on_step)
        pose_type = POSE_TYPES[values['pose_type']]
        self._inputs = [InputTopic(self, pose_type, values['pose_topic'], self._on_pose)]
        self._pose_sub = self._inputs[0]
        if values['prediction.source'] == 'cmd_vel':
            self._inputs.append(InputTopic(self, Twist, 'cmd_vel', self._on_cmd_vel, 10))
        # Health on /diagnostics: the encoders and the pose are needed, cmd_vel is not.
        self.health = Health(self, timer=False)  # updated by _check_inputs
        self.health.watch(*self.encoder.inputs, self._pose_sub)
        self.health.watch(*self._inputs[1:], needed=False)
        self._check_timer = steady_timer(self, CHECK_PERIOD, self._check_inputs)
        self._icr_pub = self.create_publisher(Float64MultiArray, 'icr_estimate', 10)
        self._path_pub = self.create_publisher(Path, 'predicted_path', 10)
        self._timer = self.create_timer(1.0 / values['publish_rate'], self._on_timer)
        reset_service(self, self._reset, 'ICR estimate reset to the initial parameters')
        model = self.estimator.model
        self.get_logger().info(
            f'estimating {model.name} ({", ".join(model.param_names)}) from '
            f'{self._pose_sub.topic_name} ({values["pose_type"]}'
            + (', heading only' if self._heading_only else '') + f') and '
            f'{self.encoder.describe()}; publishing {self._icr_pub.topic_name} and '
            f'{self._path_pub.topic_name} at {values["publish_rate"]:g} Hz'
            + (f', pushing to {", ".join(values["push_to"])}' if values['push_to'] else ''))

    @property
    def _heading_only(self) -> bool:
        return self.params['heading_only'] or self.params['pose_type'] == 'imu'

    @staticmethod
    def _build_estimator(values: Mapping[str, Any]) -> SlipEstimator:
        """Return a filter starting from the terrain file's ICRs (``model: icr``) or ideal."""
        icr = icr_from_values(values)
        if values['model'] == 'icr':
            model = ConstantIcr(icr.track_width, with_scales=False)
            return SlipEstimator(model, model.from_icr(icr), _config(values))
        return SlipEstimator(AdaptiveIcr(icr.track_width), None, _config(values))

    def _apply(self, values: Mapping[str, Any]) -> None:
        """Take new values into use (a new ``track_width`` restarts the estimate)."""
        icr = icr_from_values(values)
        self._scales = (icr.scale_left, icr.scale_right)
        self._drivetrain = drivetrain_from_values(values)
        if icr.track_width != self.estimator.model.track_width:
            self.estimator = self._build_estimator(values)
            self.get_logger().info(f'track_width is now {icr.track_width:g} m: estimate '
                                   'restarted from the icr.* values')
        else:
            self.estimator.configure(_config(values))
            if isinstance(self.estimator.model, ConstantIcr):
                self.estimator.set_initial(self.estimator.model.from_icr(icr))
        if self.encoder is not None:
            self.encoder.configure(values)
        period_ns = round(1e9 / values['publish_rate'])
        if self._timer is not None and self._timer.timer_period_ns != period_ns:
            # rclpy cannot change a timer's period: a new timer takes effect at once.
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(period_ns * 1e-9, self._on_timer)

    # --- inputs -------------------------------------------------------------------------

    def _check_inputs(self) -> None:
        for topic in self._inputs:
            topic.check()
        self.health.update()

    def _on_step(self, stamp_s: float, d_left: float, d_right: float, dt: float) -> None:
        try:
            with np.errstate(all='ignore'):
                outcome = self.estimator.add_step(stamp_s, self._scales[0] * d_left,
                                                  self._scales[1] * d_right, dt)
        except (ValueError, ArithmeticError) as err:
            self.get_logger().warning(f'encoder step skipped by the estimator: {err}',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        if outcome is not None:
            self._report(outcome)
        self._check_estimate()

    def _check_estimate(self) -> None:
        """Restart a filter whose state is no longer finite (it would never recover)."""
        estimator = self.estimator
        if np.all(np.isfinite(estimator.p)) and np.all(np.isfinite(estimator.P)):
            return
        estimator.reset()
        self.counts['restarted'] += 1
        self.get_logger().warning('the estimate became non-finite (absurd input): restarted '
                                  'from the initial parameters',
                                  throttle_duration_sec=WARN_PERIOD)

    def _on_pose(self, msg) -> None:
        self.counts['received'] += 1
        t = _seconds(msg.header.stamp)
        if t == 0.0:
            self.counts['zero_stamp'] += 1
            self.get_logger().warning('pose message with a zero stamp: skipped',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        if isinstance(msg, Imu):
            yaw = _yaw(msg.orientation)
            position = None
        else:
            pose = msg.pose if isinstance(msg, PoseStamped) else msg.pose.pose
            yaw = _yaw(pose.orientation)
            position = (pose.position.x, pose.position.y)
        self._frame = msg.header.frame_id
        try:
            with np.errstate(all='ignore'):
                if position is None or self._heading_only:
                    outcome = self.estimator.add_heading(t, yaw)
                else:
                    outcome = self.estimator.add_pose(t, position[0], position[1], yaw)
        except (ValueError, ArithmeticError) as err:
            self.get_logger().warning(f'pose measurement skipped by the estimator: {err}',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        self._report(outcome)
        self._check_estimate()

    def _report(self, outcome) -> None:
        """Count an outcome; log refusals, at most once per WARN_PERIOD for each kind."""
        self.counts[outcome.status] += 1
        if not (outcome.refused or outcome.status in ('anchored', 'gap')):
            return
        now = self.get_clock().now().nanoseconds
        last = self._logged.get(outcome.status)
        if last is not None and now - last < WARN_PERIOD * 1e9:
            return
        self._logged[outcome.status] = now
        if outcome.refused:
            self.get_logger().warning(
                f'pose measurement refused ({outcome.status}): {outcome.reason}')
        else:
            self.get_logger().info(outcome.reason)

    def _on_cmd_vel(self, msg) -> None:
        command = (msg.linear.x, msg.angular.z)
        if not all(map(math.isfinite, command)):
            self.get_logger().warning(f'non-finite cmd_vel {command}: ignored',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        self._command = command

    def _reset(self) -> None:
        self.estimator.reset()
        self._pusher.reset()

    # --- outputs ------------------------------------------------------------------------

    def _on_timer(self) -> None:
        with np.errstate(all='ignore'):
            self._publish_outputs()

    def _publish_outputs(self) -> None:
        icr = self._current_icr()
        if icr is not None:
            self._publish_icr(icr)
        if self.params['prediction.horizon'] > 0.0:
            self._publish_path()
        if self.params['push_to'] and icr is not None:
            self._push(icr)

    def _current_icr(self):
        try:
            y_left, y_right, x = (float(v) for v in self.estimator.icr())
        except (ValueError, ArithmeticError):
            return None
        if not all(map(math.isfinite, (y_left, y_right, x))) or y_left <= y_right:
            return None
        return y_left, y_right, x

    def _publish_icr(self, icr) -> None:
        y_left, y_right, x = icr
        data = [y_left, y_right, x,
                steering_efficiency(self.estimator.model.track_width, y_left, y_right),
                eccentricity(y_left, y_right)]
        if not all(map(math.isfinite, data)):
            return
        msg = Float64MultiArray()
        msg.layout.dim = [MultiArrayDimension(label=','.join(ICR_LAYOUT), size=5, stride=5)]
        msg.data = data
        self._icr_pub.publish(msg)

    def _publish_path(self) -> None:
        now = self.estimator.pose_now()
        if now is None:
            return
        t0, x, y, yaw = now
        values = self.params.values
        horizon, dt = values['prediction.horizon'], values['prediction.dt']
        est = self.estimator
        try:
            if values['prediction.source'] == 'cmd_vel' and self._command is not None:
                icr = est.icr_params(scales=self._scales)
                if icr is None:
                    return
                left, right = commands_from_twist(*self._command, icr, horizon, dt)
                # Nominal setpoints back to true speeds: the estimator works in true speeds.
                pred = predict_from_commands(est.model, est.p, self._drivetrain,
                                             self._scales[0] * left, self._scales[1] * right,
                                             dt, speeds0=est.last_speeds, pose0=(x, y, yaw))
            else:
                left, right = hold_speeds(*est.last_speeds, horizon, dt)
                pred = predict_path(est.model, est.p, left, right, dt, pose0=(x, y, yaw))
        except (ValueError, ArithmeticError) as err:
            self.get_logger().warning(f'no prediction: {err}', throttle_duration_sec=WARN_PERIOD)
            return
        if not pred.poses.size or not bool(
                all(map(math.isfinite, pred.poses.ravel().tolist()))):
            self.get_logger().warning('non-finite prediction not published',
                                      throttle_duration_sec=WARN_PERIOD)
            return
        path = Path()
        path.header.stamp = _stamp(t0)
        path.header.frame_id = self._frame
        for t, (px, py, pyaw) in zip(pred.t, pred.poses.tolist()):
            pose = PoseStamped()
            pose.header.stamp = _stamp(t0 + float(t))
            pose.header.frame_id = self._frame
            pose.pose.position.x = px
            pose.pose.position.y = py
            _, _, pose.pose.orientation.z, pose.pose.orientation.w = quaternion_from_yaw(pyaw)
            path.poses.append(pose)
        self._path_pub.publish(path)

    def _push(self, icr) -> None:
        y_left, y_right, x = icr
        values = self.params.values
        if steering_efficiency(self.estimator.model.track_width, y_left, y_right) > 1.0:
            return  # chi > 1 is not a physical terrain; the nodes would refuse it
        if isinstance(self.estimator.model, AdaptiveIcr):
            v_left, v_right = self.estimator.last_speeds
            if abs(v_right - v_left) < 0.05 * max(abs(v_left), abs(v_right), 0.1):
                return  # straight: the ICRs are not observable, keep the last pushed ones
        self._pusher.push(icr, values)


def main(args=None):
    """Run icr_estimator (console script ``icr_estimator``)."""
    sys.exit(run(IcrEstimatorNode, NODE_NAME, args, PARAMS, __doc__))
