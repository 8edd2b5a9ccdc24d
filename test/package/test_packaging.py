"""
The package installs as ament_python with colcon and with pip.

The house rule: package.xml of format 3, setup.py ``data_files`` for resource/, config/ and
launch/, and setup.cfg script directories so that ``ros2 run`` finds the console scripts.
"""

import importlib
import os
from pathlib import Path
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

from helpers.setup_info import console_scripts, ROOT
import pytest

BIN = Path(sys.executable).parent
IGNORE = shutil.ignore_patterns('.venv', '.git', 'build', 'install', 'log', '*.egg-info',
                                '__pycache__', '.pytest_cache', '.hypothesis', 'demo_output')


@pytest.fixture(scope='module')
def source_copy(tmp_path_factory):
    # Build from a copy, so that builds leave nothing in the work tree.
    dest = tmp_path_factory.mktemp('src') / 'tracked_kinematics'
    shutil.copytree(ROOT, dest, ignore=IGNORE)
    return dest


def test_package_xml_is_format_3_ament_python():
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == 'tracked_kinematics'
    assert root.find('export/build_type').text == 'ament_python'
    deps = {e.text for e in root if e.tag.endswith('depend')}
    for key in ('rclpy', 'nav_msgs', 'geometry_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs',
                'tf2_ros', 'python3-numpy', 'python3-scipy', 'python3-rosbags-pip',
                'python3-pytest'):
        assert key in deps, key
    assert (ROOT / 'resource' / 'tracked_kinematics').is_file()


def test_console_scripts_resolve():
    scripts = console_scripts()
    assert {'tracked_kinematics_demo', 'simulate_bag', 'icr_map'} <= set(scripts)
    for name, target in scripts.items():
        module, func = target.split(':')
        assert callable(getattr(importlib.import_module(module), func)), name


@pytest.mark.slow
def test_colcon_build_installs_ros2_run_layout(source_copy, tmp_path):
    ws = tmp_path / 'ws'
    (ws / 'src').mkdir(parents=True)
    shutil.copytree(source_copy, ws / 'src' / 'tracked_kinematics')
    result = subprocess.run(
        [str(BIN / 'colcon'), 'build', '--base-paths', 'src', '--event-handlers',
         'console_direct-'], cwd=ws, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    prefix = ws / 'install' / 'tracked_kinematics'
    share = prefix / 'share' / 'tracked_kinematics'
    # `ros2 run tracked_kinematics NAME` looks in lib/<package>/.
    for name in console_scripts():
        assert os.access(prefix / 'lib' / 'tracked_kinematics' / name, os.X_OK), name
    assert (share / 'package.xml').is_file()
    assert (share / 'config' / 'auriga_alpha_hard_floor.yaml').is_file()
    for vehicle in (ROOT / 'config' / 'vehicles').glob('*.yaml'):
        assert (share / 'config' / 'vehicles' / vehicle.name).is_file()
    assert (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
            / 'tracked_kinematics').is_file()
    for launch_file in (ROOT / 'launch').glob('*.py'):
        assert (share / 'launch' / launch_file.name).is_file()
    # The installed script runs from the install space and finds its share/ through the
    # ament index, as it would on a robot.
    site = next(prefix.glob('lib/python3*/site-packages'))
    env = {**os.environ, 'PYTHONPATH': str(site), 'AMENT_PREFIX_PATH': str(prefix)}
    run = subprocess.run([str(prefix / 'lib' / 'tracked_kinematics' / 'tracked_kinematics_demo'),
                          '--duration', '90', '--paths', '1', '--path-duration', '20'],
                         cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert f'({share}/config/vehicles/auriga_alpha.yaml)' in run.stdout
    # A shipped vehicle by name, found in the install space's share/.
    run = subprocess.run([str(prefix / 'lib' / 'tracked_kinematics' / 'icr_map'), 'packbot',
                          '--n', '3'], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert f'{share}/config/vehicles/packbot.yaml' in run.stdout


@pytest.mark.slow
def test_pip_install_puts_scripts_on_path_and_data_in_share(source_copy, tmp_path):
    # A throwaway venv of its own, so the project's editable install is left alone.
    venv = tmp_path / 'venv'
    subprocess.run([sys.executable, '-m', 'venv', '--without-pip', str(venv)], check=True)
    dist = tmp_path / 'dist'
    pip = [sys.executable, '-m', 'pip', '--quiet']
    built = subprocess.run(pip + ['wheel', '--no-deps', '--no-build-isolation', '-w', str(dist),
                                  str(source_copy)], capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stdout + built.stderr
    installed = subprocess.run(pip + ['--python', str(venv / 'bin' / 'python'), 'install',
                                      '--no-deps', *map(str, dist.glob('*.whl'))],
                               capture_output=True, text=True, timeout=300)
    assert installed.returncode == 0, installed.stdout + installed.stderr
    for name in console_scripts():
        assert os.access(venv / 'bin' / name, os.X_OK), name
    share = venv / 'share' / 'tracked_kinematics'
    assert (share / 'package.xml').is_file()
    assert (share / 'config' / 'auriga_alpha_hard_floor.yaml').is_file()
    assert (share / 'config' / 'vehicles' / 'auriga_alpha.yaml').is_file()


@pytest.mark.parametrize('name', sorted(console_scripts()))
def test_every_console_script_answers_help(name):
    # The first thing a new user types; evaluate_model's once crashed in argparse (a bare
    # `%` in a help text). Run as the installed script runs: the entry point in a process of
    # its own, program name first, no ROS graph needed.
    module, func = console_scripts()[name].split(':')
    code = (f'import sys; sys.argv = [{name!r}, "--help"]; '
            f'from {module} import {func} as main; sys.exit(main())')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=60, cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'Traceback' not in result.stderr, result.stderr
    first = result.stdout.lstrip().splitlines()[0]
    assert first.startswith('usage:') and name in first, result.stdout
    # More than the usage line: what the program does, or its options and parameters.
    assert len(result.stdout.splitlines()) > 5, result.stdout
