"""In-process tests of the bridge node: messages out of the sensor frames, parameters, errors."""
import math
import time

import can
import pytest

from mr_damper_can.driver_sim import SimulatedEcu
from ros_context import ros_context


@pytest.fixture
def ctx():
    """Return a context of its own and a list of the nodes made in it (destroyed after)."""
    made = []
    with ros_context(made) as context:
        yield context, made


def _make(ctx, **params):
    from rclpy.parameter import Parameter
    from mr_damper_can.can_bridge_node import CanBridgeNode
    context, made = ctx
    node = CanBridgeNode(context=context, namespace='canunit',
                         parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    made.append(node)
    return node


def test_sensor_frames_become_imu_and_car_state_messages(ctx):
    from rclpy.executors import SingleThreadedExecutor
    from mr_damper_interfaces.msg import QuarterCarState
    from sensor_msgs.msg import Imu
    from std_msgs.msg import Float64
    channel = f'node_test_{time.monotonic_ns()}'
    node = _make(ctx, interface='virtual', channel=channel, corners='fl,rr',
                 corner_namespaces=True, rx_timeout_s=60.0, command_timeout_s=60.0)
    got = {'imu': [], 'state': [], 'measured': []}
    node.create_subscription(Imu, 'rr/can/body_imu', got['imu'].append, 100)
    node.create_subscription(QuarterCarState, 'rr/can/car_state', got['state'].append, 100)
    node.create_subscription(Float64, 'fl/mr_damper/measured_current', got['measured'].append,
                             100)
    cmd = node.create_publisher(Float64, 'fl/mr_damper/current_command', 10)
    bus = can.Bus(interface='virtual', channel=channel)
    ecu = SimulatedEcu(bus, ('fl', 'rr'), command_timeout_s=60.0, tau_s=0.002)
    executor = SingleThreadedExecutor(context=ctx[0])
    executor.add_node(node)
    try:
        ecu.start()
        cmd.publish(Float64(data=1.5))
        end = time.monotonic() + 30.0
        while time.monotonic() < end and not (
                len(got['imu']) > 5 and len(got['state']) > 5
                and got['measured'] and abs(got['measured'][-1].data - 1.5) < 0.002):
            executor.spin_once(timeout_sec=0.01)
    finally:
        ecu.stop()
        bus.shutdown()
        executor.shutdown()
    imu, state = got['imu'][-1], got['state'][-1]
    assert imu.header.frame_id == 'rr_body' and imu.orientation_covariance[0] == -1.0
    assert math.isnan(imu.linear_acceleration.x) and abs(imu.linear_acceleration.z) <= 2.005
    amp = {'body_acceleration_m_s2': 2.0, 'wheel_acceleration_m_s2': 30.0,
           'suspension_travel_m': 0.02}
    for field, a in amp.items():       # the synthetic sines' amplitudes bound every value
        values = [getattr(m, field) for m in got['state']]
        assert all(abs(v) <= a * 1.003 + 1e-9 for v in values), field
        assert len(set(values)) > 1, field
    assert state.header.frame_id == 'rr' and math.isnan(state.body_velocity_m_s)
    # rr had no command: fail-safe, its safe current sent, the driver's current measured
    assert state.fail_safe_mode == QuarterCarState.MODE_FAIL_SAFE
    assert state.fail_safe_reason == 'no_command_yet' and state.current_command_a == 0.5
    st = node.status()
    assert st['corners']['fl']['mode'] == 'normal' and st['corners']['fl']['commands'] == 1


def test_bad_settings_are_refused(ctx):
    with pytest.raises(ValueError, match='corner_namespaces'):
        _make(ctx, interface='virtual', channel='x', corners='fl,fr')
    with pytest.raises(ValueError, match='corners must be'):
        _make(ctx, interface='virtual', channel='x', corners='fl,xx')


def test_safe_current_changes_while_running_within_the_dbc_range(ctx):
    from rclpy.parameter import Parameter
    node = _make(ctx, interface='virtual', channel=f'node_param_{time.monotonic_ns()}')
    assert node.set_parameters([Parameter('safe_current_a', value=1.2)])[0].successful
    assert node.core.safe_current_a == 1.2
    assert not node.set_parameters([Parameter('safe_current_a', value=3.0)])[0].successful
    assert node.core.safe_current_a == 1.2
    assert not node.set_parameters([Parameter('rx_timeout_s', value=1.0)])[0].successful


def test_driver_sim_node_takes_fault_requests(ctx):
    from rclpy.parameter import Parameter
    from std_msgs.msg import String
    from mr_damper_can.can_driver_sim_node import CanDriverSimNode
    from mr_damper_common.health import ERROR, OK
    context, made = ctx
    node = CanDriverSimNode(context=context, namespace='canunit', parameter_overrides=[
        Parameter('interface', value='virtual'), Parameter('corners', value='fl'),
        Parameter('channel', value=f'sim_node_{time.monotonic_ns()}')])
    made.append(node)
    assert node.health().level == OK
    node.on_fault(String(data='fl:gremlins'))
    node.on_fault(String(data='rr:open_load'))       # not a channel of this driver
    assert node.drops.counts() == {'bad_fault_request': 2}
    node.on_fault(String(data='fl:open_load'))
    health = node.health()
    assert health.level == ERROR and 'fl: open_load injected' in health.message
    node.on_fault(String(data='fl:none'))
    assert node.ecu.status()['corners']['fl']['fault'] == ''
