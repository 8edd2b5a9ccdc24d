"""ament_python build of tracked_kinematics (colcon on a robot, pip in a venv)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'tracked_kinematics'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/config/vehicles', glob('config/vehicles/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.py')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'pyyaml', 'rosbags', 'matplotlib', 'tqdm'],
    extras_require={'test': ['pytest', 'hypothesis']},
    zip_safe=True,
    maintainer='tracked_kinematics maintainers',
    maintainer_email='maintainers@tracked-kinematics.invalid',
    description='Slip-aware odometry, velocity control and ICR calibration for tracked robots.',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'tracked_kinematics_demo ='
            ' tracked_kinematics.offline.cli.tracked_kinematics_demo:main',
            'odometry_node = tracked_kinematics.ros.odometry_node:main',
            'cmd_vel_translator = tracked_kinematics.ros.cmd_vel_translator:main',
            'identify_icr = tracked_kinematics.offline.cli.identify_icr:main',
            'simulate_bag = tracked_kinematics.offline.cli.simulate_bag:main',
            'identify_drivetrain = tracked_kinematics.offline.cli.identify_drivetrain:main',
            'icr_map = tracked_kinematics.offline.cli.icr_map:main',
            'icr_estimator = tracked_kinematics.ros.icr_estimator:main',
            'plan_trajectory = tracked_kinematics.offline.cli.plan_trajectory:main',
            'convert_diff_drive_params ='
            ' tracked_kinematics.offline.cli.convert_diff_drive_params:main',
            'evaluate_model = tracked_kinematics.offline.cli.evaluate_model:main',
            'tracked_simulator = tracked_kinematics.ros.tracked_simulator:main',
            'calibration_drive = tracked_kinematics.apps.calibration_drive:main',
            'calibration_deadman = tracked_kinematics.ros.calibration_deadman:main',
            'play_bag = tracked_kinematics.apps.play_bag:main',
        ],
    },
)
