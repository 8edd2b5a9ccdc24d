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


def _declared(tree, name):
    return next(call for call in _calls(tree, 'DeclareLaunchArgument')
                if ast.literal_eval(call.args[0]) == name)


def test_params_file_is_required(tree):
    # Issue 37 item 4: a forgotten params_file fell back to the Auriga's terrain file, so
    # cmd_vel_translator drove a Warthog's tracks about 3x off, silently.
    params_file = _declared(tree, 'params_file')
    assert _keyword(params_file, 'default_value') is None
    assert 'required' in ast.literal_eval(_keyword(params_file, 'description')).lower()
    # Nor a vehicle of the package anywhere in the file: no terrain file, no share path.
    strings = [node.value for node in ast.walk(tree)
               if isinstance(node, ast.Constant) and isinstance(node.value, str)]
    assert not [text for text in strings
                if (text.endswith('.yaml') and ' ' not in text) or text == 'config']
    assert not _calls(tree, 'FindPackageShare')


class _Configuration:
    """launch's LaunchConfiguration as far as check_params_file uses it."""

    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context[self.name]


def _launch_module_with_stubs(monkeypatch):
    """Load the launch file with stand-ins for launch / launch_ros (not on PyPI)."""
    import sys
    import types

    def record(*args, **kwargs):
        return (args, kwargs)
    for name in ('launch', 'launch.actions', 'launch.substitutions', 'launch_ros',
                 'launch_ros.actions'):
        module = types.ModuleType(name)
        for attr in ('LaunchDescription', 'DeclareLaunchArgument', 'OpaqueFunction', 'Node'):
            setattr(module, attr, record)
        module.LaunchConfiguration = _Configuration
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location('tk_launch_stubbed', LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize('given', ['', '  ', '/no/such/robot.yaml'])
def test_a_missing_or_empty_params_file_refuses_to_start(monkeypatch, given):
    module = _launch_module_with_stubs(monkeypatch)
    with pytest.raises(RuntimeError, match='params_file') as err:
        module.check_params_file({'params_file': given})
    assert 'params_file:=' in str(err.value)    # says how to give it
    if given.strip():
        assert given in str(err.value)


def test_the_check_runs_before_the_nodes(monkeypatch):
    module = _launch_module_with_stubs(monkeypatch)
    (entities,), _ = module.generate_launch_description()
    kinds = [args[0] if args and isinstance(args[0], str) else kwargs.get('executable')
             or kwargs.get('function') for args, kwargs in entities]
    check = kinds.index(module.check_params_file)
    assert check < kinds.index('odometry_node') and check < kinds.index('cmd_vel_translator')


def test_a_shipped_terrain_file_passes_the_check(monkeypatch):
    module = _launch_module_with_stubs(monkeypatch)
    path = ROOT / 'config' / 'auriga_alpha_hard_floor.yaml'
    assert module.check_params_file({'params_file': str(path)}) == []
    icr = icr_from_values(read_params_file(path))
    assert 0.0 < icr.chi <= 1.0


def test_declares_params_file_and_use_sim_time(tree):
    declared = {ast.literal_eval(call.args[0]) for call in _calls(tree, 'DeclareLaunchArgument')}
    assert declared == {'params_file', 'use_sim_time'}


@pytest.mark.skipif(importlib.util.find_spec('launch') is None
                    or importlib.util.find_spec('launch_ros') is None,
                    reason='launch / launch_ros are not on PyPI; checked on a ROS machine')
def test_builds_launch_description():  # pragma: no cover - needs a ROS install
    from launch import LaunchContext
    from launch.actions import DeclareLaunchArgument
    spec = importlib.util.spec_from_file_location('tk_launch', LAUNCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    assert len(description.entities) == 5
    params_file = next(entity for entity in description.entities
                       if isinstance(entity, DeclareLaunchArgument)
                       and entity.name == 'params_file')
    # launch's own refusal: 'Required launch argument "params_file" ... was not provided'.
    with pytest.raises(RuntimeError, match='params_file'):
        params_file.execute(LaunchContext())
    context = LaunchContext()
    context.launch_configurations['params_file'] = '/no/such/robot.yaml'
    with pytest.raises(RuntimeError, match='params_file'):
        module.check_params_file(context)


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
