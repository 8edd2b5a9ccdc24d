"""
Start odometry_node and cmd_vel_translator with one terrain parameter file.

``params_file`` is required: there is no default vehicle (a node without ``track_width`` and
``sprocket_radius`` refuses to start, and so does this launch without the robot's own file).
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PARAMS_FILE_HINT = ('the terrain file of your robot (identify_icr or calibration_drive writes '
                    'one): params_file:=/path/to/my_robot_grass.yaml')


def check_params_file(context):
    """Refuse to start unless ``params_file`` names an existing file; nothing to launch."""
    path = LaunchConfiguration('params_file').perform(context)
    if not path.strip():
        raise RuntimeError(f'params_file is empty: give {PARAMS_FILE_HINT}')
    if not os.path.isfile(os.path.expanduser(path)):
        raise RuntimeError(f'params_file {path!r} is not a file: give {PARAMS_FILE_HINT}')
    return []


def generate_launch_description():
    """Both nodes of the package, configured by one terrain YAML (``params_file``, required)."""
    params_file = LaunchConfiguration('params_file')
    use_sim_time = LaunchConfiguration('use_sim_time')
    common = [params_file, {'use_sim_time': use_sim_time}]
    return LaunchDescription([
        # No default_value: launch refuses to start without it, naming params_file.
        DeclareLaunchArgument(
            'params_file',
            description='Required. Terrain parameter file of the robot (track_width, '
                        'sprocket_radius, icr.*, scale.*, and any node parameters) given to '
                        'both nodes; there is no default vehicle'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='Use /clock (simulation or bag replay)'),
        OpaqueFunction(function=check_params_file),
        Node(package='tracked_kinematics', executable='odometry_node', name='odometry_node',
             parameters=common, output='screen'),
        Node(package='tracked_kinematics', executable='cmd_vel_translator',
             name='cmd_vel_translator', parameters=common, output='screen'),
    ])
