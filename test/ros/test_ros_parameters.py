"""ParameterTable and run(): declaration, validation at start and at runtime."""

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from tracked_kinematics.params import icr_from_values, ParamSpec, positive, TERRAIN_PARAMS
from tracked_kinematics.ros.main import run
from tracked_kinematics.ros.parameters import ParameterError, ParameterTable

SPECS = TERRAIN_PARAMS + (
    ParamSpec('left_joints', ['left_sprocket_joint'], 'Joints of the left track'),
    ParamSpec('tags', [], 'A list that starts empty'),
    ParamSpec('rate', 50.0, 'Publish rate', 'Hz', positive),
    ParamSpec('topic', 'odom', 'Output topic', read_only=True),
)


def make(ros_context, overrides=(), changes=None):
    node = Node('table_test', context=ros_context, parameter_overrides=list(overrides))
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


def test_run_returns_2_on_invalid_parameters(capfd):
    def factory():
        raise ParameterError('invalid parameters: icr.y_left must be finite')
    assert run(factory, 'probe', args=['probe']) == 2
    assert 'icr.y_left must be finite' in capfd.readouterr().err
