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


# launch/simulation.launch.py (issue 22) ---------------------------------------------------

SIM_LAUNCH = ROOT / 'launch' / 'simulation.launch.py'


@pytest.fixture(scope='module')
def sim_tree():
    return ast.parse(SIM_LAUNCH.read_text(), filename=str(SIM_LAUNCH))


def _node_calls(tree):
    return {ast.literal_eval(_keyword(call, 'executable')): call for call in _calls(tree, 'Node')}


def test_simulation_compiles_and_starts_the_three_nodes(sim_tree):
    compile(SIM_LAUNCH.read_text(), str(SIM_LAUNCH), 'exec')
    nodes = _node_calls(sim_tree)
    assert set(nodes) == {'tracked_simulator', 'cmd_vel_translator', 'odometry_node'}
    assert set(nodes) <= set(console_scripts())
    for call in nodes.values():
        assert ast.literal_eval(_keyword(call, 'package')) == 'tracked_kinematics'


def test_simulation_runs_the_robot_nodes_on_the_simulated_clock(sim_tree):
    """The translator and odometry use /clock; the simulator, which publishes it, does not."""
    sim_time = next(node.value for node in ast.walk(sim_tree)
                    if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '')
                    == 'sim_time')
    assert ast.literal_eval(sim_time) == {'use_sim_time': True}
    nodes = _node_calls(sim_tree)
    for name in ('cmd_vel_translator', 'odometry_node'):
        parameters = _keyword(nodes[name], 'parameters')
        assert 'sim_time' in {getattr(e, 'id', None) for e in parameters.elts}
    simulator = ast.dump(_keyword(nodes['tracked_simulator'], 'parameters'))
    assert 'use_sim_time' not in simulator and 'sim_time' not in simulator


def test_simulation_arguments_are_simulator_parameters(sim_tree):
    from tracked_kinematics.params.node_tables import SIMULATOR_PARAMS
    declared = {ast.literal_eval(call.args[0])
                for call in _calls(sim_tree, 'DeclareLaunchArgument')}
    assert declared == {'vehicle', 'terrain', 'real_time_factor', 'params_file'}
    assert declared - {'params_file'} <= {spec.name for spec in SIMULATOR_PARAMS}
    values = {node.targets[0].id: ast.literal_eval(node.value) for node in ast.walk(sim_tree)
              if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '')
              .startswith('DEFAULT_')}
    assert (ROOT / 'config' / 'vehicles' / f'{values["DEFAULT_VEHICLE"]}.yaml').is_file()
    icr = icr_from_values(read_params_file(ROOT / 'config' / values['DEFAULT_TERRAIN']))
    assert 0.0 < icr.chi <= 1.0
