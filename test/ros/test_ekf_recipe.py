"""
The robot_localization recipe (config/robot_localization_ekf.yaml) against the node it fuses.

Every key of the EKF's block is one robot_localization's ekf_node declares; its topic and
frames are odometry_node's; it fuses the twist only; and odometry_node's ``publish_tf: false``
lives in a file of its own, scoped to odometry_node (issue 37, item 3).
"""

from pathlib import Path

import pytest
from rclpy.parameter import Parameter
from tracked_kinematics.params import read_params_file
from tracked_kinematics.ros.odometry_node import OdometryNode, PARAMS
from tracked_kinematics.share import config_file
import yaml

ROOT = Path(__file__).resolve().parents[2]
EKF = ROOT / 'config' / 'robot_localization_ekf.yaml'
OVERLAY = ROOT / 'config' / 'odometry_node_for_ekf.yaml'

# The parameters of robot_localization's params/ekf.yaml (ros2 / jazzy-devel branches of
# github.com/cra-ros-pkg/robot_localization), the sensor ones for index 0.
ROBOT_LOCALIZATION = frozenset("""
    frequency sensor_timeout two_d_mode transform_time_offset transform_timeout
    print_diagnostics debug debug_out_file publish_tf publish_acceleration
    permit_corrected_publication map_frame odom_frame base_link_frame world_frame
    odom0 odom0_config odom0_queue_size odom0_differential odom0_relative
    odom0_pose_use_child_frame odom0_pose_rejection_threshold odom0_twist_rejection_threshold
    imu0 imu0_config imu0_differential imu0_relative imu0_queue_size
    imu0_pose_rejection_threshold imu0_twist_rejection_threshold
    imu0_linear_acceleration_rejection_threshold imu0_remove_gravitational_acceleration
    use_control stamped_control control_timeout control_config acceleration_limits
    acceleration_gains deceleration_limits deceleration_gains process_noise_covariance
    initial_estimate_covariance smooth_lagged_data history_length
""".split())

# robot_localization's measurement vector: x y z roll pitch yaw vx vy vz vroll vpitch vyaw ax
# ay az.
TWIST = (6, 7, 11)   # vx, vy, vyaw


def ekf_block():
    doc = yaml.safe_load(EKF.read_text())
    assert list(doc) == ['ekf_filter_node'], 'the EKF file holds the EKF block only'
    return doc['ekf_filter_node']['ros__parameters']


def test_every_key_is_robot_localization_s():
    params = ekf_block()
    assert set(params) <= ROBOT_LOCALIZATION, set(params) - ROBOT_LOCALIZATION


def test_the_twist_is_fused_not_the_pose():
    params = ekf_block()
    config = params['odom0_config']
    assert len(config) == 15 and all(isinstance(flag, bool) for flag in config)
    assert [k for k, flag in enumerate(config) if flag] == list(TWIST)
    assert params['odom0_differential'] is False and params['two_d_mode'] is True
    # The EKF publishes the transform; no imu0 beside the node's gyro (counted twice).
    assert params.get('publish_tf', True) is True
    assert not any(key.startswith('imu') for key in params)


def test_publish_tf_false_is_odometry_node_s_alone():
    """The node's publish_tf: false is scoped to odometry_node: it cannot silence the EKF."""
    doc = yaml.safe_load(OVERLAY.read_text())
    assert list(doc) == ['odometry_node']
    assert read_params_file(OVERLAY, 'odometry_node')['publish_tf'] is False
    assert 'publish_tf' not in read_params_file(OVERLAY)   # no /** section
    assert 'publish_tf' not in read_params_file(EKF, 'odometry_node')
    names = {spec.name for spec in PARAMS}
    assert set(read_params_file(OVERLAY, 'odometry_node')) <= names


@pytest.mark.ros
def test_the_topic_and_frames_are_the_node_s(ros_context):
    """odometry_node started with a terrain file and the overlay publishes what odom0 reads."""
    values = {**read_params_file(config_file('auriga_alpha_hard_floor.yaml')),
              **read_params_file(OVERLAY, 'odometry_node')}
    values = {k: v for k, v in values.items() if k not in ('terrain', 'source')}
    node = OdometryNode(context=ros_context, parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()])
    try:
        params = ekf_block()
        assert node.get_publishers_info_by_topic(params['odom0'])
        assert params['odom_frame'] == params['world_frame'] == \
            node.get_parameter('odom_frame').value
        assert params['base_link_frame'] == node.get_parameter('base_frame').value
        assert node.get_parameter('publish_tf').value is False
        assert node.get_parameter('publish_rate').value == params['frequency']
    finally:
        node.destroy_node()


def test_the_docs_give_the_recipe_and_the_gyro_delay():
    text = (ROOT / 'docs' / 'nodes' / 'odometry_node.md').read_text()
    section = text.split('## Using it with robot_localization')[1].split('\n## ')[0]
    for name in ('config/robot_localization_ekf.yaml', 'config/odometry_node_for_ekf.yaml',
                 'imu_delay', 'imu0'):
        assert name in section, name
    # No block to copy that sets publish_tf: false for every node, or beside the EKF's.
    for block in section.split('```')[1::2]:
        if 'publish_tf: false' in block:
            assert '/**' not in block and 'ekf_filter_node' not in block, block


@pytest.mark.ros
def test_the_console_script_takes_the_two_files(tmp_path):
    """As the docs launch it: the terrain file, then the overlay; no transform, 30 Hz."""
    import time
    from helpers.ros_helpers import ConsoleScript
    terrain = config_file('auriga_alpha_hard_floor.yaml')
    with ConsoleScript('odometry_node', '--ros-args', '--params-file', terrain,
                       '--params-file', OVERLAY, tmp_path=tmp_path) as script:
        deadline = time.monotonic() + 30.0
        while 'ICR model' not in script.output and script.process.poll() is None \
                and time.monotonic() < deadline:
            time.sleep(0.05)   # polls the condition (test_main's pattern)
        assert script.stop() == 0, script.output
    assert 'publishing /odom (odom -> base_link) at up to 30 Hz\n' in script.output
    assert 'with TF' not in script.output and 'tf2_ros cannot be imported' not in script.output
