"""The vehicle nodes in-process (no ROS graph): lifecycle callbacks, inputs, outputs."""
import numpy as np
import pytest

from conftest import REPO

MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'


@pytest.fixture
def context():
    """Yield a private rclpy context; its nodes are destroyed after the test."""
    import rclpy
    from rclpy.context import Context
    ctx = Context()
    rclpy.init(context=ctx)
    nodes = []
    ctx.nodes = nodes
    try:
        yield ctx
    finally:
        while nodes:
            nodes.pop().destroy_node()
        rclpy.try_shutdown(context=ctx)


def _make(context, cls, **params):
    from rclpy.parameter import Parameter
    node = cls(context=context, namespace='vnunit',
               parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    context.nodes.append(node)
    return node


def test_estimator_node_takes_imu_and_joint_state_readings(context):
    from sensor_msgs.msg import Imu, JointState
    from mr_damper_common.lifecycle_utils import state_label
    from semi_active_control.estimation.sensor_specs import G0
    from semi_active_control.nodes.vehicle_estimator_node import VehicleEstimatorNode
    node = _make(context, VehicleEstimatorNode, input='topics')
    assert state_label(node) == 'unconfigured'
    node.trigger_configure()
    node.trigger_activate()
    assert state_label(node) == 'active'
    published = []                             # (sequence, valid, faults) as published
    node.pub.publish = lambda m: published.append((m.sequence, m.valid, list(m.sensor_faults)))
    rng = np.random.default_rng(2)
    for k in range(1, 40):
        for c in ('fl', 'fr', 'rl', 'rr'):
            imu = Imu()
            imu.linear_acceleration.z = G0 + 0.05 * rng.standard_normal()
            node.on_reading(f'accel_{c}', imu.linear_acceleration.z - G0)
        for c in ('rr', 'rl', 'fr', 'fl'):       # the clock corner (fl) last: it runs the cycle
            msg = JointState(position=[1e-4 * rng.standard_normal()])
            msg.header.stamp.sec, msg.header.stamp.nanosec = 0, k * 2_000_000
            node.on_position(c, msg)
    assert [p[0] for p in published] == list(range(1, 40))
    assert published[-1][1:] == (True, [])
    st = node.status()
    assert st['readings_received']['accel_rr'] == 39 and st['cycles']['lost'] == 0
    node.trigger_deactivate()
    node.on_position('fl', msg)                 # inactive: nothing published
    assert len(published) == 39


def test_controller_node_answers_states_and_deactivates_safe(context):
    from mr_damper_interfaces.msg import FullCarCommand, FullCarState
    from semi_active_control.nodes.vehicle_controller_node import VehicleControllerNode
    files = [str(MODELS / f'{c}.json') for c in ('fl', 'fr', 'rl', 'rr')]
    node = _make(context, VehicleControllerNode, model_files=files,
                 max_consecutive_misses=100000, sensor_timeout_s=60.0)
    node.trigger_configure()
    sent = []
    node.cmd_pub.publish = lambda m: sent.append((list(m.current_a), list(m.mode),
                                                  list(m.reason), m.state_sequence))
    state = FullCarState()
    state.valid = True
    state.heave_velocity_m_s = 0.1
    state.suspension_velocity_m_s = [0.1, 0.1, -0.1, -0.1]
    state.header.stamp.sec = 1
    node.on_state(state)
    assert sent == []                            # configured, not active: no command
    node.trigger_activate()
    for k in range(1, 6):
        state.sequence = k
        state.header.stamp = node.get_clock().now().to_msg()    # fresh: within its deadline
        node.on_state(state)
    assert [s[3] for s in sent] == [1, 2, 3, 4, 5]
    assert all(s[1] == [FullCarCommand.MODE_NORMAL] * 4 for s in sent)
    state.sequence = 6
    state.header.stamp.sec -= 1                  # held up for a second: skipped, a miss
    node.on_state(state)
    assert len(sent) == 5 and node.status()['states_skipped_late'] == 1
    node.trigger_deactivate()
    assert sent[-1][0] == [0.5] * 4 and sent[-1][1] == [FullCarCommand.MODE_INACTIVE] * 4
    assert sent[-1][2] == ['inactive'] * 4
    assert node.status()['corners']['fl']['source'] == 'file'
