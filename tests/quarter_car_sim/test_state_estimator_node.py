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
    from quarter_car_sim.state_estimator_node import StateEstimatorNode
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


def test_core_needs_a_model_then_estimates_and_counts_faults():
    from mr_damper_common.messages import kwok_parameters_flat
    from quarter_car_sim.failsafe import ModelSupervisor
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.sensors import default_specs, G0
    from quarter_car_sim.state_estimator_core import StateEstimatorCore
    core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor())
    rng = np.random.default_rng(0)

    def tick(k, acc=True):
        if acc:
            core.offer_reading('body_accel', G0 + 0.05 * rng.standard_normal())
        core.offer_reading('travel', 5e-5 * rng.standard_normal())
        return core.tick(k * 1e-3)
    e = tick(0)
    assert not e.valid and e.reason == 'no_model'
    core.offer_parameters(kwok_parameters_flat(thesis_parameters_msg()), 0.001)
    for k in range(1, 300):
        e = tick(k)
    assert e.valid and math.isfinite(e.v_s)
    for k in range(300, 340):
        e = tick(k, acc=False)
    assert not e.valid and e.reason == 'dropout_body_accel'
    st = core.status()
    assert st['no_model_entries'] == 1 and st['no_model_steps'] == 1
    assert st['invalid_entries'] == {'dropout_body_accel': 1}
    core.offer_reading('travel', 0.0)
    core.offer_reading('travel', 0.0)
    assert core.readings_replaced['travel'] == 1
    assert core.offer_current(math.nan) is False and core.offer_current(1.5)
    assert core.current_a == 1.5
    with pytest.raises(ValueError, match='wheel_accel'):
        core.offer_reading('wheel_accel', 1.0)


def test_node_publishes_valid_then_marked_invalid_states(make_node):
    from quarter_car_sim.sensors import G0
    node = make_node(dropout_s=0.02)
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


def test_core_clocked_by_readings_predicts_through_missing_periods():
    """tick_at: the readings' stamps are the filter's time; gaps predicted, counted."""
    from mr_damper_common.messages import kwok_parameters_flat
    from quarter_car_sim.failsafe import ModelSupervisor
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.sensors import default_specs, G0
    from quarter_car_sim.state_estimator_core import REBASE_S, StateEstimatorCore
    core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor())
    core.offer_parameters(kwok_parameters_flat(thesis_parameters_msg()), 0.0)
    rng = np.random.default_rng(1)
    stamps = [k * 1e-3 for k in range(400) if k % 7 != 3]      # every 7th reading lost
    for t in stamps:
        core.offer_reading('body_accel', G0 + 0.05 * rng.standard_normal())
        core.offer_reading('travel', 5e-5 * rng.standard_normal())
        e = core.tick_at(t, 0.0)
    # one filter step per control period of the vehicle's time, whatever was lost
    assert core.estimator.steps == 400
    assert core.predict_steps == 400 - len(stamps)
    assert e.valid and e.t == pytest.approx(stamps[-1])
    # a reading not after the last tick: no step, counted; the reading waits
    core.offer_reading('travel', 0.0)
    assert core.tick_at(stamps[-1], 0.0) is None and core.stale_ticks == 1
    assert core.estimator.steps == 400
    # the vehicle's clock restarted: the time line re-bases instead of 400 s of prediction
    assert core.tick_at(stamps[-1] - 2 * REBASE_S, 0.0) is not None
    assert core.rebases == 1 and core.estimator.steps == 401


def test_core_counts_readings_lost_between_stamps():
    """Readings the vehicle sent that never arrived: the periods skipped between stamps."""
    from quarter_car_sim.failsafe import ModelSupervisor
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.sensors import accelerometer_spec, default_specs, G0
    from quarter_car_sim.state_estimator_core import REBASE_S, StateEstimatorCore
    core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor())
    sent = range(1000)
    lost = {k for k in sent if k % 9 == 4} | set(range(500, 530))
    for k in sent:
        if k not in lost:
            core.offer_reading('travel', 0.0, k * 1e-3)
        if k % 2:                                   # every other accelerometer reading lost
            core.offer_reading('body_accel', G0, k * 1e-3)
    # the last reading of each stream arrived, so every lost one lies between two stamps
    assert core.readings_lost['travel'] == len(lost)
    assert core.readings_received['travel'] + core.readings_lost['travel'] == len(sent)
    assert core.readings_lost['body_accel'] == 499        # 1, 3, ..., 999: 499 gaps
    # not newer (a repeat): nothing skipped; a clock restart: no loss counted
    core.offer_reading('travel', 0.0, 0.999)
    core.offer_reading('travel', 0.0, 0.999 - 2 * REBASE_S)
    core.offer_reading('travel', 0.0, 1.0 - 2 * REBASE_S)
    assert core.readings_lost['travel'] == len(lost)
    # a sensor slower than the control rate counts in its own sample period (4 ms)
    specs = dict(default_specs(), body_accel=accelerometer_spec(rate_hz=250.0))
    slow = StateEstimatorCore(QuarterCarParams(), 1e-3, specs, ModelSupervisor())
    for k in (0, 1, 2, 4):
        slow.offer_reading('body_accel', G0, k * 4e-3)
    assert slow.readings_lost['body_accel'] == 1
    assert core.status()['readings_lost'] == dict(core.readings_lost)


def test_node_reads_serialised_readings_with_their_stamps(make_node):
    """The raw readers: stamps and values from the serialised messages, losses counted."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
    from quarter_car_sim.sensors import G0
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
