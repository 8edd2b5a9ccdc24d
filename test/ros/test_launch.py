"""launch/tracked_kinematics.launch.py: what can be checked without the launch package."""

import ast
import importlib.util

from helpers.setup_info import console_scripts, ROOT
import pytest
from tracked_kinematics.params import icr_from_values, read_params_file

LAUNCH = ROOT / 'launch' / 'tracked_kinematics.launch.py'


def _calls(tree, name):
    return [node for node in ast.walk(tree)
            if isinstance(node, ast.Call) and getattr(node.func, 'id', None) == name]


def _keyword(call, name):
    for keyword in call.keywords:
        if keyword.arg == name:
            return keyword.value
    return None


@pytest.fixture(scope='module')
def tree():
    return ast.parse(LAUNCH.read_text(), filename=str(LAUNCH))


def test_compiles():
    compile(LAUNCH.read_text(), str(LAUNCH), 'exec')


def test_starts_both_nodes_as_console_scripts(tree):
    executables = {ast.literal_eval(_keyword(call, 'executable')) for call in _calls(tree, 'Node')}
    assert executables == {'odometry_node', 'cmd_vel_translator'}
    assert executables <= set(console_scripts())
    for call in _calls(tree, 'Node'):
        assert ast.literal_eval(_keyword(call, 'package')) == 'tracked_kinematics'


def test_default_terrain_file_exists_and_loads(tree):
    default = next(node.value for node in ast.walk(tree)
                   if isinstance(node, ast.Assign) and node.targets[0].id == 'DEFAULT_TERRAIN')
    path = ROOT / 'config' / ast.literal_eval(default)
    assert path.is_file()
    icr = icr_from_values(read_params_file(path))
    assert 0.0 < icr.chi <= 1.0


def test_declares_params_file_and_use_sim_time(tree):
    declared = {ast.literal_eval(call.args[0]) for call in _calls(tree, 'DeclareLaunchArgument')}
    assert declared == {'params_file', 'use_sim_time'}


@pytest.mark.skipif(importlib.util.find_spec('launch') is None
                    or importlib.util.find_spec('launch_ros') is None,
                    reason='launch / launch_ros are not on PyPI; checked on a ROS machine')
def test_builds_launch_description():  # pragma: no cover - needs a ROS install
    spec = importlib.util.spec_from_file_location('tk_launch', LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    assert len(description.entities) == 4
