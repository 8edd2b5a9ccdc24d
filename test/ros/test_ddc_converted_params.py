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
from tracked_kinematics.offline.ddc import NODE_KEYS, TERRAIN_KEYS
from tracked_kinematics.params import flatten, read_params_file
from tracked_kinematics.ros import (calibration_drive_node, cmd_vel_translator, icr_estimator,
                                    odometry_node, tracked_simulator)
from tracked_kinematics.ros.main import params_file_keys, unknown_parameters
from tracked_kinematics.ros.parameters import package_parameters
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


@pytest.mark.parametrize('module', [odometry_node, icr_estimator, cmd_vel_translator,
                                    calibration_drive_node, tracked_simulator])
def test_no_node_is_given_a_parameter_no_node_declares(converted, module):
    # One file for every node of the package: a key another node declares is not unknown.
    specs = getattr(module, 'PARAMS', None) or getattr(module, 'TRANSLATOR_PARAMS', None) \
        or module.SIMULATOR_PARAMS
    keys = params_file_keys(str(converted), module.NODE_NAME)
    assert unknown_parameters(keys, specs) == []


def test_calibration_drive_reads_the_joints_of_the_converted_file(converted):
    # Issue 31 item 1: calibration_drive fell back to left_sprocket_joint.
    assert read_params_file(converted, calibration_drive_node.NODE_NAME)['left_joints'] == LEFT
    assert read_params_file(converted, calibration_drive_node.NODE_NAME)['right_joints'] == RIGHT


def test_a_node_section_holds_only_what_another_node_reads_otherwise():
    # The converter writes under /** every key that means the same to every node that
    # declares it; a key under /**/<node> is one another node declares with another default.
    tables = package_parameters()
    node_keys = {key for keys in NODE_KEYS.values() for key in keys}
    ddc_keys = [*TERRAIN_KEYS, 'left_joints', 'right_joints', 'odom_frame', 'base_frame',
                'publish_tf', 'publish_rate', 'cmd_timeout', 'use_stamped',
                *(f'{axis}.max_{kind}' for axis in ('linear.x', 'angular.z')
                  for kind in ('velocity', 'acceleration'))]
    for key in ddc_keys:
        defaults = {repr(spec.default) for specs in tables.values() for spec in specs
                    if spec.name == key}
        assert defaults, key
        assert (len(defaults) > 1) == (key in node_keys), (key, defaults)
    for node, keys in NODE_KEYS.items():
        assert set(keys) <= {spec.name for spec in tables[node]}


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
