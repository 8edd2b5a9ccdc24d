"""ros/main.run: --help, one FATAL line and exit 2 for any start-up failure, typo warnings."""

import signal
import time

from helpers.ros_helpers import ConsoleScript
import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from tracked_kinematics.params import ParamSpec, positive
from tracked_kinematics.ros.main import (_settings_notices, normalised_arguments,
                                         params_file_keys, params_file_sections, run,
                                         StartupError, unknown_parameters)
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


def odometry_node_with_typo(tmp_path, vehicle, typo='track_widht'):
    """Start odometry_node with a params file of ``vehicle`` lines and ``typo``."""
    params = tmp_path / 'p.yaml'
    params.write_text('/**:\n  ros__parameters:\n' + ''.join(f'    {line}\n' for line in vehicle)
                      + f'    {typo}: 0.5\n')
    return ConsoleScript('odometry_node', '--ros-args', '--params-file', params,
                         tmp_path=tmp_path)


@pytest.mark.ros
def test_typo_in_params_file_refuses_the_start(tmp_path):
    # Issue 31: a misspelt key of the node's own is fatal, even beside the right one.
    with odometry_node_with_typo(tmp_path, ['track_width: 0.42', 'sprocket_radius: 0.1']) \
            as script:
        assert script.wait(30) == 2
    fatal = [line for line in script.output.splitlines() if 'FATAL' in line]
    assert len(fatal) == 1, script.output
    assert "unknown 'track_widht' (did you mean 'track_width'?)" in fatal[0]


@pytest.mark.ros
def test_terrain_file_provenance_loads_without_warnings(tmp_path):
    # A terrain file as identify_icr writes it: its records are not unknown; a stranger is.
    records = ['terrain: hard_floor', 'identification:', '  model: icr_scales',
               '  bags: [/data/run1]', '  parameters: {y_left: 0.37}',
               'drivetrain_fit: {cost: 0.1}']
    with odometry_node_with_typo(tmp_path, ['track_width: 0.42', 'sprocket_radius: 0.1',
                                            *records], typo='zzz_stranger') as script:
        deadline = time.monotonic() + 30
        while 'zzz_stranger' not in script.output and time.monotonic() < deadline:
            time.sleep(0.05)
        assert script.stop() == 0
    assert "unknown parameter 'zzz_stranger'" in script.output
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


def test_a_typo_refuses_the_start_beside_the_right_name(ros_context):
    # Issue 31: 'rat' beside 'rate' would leave rate at its default as silently as a
    # missing one; an unknown name that is no typo is left to the warning.
    node = Node('typo_test', context=ros_context, parameter_overrides=[
        Parameter('track_width', value=0.5), Parameter('rat', value=5.0),
        Parameter('zzz', value=1)])
    try:
        with pytest.raises(ParameterError) as refused:
            ParameterTable(node, REQUIRED)
    finally:
        node.destroy_node()
    assert str(refused.value) == "invalid parameters: unknown 'rat' (did you mean 'rate'?)"


def test_a_misspelt_key_in_an_owned_namespace_refuses_the_start(ros_context):
    # Issue 31 item 6: icr.y_lft started a lopsided model with a warning only.
    from tracked_kinematics.params import TERRAIN_PARAMS
    node = Node('typo_test', context=ros_context, parameter_overrides=[
        Parameter('track_width', value=0.5), Parameter('sprocket_radius', value=0.1),
        Parameter('icr.y_lft', value=0.3), Parameter('scale.xyzzyplugh', value=1.0)])
    try:
        with pytest.raises(ParameterError) as refused:
            ParameterTable(node, TERRAIN_PARAMS)
    finally:
        node.destroy_node()
    assert str(refused.value) == (
        "invalid parameters: unknown 'icr.y_lft' (did you mean 'icr.y_left'?); "
        "unknown 'scale.xyzzyplugh' (scale.* holds scale.left, scale.right)")


def test_other_nodes_parameters_and_records_are_no_typos(ros_context):
    # One terrain file serves every node: odometry_node's publish_tf or the simulator's
    # left_joint (close to left_joints) is no typo for another node.
    from tracked_kinematics.params import ENCODER_INPUT_PARAMS, TERRAIN_PARAMS
    node = Node('typo_test', context=ros_context, parameter_overrides=[
        Parameter('track_width', value=0.5), Parameter('sprocket_radius', value=0.1),
        Parameter('left_joint', value='a'), Parameter('publish_tf', value=False),
        Parameter('identification.model', value='icr')])
    try:
        assert ParameterTable(node, TERRAIN_PARAMS + ENCODER_INPUT_PARAMS)['track_width'] == 0.5
    finally:
        node.destroy_node()
    assert unknown_parameters(['left_joint', 'publish_tf', 'push_to', 'zzz'], SPECS) == [
        "unknown parameter 'zzz' ignored"]


def test_an_empty_value_is_the_empty_string(ros_context):
    # Issue 31 item 2: the shell leaves deadman_topic:= of the documented deadman_topic:=''.
    assert normalised_arguments(['n', 'x:=', '--ros-args', '-p', 'a:=', '-r', 'b:=',
                                 '--param', 'c:=', '-p', 'd:=1', '--', '-p', 'e:=']) == [
        'n', 'x:=', '--ros-args', '-p', "a:=''", '-r', 'b:=', '--param', "c:=''", '-p', 'd:=1',
        '--', '-p', 'e:=']
    seen = []

    def factory():
        node = Node('probe')
        node.declare_parameter('topic', 'deadman')
        seen.append(node.get_parameter('topic').value)
        raise RuntimeError('built')
    assert run(factory, 'probe', ['probe', '--ros-args', '-p', 'topic:=']) == 2
    assert seen == ['']


def test_settings_a_node_will_not_use_are_said(tmp_path):
    from tracked_kinematics.ros.odometry_node import PARAMS as ODOMETRY
    path = tmp_path / 'p.yaml'
    path.write_text('/**:\n  ros__parameters:\n    track_width: 0.4\n'
                    'odometry_node:\n  ros__parameters:\n    publish_tf: true\n'
                    '    left_joints: [l]\n    odom_frame: o\n')
    sections = params_file_sections(str(path))
    # Issue 31 item 5: -p publish_tf:=false is overridden by the odometry_node section.
    notices = _settings_notices('odometry_node', ODOMETRY, [
        ('p', 'track_width'), ('file', str(path), sections), ('p', 'publish_tf')])
    assert len(notices) == 2, notices
    assert notices[0].startswith(f'-p track_width has no effect: {path}, given after it')
    assert notices[1].startswith("-p publish_tf has no effect: the section 'odometry_node' of")
    # Issue 31 item 1: the joints of an odometry_node section do not reach calibration_drive.
    from tracked_kinematics.ros.calibration_drive_node import PARAMS as CALIBRATION
    notices = _settings_notices('calibration_drive', CALIBRATION,
                                [('file', str(path), sections)])
    assert notices == [f'{path} sets left_joints only for odometry_node; calibration_drive '
                       'uses its default unless given: put what every node shares under /** '
                       '(convert_diff_drive_params writes it so)']
    assert _settings_notices('calibration_drive', CALIBRATION, [
        ('file', str(path), sections), ('p', 'left_joints')]) == []


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
            signal.raise_signal(signal.SIGINT)

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


@pytest.mark.ros
def test_a_node_without_traffic_stops_at_once(tmp_path):
    # Issue 31: tracked_simulator without setpoints took 5 s to stop on Ctrl-C ("a callback
    # is still running 5 s after the stop request"): its executor, woken, waited again.
    with ConsoleScript('tracked_simulator', tmp_path=tmp_path) as script:
        deadline = time.monotonic() + 60
        while 'simulating' not in script.output and time.monotonic() < deadline:
            time.sleep(0.05)
        assert 'simulating' in script.output, script.output
        start = time.monotonic()
        assert script.stop() == 0
        elapsed = time.monotonic() - start
    assert 'still running' not in script.output
    assert elapsed < 4.0
