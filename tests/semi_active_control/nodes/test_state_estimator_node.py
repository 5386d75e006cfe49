"""The estimator node's core and callbacks in-process (no ROS graph): counts and fields."""
import math

import numpy as np
import pytest

from kwok_messages import thesis_parameters_msg
from ros_context import ros_context


@pytest.fixture
def make_node():
    """Build estimator nodes in a private rclpy context; destroyed after the test."""
    from rclpy.parameter import Parameter
    from semi_active_control.nodes.state_estimator_node import StateEstimatorNode
    nodes = []
    with ros_context(nodes) as context:
        def make(**params):
            overrides = [Parameter(k, value=v) for k, v in params.items()]
            nodes.append(StateEstimatorNode(context=context, namespace='seunit',
                                            parameter_overrides=overrides))
            return nodes[-1]
        yield make


def _position(x, t=None):
    """Return a serialised JointState reading (the node's readers take raw messages)."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    msg = JointState(name=['suspension'], position=[x])
    if t is not None:
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), round((t - int(t)) * 1e9)
    return serialize_message(msg)


def test_node_publishes_valid_then_marked_invalid_states(make_node):
    from semi_active_control.estimation.sensor_specs import G0
    # the set must not go stale while the loop runs (node clock = wall time; a loaded machine
    # took over 1 s for the 200 periods below): the truth here is the dropout, not the timeout
    node = make_node(dropout_s=0.02, param_timeout_s=3600.0)
    sent = []
    node.pub.publish = lambda m: sent.append((m.fail_safe_mode, m.fail_safe_reason,
                                              m.body_velocity_m_s, m.wheel_displacement_m,
                                              m.road_height_m))
    rng = np.random.default_rng(1)
    node.on_params(thesis_parameters_msg())
    for _ in range(200):
        node.core.offer_reading('body_accel', G0 + 0.05 * rng.standard_normal())
        node.on_position(_position(5e-5 * rng.standard_normal()))
        node.on_tick()
    mode, reason, v_s, z_u, z_r = sent[-1]
    assert (mode, reason) == (0, 'ok') and math.isfinite(v_s) and math.isfinite(z_u)
    assert z_r == 0.0
    # the body accelerometer goes silent: after dropout_s of node time the state is marked
    t_end = node.core.last.t + 0.5
    while node.core.last.t < t_end and node.core.last.valid:
        node.on_position(_position(5e-5 * rng.standard_normal()))
        node.on_tick()
    mode, reason, v_s, z_u, _ = sent[-1]
    assert mode == 1 and reason == 'dropout_body_accel'
    assert math.isnan(v_s) and math.isnan(z_u)
    h = node.health()
    assert h.level == 1 and 'dropout_body_accel' in h.message
    assert h.values['invalid_entries'] == {'dropout_body_accel': 1}
    assert node.diagnostics.name == 'seunit/state_estimator'
    node.on_position(_position(math.nan))           # a lost sample: counted, not used
    node.on_tick()
    assert node.core.estimator.samples_missing['travel'] == 1


def test_node_reads_serialised_readings_with_their_stamps(make_node):
    """The raw readers: stamps and values from the serialised messages, losses counted."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
    from semi_active_control.estimation.sensor_specs import G0
    node = make_node(clock='readings')
    sent = []
    node.pub.publish = lambda m: sent.append((m.header.stamp.sec, m.header.stamp.nanosec))
    node.on_params(thesis_parameters_msg())
    imu = Imu()
    imu.header.frame_id = 'body'
    for k in range(1, 60):
        if k % 10 == 5:
            continue                                # lost on the way: both sensors
        imu.header.stamp.nanosec = k * 1_000_000
        imu.linear_acceleration.z = G0 + 0.01 * (k % 3)
        node.on_accel('body_accel', serialize_message(imu))
        node.on_position(_position(1e-5 * (k % 4), k * 1e-3))
    st = node.status()
    assert st['readings_received'] == {'body_accel': 53, 'travel': 53}
    assert st['readings_lost'] == {'body_accel': 6, 'travel': 6}
    # one estimate per reading, stamped with it; the lost periods predicted through
    assert len(sent) == 53 and sent[-1] == (0, 59_000_000)
    assert st['predict_steps'] == 6 and st['steps'] == 59
    assert node.core.estimator._last_val['body_accel'] == pytest.approx(G0 + 0.01 * (59 % 3))
    node.on_position(b'\x00\x01\x00\x00\x01')      # plain CDR, cut short: counted
    node.on_position(b'\x00\x07\x00\x00')           # not plain CDR, undecodable: counted
    assert node.status()['dropped'] == {'undecodable_reading': 2}
    assert len(sent) == 53
