"""Start odometry_node and cmd_vel_translator with one terrain parameter file."""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

DEFAULT_TERRAIN = 'auriga_alpha_hard_floor.yaml'


def generate_launch_description():
    """Both nodes of the package, configured by one terrain YAML (``params_file``)."""
    params_file = LaunchConfiguration('params_file')
    use_sim_time = LaunchConfiguration('use_sim_time')
    common = [params_file, {'use_sim_time': use_sim_time}]
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare('tracked_kinematics'), 'config', DEFAULT_TERRAIN]),
            description='Terrain parameter file (track_width, sprocket_radius, icr.*, scale.*, '
                        'and any node parameters) given to both nodes'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='Use /clock (simulation or bag replay)'),
        Node(package='tracked_kinematics', executable='odometry_node', name='odometry_node',
             parameters=common, output='screen'),
        Node(package='tracked_kinematics', executable='cmd_vel_translator',
             name='cmd_vel_translator', parameters=common, output='screen'),
    ])
