"""Drive the package's nodes without a robot: tracked_simulator + translator + odometry."""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

DEFAULT_TERRAIN = 'auriga_alpha_hard_floor.yaml'
DEFAULT_VEHICLE = 'auriga_alpha'


def generate_launch_description():
    """
    Start the simulator on /clock and the two robot nodes in simulated time.

    ``cmd_vel`` (teleop, Nav2) -> cmd_vel_translator -> track setpoints -> tracked_simulator
    -> joint_states -> odometry_node -> ``odom`` and TF; ``ground_truth/odom`` is the true pose
    to compare with in RViz.
    """
    params_file = LaunchConfiguration('params_file')
    sim_time = {'use_sim_time': True}
    return LaunchDescription([
        DeclareLaunchArgument(
            'vehicle', default_value=DEFAULT_VEHICLE,
            description='Simulated vehicle: a shipped name (auriga_alpha, packbot) or a path'),
        DeclareLaunchArgument(
            'terrain', default_value='hard_floor',
            description='Simulated terrain (hard_floor, asphalt, gravel, grass, ice); '
                        'ros2 param set /tracked_simulator terrain NAME changes it live'),
        DeclareLaunchArgument(
            'real_time_factor', default_value='1.0',
            description='Simulated seconds per wall-clock second'),
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution(
                [FindPackageShare('tracked_kinematics'), 'config', DEFAULT_TERRAIN]),
            description='Terrain parameter file of cmd_vel_translator and odometry_node '
                        '(the model the robot believes; the default is identified on the '
                        'simulated auriga_alpha on hard_floor)'),
        Node(package='tracked_kinematics', executable='tracked_simulator',
             name='tracked_simulator', output='screen',
             parameters=[{'vehicle': LaunchConfiguration('vehicle'),
                          'terrain': LaunchConfiguration('terrain'),
                          'real_time_factor': LaunchConfiguration('real_time_factor')}]),
        Node(package='tracked_kinematics', executable='cmd_vel_translator',
             name='cmd_vel_translator', parameters=[params_file, sim_time], output='screen'),
        Node(package='tracked_kinematics', executable='odometry_node', name='odometry_node',
             parameters=[params_file, sim_time], output='screen'),
    ])
