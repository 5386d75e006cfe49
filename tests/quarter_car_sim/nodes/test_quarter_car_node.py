"""In-process tests of the quarter-car node: parameters, callbacks, health, log file."""
import json
import math

import numpy as np
import pytest

from kwok_messages import thesis_parameters_msg
from mr_damper_common.contract import CornerState


@pytest.fixture
def node_factory(tmp_path):
    from rclpy.parameter import Parameter
    from quarter_car_sim.nodes.quarter_car_node import QuarterCarNode
    from ros_context import ros_context
    made = []
    with ros_context(made) as ctx:
        def make(**params):
            values = {'real_time_factor': 5.0, 'plant': 'kwok-current',
                      'road_duration_s': 30.0, 'log_file': str(tmp_path / 'log')}
            values.update(params)
            node = QuarterCarNode(context=ctx, namespace='h5unit', parameter_overrides=[
                Parameter(k, value=v) for k, v in values.items()])
            made.append(node)
            return node
        try:
            yield make
        finally:
            for node in made:
                node.stop()


def test_callbacks_drive_the_supervisor_and_health(node_factory, tmp_path):
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.health import flatten, OK, unflatten, WARN
    node = node_factory(safe_current_a=0.25)
    assert node.sup.safe_current_a == 0.25 and node.sup.mode == 'failsafe'
    h = node.health()
    # (the loop may also be late on a busy machine: another WARN, joined with '; ')
    assert h.level == WARN and 'fail-safe: no identified parameters yet' in h.message.split('; ')
    node.on_params(thesis_parameters_msg())
    assert node.sup.mode == 'normal'
    h = node.health()
    assert h.level in (OK, WARN) and 'fail-safe' not in h.message
    assert h.values['params_accepted'] == 1 and h.values['mode'] == 'normal'
    node.on_params(thesis_parameters_msg(valid=0.0))
    node.on_params(KwokParameters())              # i_ref_a 0: refused by its own reason
    h = node.health()
    assert h.level == WARN and h.message.startswith('fail-safe: parameters refused (bad_i_ref)')
    st = unflatten(flatten(h.values))             # what /diagnostics carries
    assert st['mode'] == 'failsafe' and st['reason'] == 'bad_i_ref'
    assert st['params_accepted'] == 1
    assert st['params_rejected']['invalid_flag'] == 1 and st['params_rejected']['bad_i_ref'] == 1
    assert st['params_rejected']['undecodable'] == 0
    assert set(st['ride_metrics']) >= {'rms_body_accel_wk', 'rms_tyre_load_ratio',
                                       'rms_suspension_travel'}
    assert set(st['loop']) >= {'period', 'lateness', 'latency', 'step'}
    assert 0.0 <= st['current_a'] <= 2.0 and st['safe_current_a'] == 0.25
    assert 'saturated_steps' in st and 'param_age_s' in st
    json.dumps(node.status())                     # JSON-ready (the log file's header)
    node.on_params(thesis_parameters_msg())
    import time
    deadline = time.monotonic() + 30.0               # hang guard only: count steps, not time
    while node.status()['steps'] <= 200 and time.monotonic() < deadline:
        time.sleep(0.01)
    st = node.status()
    assert st['steps'] > 200 and st['t_sim'] > -0.5 + 0.2
    assert st['loop']['steps'] == st['steps'] or st['loop']['steps'] >= st['steps'] - 1
    node.stop()
    from mr_damper_common.recording.columnlog import ColumnReader
    log = ColumnReader(tmp_path / 'log')
    z = log.read()
    assert z['t'].size >= st['steps'] and log.meta['dt'] == pytest.approx(1e-3)
    assert np.all((z['i_cmd'] >= 0.0) & (z['i_cmd'] <= 2.0))
    assert log.meta['status']['controller'] == 'skyhook'


def test_bad_parameters_raise_value_error(node_factory):
    with pytest.raises(ValueError, match='force actuator'):
        node_factory(controller='lqr-active')
    with pytest.raises(ValueError):
        node_factory(road_class='Z')


def test_state_message_layout():
    from quarter_car_sim.nodes.quarter_car_node import _fmt, STATE_JOINTS
    s = CornerState(0.1, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0)
    pos, vel, eff = _fmt(s)
    assert STATE_JOINTS == ('body', 'wheel', 'suspension', 'tyre')
    assert pos == [1.0, 4.0, 8.0, 7.0]               # z_s, z_u, travel, z_r
    assert vel == [2.0, 5.0, 9.0, 12.0]              # v_s, v_u, v_rel, coil current
    assert eff == [3.0, 6.0, 11.0, 10.0]             # a_s, a_u, damper force, tyre load
    assert not any(math.isnan(v) for v in pos + vel + eff)


def test_diagnostics_are_published_under_the_node_name(node_factory):
    node = node_factory(diagnostics_period_s=0.05)
    assert node.diagnostics.name == 'h5unit/quarter_car_node'
    health = node.diagnostics.publish()
    assert node.diagnostics.published == 1 and health.values['controller'] == 'skyhook'


def test_dynamic_parameters_reach_the_cores_and_the_rest_is_refused(node_factory):
    from rclpy.parameter import Parameter
    node = node_factory(controller_options='{"c_sky": 3000.0}')
    assert node.loop.controller.c_sky == 3000.0
    res = node.set_parameters([Parameter('controller_options', value='{"c_sky": 4500.0}'),
                               Parameter('safe_current_a', value=0.8),
                               Parameter('param_timeout_s', value=2.5),
                               Parameter('hold_on_reject', value=True),
                               Parameter('min_current_span_a', value=0.5),
                               Parameter('lateness_warn_ms', value=9.0)])
    assert all(r.successful for r in res), res
    assert node.loop.controller.c_sky == 4500.0
    assert (node.sup.safe_current_a, node.sup.timeout_s) == (0.8, 2.5)
    assert node.sup.hold_on_reject and node.sup.min_current_span_a == 0.5
    assert node.health_rules.lateness_warn_ms == 9.0
    # refused by the core (bad option, safe current outside the coil range): nothing changes
    res = node.set_parameters([Parameter('controller_options', value='{"nope": 1}')])
    assert not res[0].successful and 'controller_options refused' in res[0].reason
    res = node.set_parameters_atomically([Parameter('safe_current_a', value=3.0),
                                          Parameter('param_timeout_s', value=9.0)])
    assert not res.successful and 'safe_current_a' in res.reason
    assert (node.sup.safe_current_a, node.sup.timeout_s) == (0.8, 2.5)
    assert node.loop.controller.c_sky == 4500.0
    # start-up only: read-only, refused with a reason
    res = node.set_parameters([Parameter('rate_hz', value=500.0)])
    assert not res[0].successful and 'read-only' in res[0].reason
    assert node.rate_hz == 1000.0
    # out of range: refused by rclpy
    res = node.set_parameters([Parameter('param_timeout_s', value=-1.0)])
    assert not res[0].successful and node.sup.timeout_s == 2.5
    # command_timeout_s has no command input with the built-in controller
    res = node.set_parameters([Parameter('command_timeout_s', value=0.5)])
    assert not res[0].successful and 'controller:=external' in res[0].reason


def test_parameter_age_is_on_the_node_clock(node_factory):
    from rclpy.clock import ClockType
    from rclpy.time import Time
    node = node_factory(real_time_factor=0.5)
    now = node.get_clock().now().nanoseconds * 1e-9
    node.on_params(thesis_parameters_msg())
    assert node.sup.accepted_at == pytest.approx(now, abs=5.0)    # ROS time, not monotonic
    assert node.get_clock().clock_type == ClockType.ROS_TIME
    assert Time(seconds=node.sup.accepted_at).nanoseconds > 0


def test_dead_control_thread_is_an_error_on_diagnostics_and_ends_the_node(node_factory):
    import time
    import rclpy
    from mr_damper_common.health import ERROR
    node = node_factory(real_time_factor=0.5, log_file='')

    def broken():
        raise RuntimeError('plant diverged')
    node.loop.advance = broken                       # injected fault in the next step
    deadline = time.monotonic() + 30.0               # hang guard only
    while rclpy.ok(context=node.context) and time.monotonic() < deadline:
        time.sleep(0.01)
    assert node.failed == 'RuntimeError: plant diverged'
    assert node.diagnostics.published == 1           # said once, then the shutdown
    h = node.health()
    assert h.level == ERROR and h.message == 'control thread died: RuntimeError: plant diverged'
    assert not rclpy.ok(context=node.context)        # the process now exits 1


def test_parameter_timeout_runs_on_ros_time_under_use_sim_time(node_factory):
    import time
    from rclpy.time import Time
    node = node_factory(use_sim_time=True, param_timeout_s=1.0, real_time_factor=0.5)
    clock = node.get_clock()
    assert clock.ros_time_is_active
    clock.set_ros_time_override(Time(seconds=100.0))     # what a /clock message does
    node.on_params(thesis_parameters_msg())
    assert node.sup.accepted_at == pytest.approx(100.0)
    # the control thread steps on (wall-paced) while ROS time stands: the model stays fresh
    steps = node.loop.steps
    deadline = time.monotonic() + 30.0                   # hang guard only
    while node.loop.steps < steps + 50 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert node.sup.mode == 'normal' and node.status()['param_age_s'] == pytest.approx(0.0)
    clock.set_ros_time_override(Time(seconds=101.5))     # 1.5 s of ROS time later: stale
    while node.sup.reason != 'stale' and time.monotonic() < deadline:
        time.sleep(0.01)
    assert (node.sup.mode, node.sup.reason) == ('failsafe', 'stale')


def test_vehicle_sensing_publishes_the_sensors_and_moves_the_true_state(node_factory):
    """sensing:=vehicle: Imu and JointState readings of the sampler, true state elsewhere."""
    import time
    from semi_active_control.estimation.sensor_specs import G0
    with pytest.raises(ValueError, match='needs controller:=external'):
        node_factory(sensing='vehicle')
    with pytest.raises(ValueError, match="'ideal' or 'vehicle'"):
        node_factory(sensing='perfect', controller='external')
    node = node_factory(controller='external', sensing='vehicle', sensor_dropout_start_s=0.1,
                        sensor_dropout_s=0.05)
    assert node.car_state_pub.topic_name == '/h5unit/quarter_car/true_state'
    assert node.imu_pub.topic_name == '/h5unit/quarter_car/body_imu'
    assert node.position_pub.topic_name == '/h5unit/quarter_car/suspension_position'
    deadline = time.monotonic() + 30.0          # hang guard: the car runs at 5x real time
    while node.car.state.t < 0.3 and time.monotonic() < deadline:
        time.sleep(0.02)
    st = node.status()['sensing']
    # every control step sampled both sensors; the 50 ms window (1 kHz) lost, counted
    assert st['sensors']['body_accel']['samples'] == st['sensors']['travel']['samples'] > 300
    assert st['sensors']['body_accel']['lost'] >= 50
    assert st['dropout_window_s'] == [0.1, 0.05]
    # the messages carry the sampler's readings: specific force and travel, stamped >= 0
    assert node.imu_msg.orientation_covariance[0] == -1.0
    assert abs(node.imu_msg.linear_acceleration.z - G0) < 20.0
    assert node.position_msg.name == ['suspension'] and len(node.position_msg.position) == 1
    assert node.position_msg.header.stamp.sec >= 0
