"""ParameterTable and run(): declaration, validation at start and at runtime."""

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from tracked_kinematics.params import icr_from_values, ParamSpec, positive, TERRAIN_PARAMS
from tracked_kinematics.ros.main import run
from tracked_kinematics.ros.parameters import (destroyed_on_failure, ParameterError,
                                               ParameterTable, TableNode)

SPECS = TERRAIN_PARAMS + (
    ParamSpec('left_joints', ['left_sprocket_joint'], 'Joints of the left track'),
    ParamSpec('tags', [], 'A list that starts empty'),
    ParamSpec('rate', 50.0, 'Publish rate', 'Hz', positive),
    ParamSpec('topic', 'odom', 'Output topic', read_only=True),
)


VEHICLE = [Parameter('track_width', value=0.42), Parameter('sprocket_radius', value=0.1)]


def make(ros_context, overrides=(), changes=None, vehicle=VEHICLE):
    node = Node('table_test', context=ros_context,
                parameter_overrides=list(vehicle) + list(overrides))
    with destroyed_on_failure(node):  # a refused start leaves no node to the collector
        table = ParameterTable(node, SPECS, validate=icr_from_values,
                               on_change=(changes.append if changes is not None else None))
    return node, table


def test_declares_with_descriptions_and_defaults(ros_context):
    node, table = make(ros_context)
    assert table['icr.y_left'] == 0.21
    assert table['left_joints'] == ['left_sprocket_joint']
    assert table['tags'] == []
    desc = node.describe_parameter('track_width')
    assert 'track centrelines' in desc.description and '[m]' in desc.description
    assert node.describe_parameter('topic').read_only
    node.destroy_node()


def test_integer_override_accepted_for_double(ros_context):
    node, table = make(ros_context, [Parameter('icr.x', value=0)])
    assert table['icr.x'] == 0.0 and isinstance(table['icr.x'], float)
    node.destroy_node()


@pytest.mark.parametrize('overrides, match', [
    ([Parameter('icr.y_left', value=-0.3)], 'icr.y_left .* greater than icr.y_right'),
    ([Parameter('scale.left', value=0.0)], 'scale.left must be > 0'),
    ([Parameter('icr.x', value=float('nan'))], 'icr.x must be finite'),
    ([Parameter('rate', value='fast')], 'rate must be of the type'),
])
def test_invalid_at_start_raises_with_reason(ros_context, overrides, match):
    with pytest.raises(ParameterError, match=match):
        make(ros_context, overrides)


def test_runtime_change_validated_as_a_whole(ros_context):
    changes = []
    node, table = make(ros_context, changes=changes)
    # y_left alone below track_width / 2 would make chi > 1: refused, old value kept.
    result = node.set_parameters([Parameter('icr.y_left', value=0.1)])[0]
    assert not result.successful and 'chi' in result.reason
    assert table['icr.y_left'] == 0.21 and changes == []
    assert node.get_parameter('icr.y_left').value == 0.21
    # Both together are valid: accepted, callback told, values updated.
    results = node.set_parameters_atomically([Parameter('icr.y_left', value=0.35),
                                              Parameter('icr.y_right', value=-0.42)])
    assert results.successful
    assert table['icr.y_left'] == 0.35 and changes[-1]['icr.y_right'] == -0.42
    # Wrong type at runtime.
    bad = node.set_parameters([Parameter('rate', Parameter.Type.STRING, 'x')])[0]
    assert not bad.successful
    assert table['rate'] == 50.0
    node.destroy_node()


def test_required_parameters_missing_at_start_are_named(ros_context):
    with pytest.raises(ParameterError, match='track_width and sprocket_radius have no '
                                             'default'):
        make(ros_context, vehicle=())
    with pytest.raises(ParameterError, match='^invalid parameters: sprocket_radius has no'):
        make(ros_context, vehicle=VEHICLE[:1])


def test_derived_icrs_follow_track_width_until_set(ros_context):
    changes = []
    node, table = make(ros_context, changes=changes)
    assert (table['icr.y_left'], table['icr.y_right']) == (0.21, -0.21)
    assert node.get_parameter('icr.y_right').value == -0.21  # ros2 param get shows it
    assert 'track_width / 2 unless set' in node.describe_parameter('icr.y_left').description
    # A runtime change of track_width (as `ros2 param set` does it, one parameter) moves
    # both derived ICRs with it: the model stays the ideal drive of the new width.
    assert node.set_parameters([Parameter('track_width', value=0.5)])[0].successful
    assert (table['icr.y_left'], table['icr.y_right']) == (0.25, -0.25)
    assert node.get_parameter('icr.y_left').value == 0.25
    assert changes[-1]['icr.y_right'] == -0.25
    # Once set explicitly, an ICR stays where it was put.
    assert node.set_parameters([Parameter('icr.y_left', value=0.4)])[0].successful
    assert node.set_parameters([Parameter('track_width', value=0.6)])[0].successful
    assert (table['icr.y_left'], table['icr.y_right']) == (0.4, -0.3)
    assert table.explicit == {'icr.y_left'}
    # A width the explicit ICR does not allow (chi > 1) is refused as a whole.
    result = node.set_parameters([Parameter('track_width', value=1.0)])[0]
    assert not result.successful and 'chi' in result.reason
    assert (table['track_width'], table['icr.y_right']) == (0.6, -0.3)
    node.destroy_node()


def test_icrs_given_at_start_are_explicit(ros_context):
    node, table = make(ros_context, [Parameter('icr.y_right', value=-0.3)])
    assert table.explicit == {'icr.y_right'}
    assert node.set_parameters_atomically([Parameter('track_width', value=0.5)]).successful
    assert (table['icr.y_left'], table['icr.y_right']) == (0.25, -0.3)
    node.destroy_node()


def test_run_returns_2_on_invalid_parameters(capfd):
    def factory():
        raise ParameterError('invalid parameters: icr.y_left must be finite')
    assert run(factory, 'probe', args=['probe']) == 2
    assert 'icr.y_left must be finite' in capfd.readouterr().err


class _Probe(TableNode):
    """A TableNode that records what it was given, and fails where told to."""

    def __init__(self, fail_in_start=False, **kwargs):
        self.fail_in_start = fail_in_start
        self.calls = []
        super().__init__('probe_node', SPECS, icr_from_values, **kwargs)

    def _start(self, values):
        self.calls.append(('start', values['rate']))
        if self.fail_in_start:
            raise RuntimeError('no device')

    def _apply(self, values):
        self.calls.append(('apply', values['rate']))

    def _abandon(self):
        self.calls.append(('abandon',))


def test_a_table_node_builds_from_its_values_and_applies_changes(ros_context):
    node = _Probe(context=ros_context, parameter_overrides=VEHICLE)
    try:
        assert node.params['rate'] == 50.0 and node.calls == [('start', 50.0)]
        assert node.set_parameters([Parameter('rate', value=5.0)])[0].successful
        assert node.calls[-1] == ('apply', 5.0)
    finally:
        node.destroy_node()


@pytest.mark.parametrize('overrides, fail_in_start, error', [
    ([], False, ParameterError),                                  # no vehicle given
    (VEHICLE + [Parameter('rate', value=-1.0)], False, ParameterError),
    (VEHICLE, True, RuntimeError),
])
def test_a_table_node_whose_start_fails_is_destroyed(ros_context, overrides, fail_in_start,
                                                     error):
    built = []

    class Recorded(_Probe):
        def _abandon(self):
            built.append(self)
            super()._abandon()

    with pytest.raises(error):
        Recorded(fail_in_start, context=ros_context, parameter_overrides=overrides)
    node, = built
    assert node.calls[-1] == ('abandon',)
    with pytest.raises(Exception, match='destruction was requested'):
        node.get_name()   # destroyed: nothing left for the garbage collector


@pytest.mark.parametrize('sim_time_at_start', [True, False])
def test_an_invalid_clock_message_is_refused_not_raised(ros_context, executor,
                                                        sim_time_at_start):
    # Issue 27: a /clock with sec = -1 raised inside rclpy's TimeSource and killed the nodes.
    from builtin_interfaces.msg import Time
    from helpers.ros_helpers import spin_until
    from rosgraph_msgs.msg import Clock
    sim_time = [Parameter('use_sim_time', value=True)] if sim_time_at_start else []
    node = _Probe(context=ros_context, parameter_overrides=VEHICLE + sim_time)
    pub_node = Node('clock_source', context=ros_context)
    try:
        if not sim_time_at_start:   # the /clock subscription is made at runtime
            assert node.set_parameters([Parameter('use_sim_time', value=True)])[0].successful
        executor.add_node(node)
        executor.add_node(pub_node)
        clock = pub_node.create_publisher(Clock, '/clock', 10)
        assert spin_until(executor, lambda: clock.get_subscription_count() > 0)
        clock.publish(Clock(clock=Time(sec=12, nanosec=5)))
        assert spin_until(executor, lambda: node.ros_time() == pytest.approx(12.0))
        clock.publish(Clock(clock=Time(sec=-1, nanosec=0)))
        assert spin_until(executor, lambda: node.clock_fault() != '')
        assert 'negative time -1 s' in node.clock_fault()
        assert node.ros_time() is None
        assert node.get_clock().now().nanoseconds == 12_000_000_005   # left where it was
        clock.publish(Clock(clock=Time(sec=13, nanosec=0)))
        assert spin_until(executor, lambda: node.clock_fault() == '')
        assert node.ros_time() == pytest.approx(13.0)
    finally:
        executor.remove_node(node)
        executor.remove_node(pub_node)
        node.destroy_node()
        pub_node.destroy_node()
