"""A file of convert_diff_drive_params, loaded by the nodes as ``--params-file`` loads it."""

import math
from pathlib import Path

from helpers.ddc_odometry import ddc_from_parameters, run_ddc
from helpers.encoder_stream import Driver, joint_state
from helpers.ros_helpers import spin_until
from nav_msgs.msg import Odometry as OdometryMsg
import numpy as np
import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from tracked_kinematics.offline.cli.convert_diff_drive_params import main
from tracked_kinematics.params import flatten
from tracked_kinematics.ros import cmd_vel_translator, icr_estimator, odometry_node
from tracked_kinematics.ros.main import params_file_keys, unknown_parameters
import yaml

pytestmark = pytest.mark.ros

HUSKY = Path(__file__).resolve().parents[1] / 'data' / 'ddc' / 'husky_style_controllers.yaml'
LEFT = ['front_left_wheel_joint', 'rear_left_wheel_joint']
RIGHT = ['front_right_wheel_joint', 'rear_right_wheel_joint']


@pytest.fixture
def converted(tmp_path):
    output = tmp_path / 'husky.yaml'
    assert main([str(HUSKY), '--output', str(output)]) == 0
    return output


@pytest.fixture
def context(converted):
    """Start a context as ``ros2 run ... --ros-args --params-file converted.yaml`` does."""
    import rclpy
    context = rclpy.Context()
    rclpy.init(context=context, args=['--ros-args', '--params-file', str(converted)])
    yield context
    rclpy.try_shutdown(context=context)


def test_each_node_gets_the_vehicle_and_its_own_section(context):
    odometry = odometry_node.OdometryNode(context=context)
    translator = cmd_vel_translator.CmdVelTranslator(context=context)
    try:
        for node in (odometry, translator):
            assert node.get_parameter('track_width').value == 0.512
            assert node.get_parameter('icr.y_left').value == 0.384
            assert node.get_parameter('icr.y_right').value == -0.384
            assert node.get_parameter('sprocket_radius').value == 0.1651
        assert odometry.get_parameter('left_joints').value == LEFT
        assert odometry.get_parameter('right_joints').value == RIGHT
        assert odometry.get_parameter('publish_rate').value == 50.0
        assert translator.get_parameter('linear.x.max_velocity').value == 1.0
        assert translator.get_parameter('angular.z.max_acceleration').value == 6.0
        assert translator.get_parameter('use_stamped').value is False
        assert odometry.odometry.icr.chi == pytest.approx(1 / 1.5)
    finally:
        translator.destroy_node()
        odometry.destroy_node()


@pytest.mark.parametrize('module', [odometry_node, icr_estimator])
def test_no_node_is_given_a_parameter_it_does_not_declare(converted, module):
    assert unknown_parameters(params_file_keys(str(converted), module.NODE_NAME),
                              module.PARAMS) == []


def test_translator_is_given_only_its_parameters(converted):
    keys = params_file_keys(str(converted), cmd_vel_translator.NODE_NAME)
    assert 'cmd_timeout' in keys and 'left_joints' not in keys
    assert unknown_parameters(keys, cmd_vel_translator.TRANSLATOR_PARAMS) == []


def test_odometry_on_topics_equals_ddc(context):
    # Two wheels a side, the joint_states of a joint_state_broadcaster at 50 Hz: the odom
    # odometry_node publishes ends where DDC's odometry.cpp ends on the same positions.
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor(context=context)
    node = odometry_node.OdometryNode(context=context)
    executor.add_node(node)
    try:
        driver = Driver(context, executor, lambda: node.encoder.received)
        odom = []
        driver.node.create_subscription(
            OdometryMsg, 'odom', odom.append,
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        assert spin_until(executor, lambda: node.count_subscribers('odom') >= 1)
        times = 20.0 + np.arange(151) / 50.0
        tau = times - times[0]
        speed_left = 0.4 - 0.5 * np.sin(tau)
        speed_right = 0.4 + 0.5 * np.sin(tau)
        angle_left = np.concatenate([[0.0], np.cumsum(speed_left[1:]) / 50.0]) / 0.1651
        angle_right = np.concatenate([[0.0], np.cumsum(speed_right[1:]) / 50.0]) / 0.1651
        # The rear wheels slip a little against the front ones; every side starts at 0 (DDC
        # integrates its first reading from 0, odometry_node from the first reading).
        wobble = 1e-3 * np.sin(3.0 * tau)
        left = np.stack([angle_left - wobble, angle_left + wobble], -1)
        right = np.stack([angle_right + wobble, angle_right - wobble], -1)
        for t, l_pos, r_pos in zip(times, left, right):
            assert driver.send(joint_state(t, [*l_pos, *r_pos], names=LEFT + RIGHT))
        assert spin_until(executor, lambda: odom and odom[-1].header.stamp.sec == 23
                          and odom[-1].header.stamp.nanosec == 0, 5.0)
        ddc = yaml.safe_load(HUSKY.read_text())['husky_velocity_controller']['ros__parameters']
        x, y, heading = run_ddc(ddc_from_parameters(flatten(ddc)), times, left, right)[-1]
        last = odom[-1].pose.pose
        assert last.position.x == pytest.approx(x, abs=1e-9)
        assert last.position.y == pytest.approx(y, abs=1e-9)
        yaw = 2.0 * math.atan2(last.orientation.z, last.orientation.w)
        assert math.remainder(yaw - heading, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
        assert math.hypot(x, y) > 0.5 and abs(heading) > 0.1
    finally:
        executor.shutdown()
        node.destroy_node()
