"""ros/main.run: --help, one FATAL line and exit 2 for any start-up failure, typo warnings."""

import os
import signal
import time

from helpers.ros_helpers import ConsoleScript
import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from tracked_kinematics.params import ParamSpec, positive
from tracked_kinematics.ros.main import params_file_keys, run, StartupError, unknown_parameters
from tracked_kinematics.ros.parameters import ParameterError, ParameterTable

SPECS = (ParamSpec('rate', 50.0, 'Publish rate', 'Hz', positive, low=0.1, high=1000.0),
         ParamSpec('count', 3, 'A count', low=1, high=10),
         ParamSpec('track_width', 0.42, 'Track width', 'm', positive))


def never_called():
    raise AssertionError('the node must not be built')


def fatal_lines(capfd):
    err = capfd.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and '[FATAL]' in lines[0], err
    return lines[0]


@pytest.mark.parametrize('content, message', [
    ('a: [\n', 'is not valid YAML'),
    ('- 1\n- 2\n', 'is not a mapping'),
    ('/**:\n  rate: 1\n', 'has no "ros__parameters:" section'),
    (b'\xff\xfe\x00', 'is not valid YAML'),
])
def test_broken_params_file_is_one_fatal_line(tmp_path, capfd, content, message):
    path = tmp_path / 'p.yaml'
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    assert run(never_called, 'probe', ['probe', '--ros-args', '--params-file', str(path)]) == 2
    assert message in fatal_lines(capfd)


@pytest.mark.parametrize('where, message', [('missing.yaml', 'does not exist'),
                                            ('.', 'is not a regular file')])
def test_missing_params_file_or_directory(tmp_path, capfd, where, message):
    path = tmp_path / where
    assert run(never_called, 'probe', ['probe', '--ros-args', '--params-file', str(path)]) == 2
    assert message in fatal_lines(capfd)


def test_help_prints_usage_and_parameters(capsys):
    assert run(never_called, 'probe', ['probe', '--help'], SPECS, 'Probe: does things.') == 0
    out = capsys.readouterr().out
    assert out.startswith('usage: ros2 run tracked_kinematics probe')
    assert 'rate (default 50.0): Publish rate [Hz]' in out and 'docs/nodes/probe.md' in out


def test_construction_failure_is_one_fatal_line(capfd):
    def factory():
        raise RuntimeError('cannot open the device\n  really')
    assert run(factory, 'probe', ['probe']) == 2
    assert 'cannot start: RuntimeError: cannot open the device really' in fatal_lines(capfd)


def test_parameter_argument_without_assignment(capfd):
    assert run(never_called, 'probe', ['probe', '--ros-args', '-p', 'no_assignment']) == 2
    assert "-p needs NAME:=VALUE, got 'no_assignment'" in fatal_lines(capfd)


def test_rcl_argument_error_is_a_fatal_line(capfd):
    # rcl logs its own ERROR line before refusing; ours is the FATAL one with the reason.
    assert run(never_called, 'probe', ['probe', '--ros-args', '-r', 'broken']) == 2
    assert '[FATAL]' in capfd.readouterr().err


def test_params_file_keys_of_this_node(tmp_path):
    path = tmp_path / 'p.yaml'
    path.write_text('/**:\n  ros__parameters:\n    icr: {y_left: 0.3}\n'
                    'probe:\n  ros__parameters:\n    rate: 5.0\n'
                    'other:\n  ros__parameters:\n    nope: 1\n')
    assert params_file_keys(str(path), 'probe') == ['icr.y_left', 'rate']
    with pytest.raises(StartupError):
        params_file_keys(str(tmp_path / 'none.yaml'), 'probe')


def test_unknown_parameters_name_the_closest():
    messages = unknown_parameters(['track_widht', 'rate', 'use_sim_time', 'zzz'], SPECS)
    assert messages == ["unknown parameter 'track_widht' ignored (did you mean "
                        "'track_width'?)", "unknown parameter 'zzz' ignored"]


def test_terrain_file_records_are_not_unknown_parameters():
    # identify_icr writes its provenance into the terrain file a node then loads.
    given = ['terrain', 'identification.model', 'identification.parameters.y_left',
             'drivetrain_fit.cost', 'simulation.seed', 'identification_typo', 'rate']
    assert unknown_parameters(given, SPECS) == ["unknown parameter 'identification_typo' "
                                                'ignored']


def test_ranges_are_descriptors_and_enforced(ros_context):
    node = Node('range_test', context=ros_context)
    table = ParameterTable(node, SPECS)
    desc = node.describe_parameter('rate')
    assert desc.floating_point_range[0].from_value == 0.1
    assert desc.floating_point_range[0].to_value == 1000.0
    assert node.describe_parameter('count').integer_range[0].to_value == 10
    for value in (1e-10, 5e-324, 1e6):
        assert not node.set_parameters([Parameter('rate', value=value)])[0].successful
    assert not node.set_parameters([Parameter('rate', value=0)])[0].successful  # int path
    assert not node.set_parameters([Parameter('count', value=11)])[0].successful
    assert table['rate'] == 50.0 and table['count'] == 3
    assert node.set_parameters([Parameter('rate', value=200.0)])[0].successful
    assert table['rate'] == 200.0
    node.destroy_node()


@pytest.mark.ros
@pytest.mark.parametrize('name', ['odometry_node', 'cmd_vel_translator', 'icr_estimator'])
def test_node_help_does_not_start_ros(tmp_path, name):
    with ConsoleScript(name, '--help', tmp_path=tmp_path) as script:
        assert script.wait(30) == 0
    assert script.output.startswith(f'usage: ros2 run tracked_kinematics {name}')


def odometry_node_with_typo(tmp_path, vehicle):
    """Start odometry_node with a params file of ``vehicle`` lines and ``track_widht``."""
    params = tmp_path / 'p.yaml'
    params.write_text('/**:\n  ros__parameters:\n' + ''.join(f'    {line}\n' for line in vehicle)
                      + '    track_widht: 0.5\n')
    return ConsoleScript('odometry_node', '--ros-args', '--params-file', params,
                         tmp_path=tmp_path)


@pytest.mark.ros
def test_typo_in_params_file_is_named(tmp_path):
    with odometry_node_with_typo(tmp_path, ['track_width: 0.42', 'sprocket_radius: 0.1']) \
            as script:
        deadline = time.monotonic() + 30
        while 'track_widht' not in script.output and time.monotonic() < deadline:
            time.sleep(0.05)
        assert script.stop() == 0
    assert "unknown parameter 'track_widht' ignored (did you mean 'track_width'?)" \
        in script.output


@pytest.mark.ros
def test_terrain_file_provenance_loads_without_warnings(tmp_path):
    # A terrain file as identify_icr writes it: its records are no typos; the typo still is.
    records = ['terrain: hard_floor', 'identification:', '  model: icr_scales',
               '  bags: [/data/run1]', '  parameters: {y_left: 0.37}',
               'drivetrain_fit: {cost: 0.1}']
    with odometry_node_with_typo(tmp_path, ['track_width: 0.42', 'sprocket_radius: 0.1',
                                            *records]) as script:
        deadline = time.monotonic() + 30
        while 'track_widht' not in script.output and time.monotonic() < deadline:
            time.sleep(0.05)
        assert script.stop() == 0
    assert "unknown parameter 'track_widht'" in script.output
    assert 'identification' not in script.output and 'drivetrain_fit' not in script.output
    assert "'terrain'" not in script.output


REQUIRED = (ParamSpec('track_width', 0.42, 'Track width', 'm', positive, required=True),
            ParamSpec('rate', 50.0, 'Publish rate', 'Hz', positive))


def test_a_refused_start_names_the_typo_behind_it(ros_context):
    # Issue 23: track_widht leaves track_width missing; the refusal names the typo, not only
    # the missing name. An unknown name that is no typo of a known one is not named there.
    node = Node('typo_test', context=ros_context, parameter_overrides=[
        Parameter('track_widht', value=0.5), Parameter('odom_frame', value='odom')])
    try:
        with pytest.raises(ParameterError) as refused:
            ParameterTable(node, REQUIRED)
    finally:
        node.destroy_node()
    message = str(refused.value)
    assert message.startswith('invalid parameters: track_width has no default')
    assert message.endswith("; unknown 'track_widht' (did you mean 'track_width'?)")
    assert 'odom_frame' not in message


def test_a_start_that_is_not_refused_leaves_typos_to_the_warning(ros_context):
    node = Node('typo_test', context=ros_context, parameter_overrides=[
        Parameter('track_width', value=0.5), Parameter('rat', value=5.0)])
    try:
        assert ParameterTable(node, REQUIRED)['rate'] == 50.0
    finally:
        node.destroy_node()


@pytest.mark.ros
def test_typo_that_refuses_the_start_is_named_in_the_fatal_line(tmp_path):
    with odometry_node_with_typo(tmp_path, ['sprocket_radius: 0.1']) as script:
        assert script.wait(30) == 2
    fatal = [line for line in script.output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1, script.output
    assert 'track_width has no default' in fatal[0]
    assert fatal[0].endswith("unknown 'track_widht' (did you mean 'track_width'?)"), fatal[0]


@pytest.mark.ros
@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_signal_is_a_clean_exit(tmp_path, sig):
    with ConsoleScript('odometry_node', '--ros-args', '-p', 'track_width:=0.42',
                       '-p', 'sprocket_radius:=0.1', tmp_path=tmp_path) as script:
        deadline = time.monotonic() + 30
        while 'ICR model' not in script.output and time.monotonic() < deadline:
            time.sleep(0.05)
        script.process.send_signal(sig)
        assert script.wait(30) == 0
    assert 'Traceback' not in script.output


class _Recorder(Node):
    """A node that signals its own process from a timer and records how it was stopped."""

    def __init__(self, log, signals=1):
        super().__init__('interrupted')
        self.log = log
        self._left = signals
        self.create_timer(0.01, self._tick)

    def _tick(self):
        self.log.append('tick')
        if self._left > 0:
            self._left -= 1
            os.kill(os.getpid(), signal.SIGINT)

    def destroy_node(self):
        self.log.append(('destroyed, context ok', self.context.ok()))
        super().destroy_node()


@pytest.mark.parametrize('signals', [1, 2])
def test_a_signal_is_an_orderly_stop(monkeypatch, signals):
    # The signal is a request, never a KeyboardInterrupt inside rclpy: run() stops the
    # executor, destroys the node while its context is up, then shuts the context down. A
    # try_shutdown that meets another shutdown ("rcl_shutdown already called") is no crash.
    from rclpy._rclpy_pybind11 import RCLError
    real = rclpy.try_shutdown

    def racing(*args, **kwargs):
        real(*args, **kwargs)
        raise RCLError('failed to shutdown: rcl_shutdown already called on the given context')

    monkeypatch.setattr(rclpy, 'try_shutdown', racing)
    log = []
    before = signal.getsignal(signal.SIGINT)
    assert run(lambda: _Recorder(log, signals), 'interrupted', ['interrupted']) == 0
    assert 'tick' in log and log[-1] == ('destroyed, context ok', True)
    assert not rclpy.ok()
    assert signal.getsignal(signal.SIGINT) is before  # the test process's handler is back


class _GivingUp(Node):
    """A node whose own work fails for good: it sets ``failure``, shuts its context down."""

    def __init__(self):
        super().__init__('giving_up')
        self.failure = None
        self.create_timer(0.01, self._give_up)

    def _give_up(self):
        self.failure = RuntimeError('broken for good')
        self.context.try_shutdown()


def test_a_node_that_gave_up_exits_1():
    # As cmd_vel_translator and tracked_simulator do when their loop keeps failing.
    assert run(_GivingUp, 'giving_up', ['giving_up']) == 1
    assert not rclpy.ok()


def test_a_callback_that_raises_is_a_traceback_after_an_orderly_stop():
    # A bug is not swallowed: the error reaches the caller once the node is down.
    log = []

    def factory():
        node = _Recorder(log, signals=0)
        node.create_timer(0.02, lambda: (_ for _ in ()).throw(ZeroDivisionError('bug')))
        return node

    with pytest.raises(ZeroDivisionError, match='bug'):
        run(factory, 'interrupted', ['interrupted'])
    assert log[-1] == ('destroyed, context ok', True) and not rclpy.ok()
