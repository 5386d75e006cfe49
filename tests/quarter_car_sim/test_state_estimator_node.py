"""The estimator node's core and callbacks in-process (no ROS graph): counts and fields."""
import math

import numpy as np
import pytest

from kwok_messages import thesis_parameters_msg


@pytest.fixture
def make_node():
    """Build estimator nodes in a private rclpy context; destroyed after the test."""
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter
    from quarter_car_sim.state_estimator_node import StateEstimatorNode
    context = Context()
    rclpy.init(context=context)
    nodes = []

    def make(**params):
        overrides = [Parameter(k, value=v) for k, v in params.items()]
        nodes.append(StateEstimatorNode(context=context, namespace='seunit',
                                        parameter_overrides=overrides))
        return nodes[-1]
    try:
        yield make
    finally:
        while nodes:
            nodes.pop().destroy_node()
        rclpy.try_shutdown(context=context)


def _position(x):
    from sensor_msgs.msg import JointState
    return JointState(name=['suspension'], position=[x])


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
