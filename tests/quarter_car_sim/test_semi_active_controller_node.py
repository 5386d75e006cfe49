"""In-process tests of the controller node and of the car's external branch (callbacks)."""
import math
import time

import pytest

from kwok_messages import thesis_parameters_msg
from ros_context import ros_context


@pytest.fixture
def ctx():
    made = []
    with ros_context(made) as context:
        try:
            yield context, made
        finally:
            for node in made:
                if hasattr(node, 'stop'):
                    node.stop()


def _make(ctx, cls, **params):
    from rclpy.parameter import Parameter
    context, made = ctx
    node = cls(context=context, namespace='cnunit',
               parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    made.append(node)
    return node


def _car_state(t=1.0, v_s=0.3, v_rel=0.2):
    from quarter_car_sim.dynamics import CarState
    return CarState(t, 0.01, v_s, 2.0, 0.0, v_s - v_rel, -1.0, 0.0, 0.01, v_rel, 2900.0, -50.0,
                    0.4)


def test_state_message_round_trip_keeps_the_law_fields():
    from quarter_car_sim.controller_core import LAW_FIELDS
    from quarter_car_sim.semi_active_controller_node import (car_state_to_msg,
                                                             vehicle_state_from_msg)
    s = _car_state(t=2.5)
    msg = car_state_to_msg(s, 1.25, False, 'stale')
    v = vehicle_state_from_msg(msg)
    assert v.t == pytest.approx(2.5, abs=1e-9)
    for name in LAW_FIELDS + ('z_u', 'z_r'):     # and the LQR laws' tyre deflection
        assert getattr(v, name) == getattr(s, name)
    assert msg.current_command_a == 1.25 and msg.fail_safe_reason == 'stale'
    assert msg.fail_safe_mode == msg.MODE_FAIL_SAFE
    assert (msg.tyre_load_n, msg.coil_current_a) == (s.tyre_force, s.coil_current)


def test_controller_node_answers_states_through_the_supervised_core(ctx):
    from mr_damper_interfaces.msg import KwokParameters
    from quarter_car_sim.semi_active_controller_node import (car_state_to_msg,
                                                             SemiActiveControllerNode)
    node = _make(ctx, SemiActiveControllerNode, safe_current_a=0.25)
    sent = []
    node.cmd_pub.publish = lambda m: sent.append(m.data)
    node.on_state(car_state_to_msg(_car_state(1.0), 0.0, True, 'ok'))
    assert sent == [0.25] and node.status()['reason'] == 'no_parameters_yet'
    node.on_params(thesis_parameters_msg())
    node.on_state(car_state_to_msg(_car_state(1.001), 0.0, True, 'ok'))
    assert node.core.sup.mode == 'normal' and 0.0 <= sent[-1] <= 2.0 and sent[-1] != 0.25
    bad = car_state_to_msg(_car_state(1.002, v_s=math.nan), 0.0, True, 'ok')
    node.on_state(bad)
    assert sent[-1] == 0.25
    # the safe current for a state reason: the status says so, with the model still in use
    st = node.status()
    assert (st['mode'], st['reason']) == ('failsafe', 'state_non_finite')
    assert node.core.sup.mode == 'normal'
    from mr_damper_common.health import WARN
    h = node.health()                               # what /diagnostics carries
    assert h.level == WARN and 'fail-safe: vehicle state refused' in h.message
    assert 'states refused since the last check: 1 non_finite' in h.message
    node.on_params(KwokParameters())               # i_ref_a 0: refused by its own reason
    node.on_state(car_state_to_msg(_car_state(1.003), 0.0, True, 'ok'))
    assert sent[-1] == 0.25
    st = node.status()
    assert st['mode'] == 'failsafe' and st['reason'] == 'bad_i_ref'
    assert st['commands'] == 4 and st['commands_normal'] == 1
    assert st['state_rejected'] == {'non_finite': 1, 'future_stamp': 0, 'out_of_order': 0}
    assert st['params_accepted'] == 1 and st['params_rejected']['bad_i_ref'] == 1
    assert st['params_rejected']['undecodable'] == 0
    h = node.health()
    assert h.level == WARN and h.message.startswith('fail-safe: parameters refused (bad_i_ref)')
    assert h.values['commands'] == 4 and node.diagnostics.name == 'cnunit/semi_active_controller'


@pytest.mark.parametrize('law', ['clipped-optimal', 'clipped-optimal-wk'])
def test_controller_node_runs_the_lqr_laws_on_the_state_message(ctx, law):
    """The LQR laws read the tyre deflection (wheel displacement - road height) of the state."""
    from quarter_car_sim.controller_core import ControllerCore
    from quarter_car_sim.controllers import make_controller
    from quarter_car_sim.failsafe import ModelSupervisor
    from quarter_car_sim.semi_active_controller_node import (car_state_to_msg,
                                                             SemiActiveControllerNode,
                                                             vehicle_state_from_msg)
    from mr_damper_common.messages import kwok_parameters_flat
    node = _make(ctx, SemiActiveControllerNode, controller=law, safe_current_a=0.25)
    sent = []
    node.cmd_pub.publish = lambda m: sent.append(m.data)
    ref = ControllerCore(make_controller(law, damper_only=True),
                         ModelSupervisor(safe_current_a=0.25))
    params = thesis_parameters_msg()
    node.on_params(params)
    ref.offer_parameters(kwok_parameters_flat(params), 0.0)
    for k in range(5):
        msg = car_state_to_msg(_car_state(1.0 + 1e-3 * k, v_s=-0.3, v_rel=0.2), 0.0, True, 'ok')
        node.on_state(msg)
        assert sent[-1] == ref.command(vehicle_state_from_msg(msg), 0.0)
    st = node.status()
    assert st['commands_normal'] == 5 and st['state_rejected']['non_finite'] == 0
    assert sent[-1] != 0.25
    # a vehicle that leaves the road height NaN: the LQR law cannot run, the safe current
    blind = car_state_to_msg(_car_state(1.01), 0.0, True, 'ok')
    blind.road_height_m = math.nan
    node.on_state(blind)
    assert sent[-1] == 0.25 and node.status()['state_rejected']['non_finite'] == 1


def test_controller_node_refuses_an_active_controller(ctx):
    from quarter_car_sim.semi_active_controller_node import SemiActiveControllerNode
    with pytest.raises(ValueError, match='force actuator'):
        _make(ctx, SemiActiveControllerNode, controller='skyhook-ideal')


def _steps_later(node, n):
    """Wait until the car's control thread made ``n`` more steps (hang guard only)."""
    steps = node.status()['steps']
    deadline = time.monotonic() + 30.0
    while node.status()['steps'] < steps + n and time.monotonic() < deadline:
        time.sleep(0.01)
    return node.status()


def test_car_external_branch_counts_commands_and_times_out(ctx, tmp_path):
    from rclpy.time import Time
    from std_msgs.msg import Float64
    from quarter_car_sim.quarter_car_node import QuarterCarNode
    # the command timeout runs on the node clock: under use_sim_time the test sets the time,
    # so a starved control thread cannot turn "fresh" into "timed out" between two checks
    node = _make(ctx, QuarterCarNode, controller='external', real_time_factor=2.0,
                 plant='kwok-current', road_duration_s=30.0, command_timeout_s=0.2,
                 safe_current_a=0.5, log_file=str(tmp_path / 'log'), use_sim_time=True)
    clock = node.get_clock()
    clock.set_ros_time_override(Time(seconds=100.0))
    st = node.status()
    assert (st['mode'], st['reason'], st['controller']) == ('failsafe', 'no_command_yet',
                                                            'external')
    assert 'fail-safe: no current command yet' in node.health().message.split('; ')
    for value in (1.2, -1.0, 5.0, math.nan):
        node.on_command(Float64(data=value))
    st = node.status()
    assert st['commands'] == {'accepted': 1, 'clamped_low': 1, 'clamped_high': 1,
                              'refused_non_finite': 1}
    st = _steps_later(node, 20)                   # the loop applies the command
    assert st['mode'] == 'normal' and st['current_a'] == 2.0      # the clamped 5 A
    assert st['command_timeouts'] == 0
    clock.set_ros_time_override(Time(seconds=100.5))   # no command for 0.5 s > 0.2 s
    st = _steps_later(node, 20)
    assert (st['mode'], st['reason']) == ('failsafe', 'command_timeout')
    assert st['command_timeouts'] == 1 and st['current_a'] == 0.5


def test_car_external_with_the_rig_as_plant_keeps_stepping(ctx, tmp_path):
    """
    plant:=rig with controller:=external (hil --external-controller) keeps stepping.

    Lock-step is off here: the test is that the rig plant's wait and the external command
    input coexist (their Condition and Event no longer share a name). The car holds step 0
    until a rig answers: a stand-in rig (real topics) answers each displacement command with
    one measured sample, as the rig node does.
    """
    import threading
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64
    from mr_damper_common.messages import samples_to_msg
    from mr_damper_interfaces.msg import DamperSamples
    from quarter_car_sim.quarter_car_node import QuarterCarNode
    context, made = ctx
    rig = rclpy.create_node('stand_in_rig', context=context)
    made.append(rig)
    answers = rig.create_publisher(DamperSamples, 'cnunit/mr_damper/hil_measurement', 10)
    sent = []

    def answer(msg):
        k = len(sent)
        sent.append(msg.data)
        answers.publish(samples_to_msg([k * 1e-3], [msg.data], [0.0], [100.0], [1.0],
                                       sequence=k, first_index=k, sample_period_s=1e-3))
    rig.create_subscription(Float64, 'cnunit/mr_damper/displacement_command', answer, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(rig)
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()
    node = _make(ctx, QuarterCarNode, controller='external', plant='rig', real_time_factor=2.0,
                 road_duration_s=30.0, safe_current_a=0.5, log_file=str(tmp_path / 'log'))
    node.on_command(Float64(data=1.0))
    st = _steps_later(node, 50)
    assert node.failed is None and st['steps'] >= 50
    assert st['commands']['accepted'] == 1
    # step 0 came after the rig answered the car's neutral command (hil_wait_s 0: the steps
    # after it do not wait for each answer)
    assert sent[0] == 0.0 and st['hil']['counts']['measurements'] >= 1
    executor.shutdown(timeout_sec=1.0)


def test_controller_node_dynamic_parameters(ctx):
    from rclpy.parameter import Parameter
    from quarter_car_sim.semi_active_controller_node import SemiActiveControllerNode
    node = _make(ctx, SemiActiveControllerNode, controller_options='{"c_sky": 3000.0}')
    res = node.set_parameters([Parameter('controller_options', value='{"c_sky": 5000.0}'),
                               Parameter('safe_current_a', value=0.3),
                               Parameter('param_timeout_s', value=7.0)])
    assert all(r.successful for r in res), res
    assert node.core.controller.c_sky == 5000.0
    assert (node.core.sup.safe_current_a, node.core.sup.timeout_s) == (0.3, 7.0)
    res = node.set_parameters([Parameter('controller_options', value='not json')])
    assert not res[0].successful and 'controller_options refused' in res[0].reason
    res = node.set_parameters([Parameter('controller', value='groundhook')])
    assert not res[0].successful and 'read-only' in res[0].reason
    res = node.set_parameters([Parameter('safe_current_a', value=11.0)])     # out of range
    assert not res[0].successful and node.core.sup.safe_current_a == 0.3
    assert node.core.controller.c_sky == 5000.0


def test_car_external_command_timeout_is_dynamic(ctx, tmp_path):
    from rclpy.parameter import Parameter
    from quarter_car_sim.quarter_car_node import QuarterCarNode
    node = _make(ctx, QuarterCarNode, controller='external', real_time_factor=0.5,
                 plant='kwok-current', road_duration_s=30.0, command_timeout_s=0.2)
    res = node.set_parameters([Parameter('command_timeout_s', value=0.7),
                               Parameter('safe_current_a', value=0.6)])
    assert all(r.successful for r in res), res
    assert (node.cmd_in.timeout_s, node.cmd_in.safe_current_a) == (0.7, 0.6)
    assert node.sup.safe_current_a == 0.6
    res = node.set_parameters([Parameter('controller_options', value='{"c_sky": 1.0}')])
    assert not res[0].successful and 'no built-in controller' in res[0].reason


def test_parameter_age_and_timeout_follow_ros_time_under_use_sim_time(ctx):
    from rclpy.parameter import Parameter
    from rclpy.time import Time
    from quarter_car_sim.semi_active_controller_node import (car_state_to_msg,
                                                             SemiActiveControllerNode)
    node = _make(ctx, SemiActiveControllerNode, param_timeout_s=1.0)
    node.set_parameters([Parameter('use_sim_time', value=True)])
    clock = node.get_clock()
    assert clock.ros_time_is_active
    clock.set_ros_time_override(Time(seconds=100.0))      # what a /clock message does
    node.on_params(thesis_parameters_msg())
    assert node.core.sup.accepted_at == pytest.approx(100.0)
    clock.set_ros_time_override(Time(seconds=100.5))
    st = node.status()
    assert st['mode'] == 'normal' and st['param_age_s'] == pytest.approx(0.5)
    # 1.5 s of ROS time later (no wall time passes): stale
    clock.set_ros_time_override(Time(seconds=101.5))
    node.on_state(car_state_to_msg(_car_state(1.0), 0.0, True, 'ok'))
    st = node.status()
    assert (st['mode'], st['reason']) == ('failsafe', 'stale')
    clock.set_ros_time_override(Time(seconds=102.25))
    assert node.status()['failsafe_s'] == pytest.approx(0.75)    # 101.5 .. 102.25 in ROS time
