"""Tests of node_utils.parameters: descriptions, ranges, read-only start-up parameters."""
import pytest
import rclpy

from mr_damper_common import node_utils
import node_utils_helpers

ros = node_utils_helpers.ros      # this module's rclpy context (fixture)


_SPECS = (
    node_utils.Param('gain', 2.0, 'Controller gain [N s/m]', 0.0, 10.0, dynamic=True),
    node_utils.Param('safe_current_a', 0.5, 'Safe current [A]', 0.0, 2.0, dynamic=True),
    node_utils.Param('window', 3, 'Window count [-]', 1, 100),
    node_utils.Param('mode', 'sim', 'Source of the samples'),
)


def test_parameters_have_descriptions_ranges_and_refuse_what_cannot_change(ros):
    from rclpy.parameter import Parameter
    node = rclpy.create_node('param_spec_test', context=ros)
    applied = []

    def on_set(changes):
        if changes.get('gain', 0.0) > 5.0 and 'safe_current_a' not in changes:
            return 'gain above 5 needs a safe current in the same request'
        applied.append(changes)
        return ''

    values = node_utils.declare_parameters(node, _SPECS, on_set)
    assert values == {'gain': 2.0, 'safe_current_a': 0.5, 'window': 3, 'mode': 'sim'}
    desc = node.describe_parameter('gain')
    assert desc.description == 'Controller gain [N s/m]' and not desc.read_only
    assert (desc.floating_point_range[0].from_value,
            desc.floating_point_range[0].to_value) == (0.0, 10.0)
    assert node.describe_parameter('window').integer_range[0].to_value == 100
    assert node.describe_parameter('mode').read_only
    # a dynamic parameter in range is applied through the callback
    result = node.set_parameters([Parameter('gain', value=4.0)])[0]
    assert result.successful and applied == [{'gain': 4.0}]
    assert node.get_parameter('gain').value == 4.0
    # out of range: rclpy refuses before the callback
    result = node.set_parameters([Parameter('gain', value=11.0)])[0]
    assert not result.successful and 'out of range' in result.reason
    # the node's own check refuses with its reason; nothing changes
    result = node.set_parameters([Parameter('gain', value=6.0)])[0]
    assert not result.successful and 'safe current' in result.reason
    assert node.get_parameter('gain').value == 4.0 and len(applied) == 1
    # start-up-only parameters are refused, not accepted and ignored
    result = node.set_parameters([Parameter('mode', value='csv')])[0]
    assert not result.successful and 'read-only' in result.reason
    assert node.get_parameter('mode').value == 'sim'
    node.destroy_node()


def test_a_value_out_of_range_at_start_up_is_a_parameter_error(ros):
    from rclpy.exceptions import ParameterException
    from rclpy.parameter import Parameter
    node = rclpy.create_node('param_range_test', context=ros, parameter_overrides=[
        Parameter('window', value=0)])
    with pytest.raises(ParameterException):
        node_utils.declare_parameters(node, _SPECS[2:])
    node.destroy_node()


def test_dynamic_parameters_need_an_on_set_callback(ros):
    node = rclpy.create_node('param_no_callback', context=ros)
    with pytest.raises(ValueError, match='on_set'):
        node_utils.declare_parameters(node, _SPECS[:1])
    node.destroy_node()
