"""
The stand-alone controller node driving the quarter car (``controller:=external``) over ROS 2.

Real node processes (console scripts), a test publisher of a valid identified parameter set,
LOCALHOST discovery and the private domain of tests/conftest.py. Assertions are on the order of
events and on counters only; the waits are hang guards.

- asynchronous (real time): the car starts alone (fail-safe, ``no_command_yet``), the controller
  comes up: commands arrive, the controller uses the model, the car leaves fail-safe; the
  controller killed (SIGKILL): the car goes to the safe current after ``command_timeout_s``
  (``command_timeout``), counted once, and keeps stepping;
- lock-step, as fast as possible: the car waits for the command answering each state, so the
  external loop is step for step the built-in one; its ride figures (Wk RMS body acceleration,
  RMS dynamic tyre load) on the same road and seed are within 2 % of the built-in
  ``ClosedLoop``'s (in fact equal: the same floats go through the same core);
- one state stamped +1e6 s (issue 21): answered with the safe current once, the valid states
  before and after it with the law's commands (state by state, lock-step from the test).
"""
import os
import signal

import numpy as np
import pytest

from integration.ros_helpers import NodeProcess
from kwok_messages import thesis_parameter_values

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0      # hang guard of every wait
SAFE_A = 0.5
NS = 'ctrl_node_test'           # car and controller in one namespace: their topics meet there
CAR_NAME, CTRL_NAME = f'{NS}/quarter_car_node', f'{NS}/semi_active_controller'


@pytest.fixture(scope='module')
def listener(listener):
    """Return the module's listening node (conftest.py), thesis parameters latched on NS."""
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.messages import kwok_parameters_msg
    from mr_damper_common.node_utils import LATCHED_QOS
    pub = listener.publisher(f'/{NS}/mr_damper/kwok_parameters', KwokParameters, LATCHED_QOS)
    pub.publish(kwok_parameters_msg(thesis_parameter_values()))   # latched
    listener.params_pub = pub
    return listener


CAR = {'plant': 'kwok-current', 'controller': 'external', 'safe_current_a': SAFE_A,
       'road_duration_s': 30.0, 'road_seed': 3, 'diagnostics_period_s': 0.05}
CTRL = {'safe_current_a': SAFE_A, 'param_timeout_s': 3600.0, 'diagnostics_period_s': 0.05}


def car_status(listener):
    """Newest diagnostics values of the car ({} before the first)."""
    return listener.diag.values(CAR_NAME)


def ctrl_status(listener):
    """Newest diagnostics values of the controller node ({} before the first)."""
    return listener.diag.values(CTRL_NAME)


def test_commands_arrive_then_controller_killed_car_goes_safe(listener):
    listener.diag = listener.diagnostics()       # this test's statuses only
    wait = listener.wait_for
    car_params = dict(CAR, real_time_factor=1.0, command_timeout_s=0.2)
    n0 = listener.diag.count(CAR_NAME)
    with NodeProcess('quarter_car_node', params=car_params, namespace=NS) as car:
        assert wait(lambda: listener.diag.count(CAR_NAME) > n0 + 2, GUARD_S,
                    procs=[car]), car.output()
        st = car_status(listener)
        assert (st['mode'], st['reason']) == ('failsafe', 'no_command_yet')
        assert st['commands_received'] == 0 and st['current_a'] == SAFE_A
        steps_alone = st['steps']
        assert steps_alone > 0                          # the plant runs without a controller
        ctrl = NodeProcess('semi_active_controller_node', params=CTRL, namespace=NS)
        try:
            # order: the controller takes the model, its commands reach the car, the car is
            # normal
            assert wait(lambda: ctrl_status(listener).get('mode') == 'normal', GUARD_S,
                        procs=[car, ctrl]), ctrl.output()
            assert wait(lambda: car_status(listener).get('mode') == 'normal', GUARD_S,
                        procs=[car, ctrl]), (car_status(listener), ctrl.output())
            assert wait(lambda: car_status(listener)['commands_received'] > 500, GUARD_S,
                        procs=[car, ctrl])
            cst = ctrl_status(listener)
            assert cst['params_accepted'] == 1 and cst['commands_normal'] > 0
            assert cst['state_rejected'] == {'non_finite': 0, 'future_stamp': 0,
                                             'out_of_order': 0}
            # a loaded machine may delay a command past the timeout now and then: the car
            # then goes safe and comes back with the next command (not counted as a failure)
            assert wait(lambda: car_status(listener).get('reason') == 'ok', GUARD_S,
                        procs=[car, ctrl]), car_status(listener)
            st = car_status(listener)
            assert st['commands']['refused_non_finite'] == 0
            assert 0.0 <= st['current_a'] <= 2.0
            timeouts_alive = st['command_timeouts']
        finally:
            os.kill(ctrl.proc.pid, signal.SIGKILL)
            ctrl.proc.wait(GUARD_S)
        # the controller is gone: the car falls back to the safe current and keeps stepping
        assert wait(lambda: car_status(listener).get('reason') == 'command_timeout', GUARD_S,
                    procs=[car]), car_status(listener)
        st = car_status(listener)
        assert st['mode'] == 'failsafe' and st['command_timeouts'] >= timeouts_alive + 1
        steps, received, timeouts = st['steps'], st['commands_received'], st['command_timeouts']
        assert wait(lambda: car_status(listener)['steps'] > steps + 200, GUARD_S, procs=[car])
        st = car_status(listener)
        assert st['current_a'] == SAFE_A and st['commands_received'] == received
        # counted once: the silence goes on, the count does not
        assert st['mode'] == 'failsafe' and st['command_timeouts'] == timeouts
        code = car.stop()
    assert code == 0, car.output()


RIDE_COLUMNS = ('t', 'a_s', 'travel', 'tyre_force', 'damper_force')


def _reference_ride(n_steps):
    """Run the built-in loop on the same car, road, seed and model; return per-step arrays."""
    from mr_damper_model.models.plant import make_plant
    from quarter_car_sim.simulate import live_loop
    from semi_active_control.laws import make_controller
    from quarter_car_sim.plant.quarter_car import QuarterCar
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.plant.road import make_road
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=CAR['road_seed'],
                     duration_s=CAR['road_duration_s'], dt=1e-3)
    car = QuarterCar(params, make_plant('kwok-current'), road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=3600.0, safe_current_a=SAFE_A)
    law = make_controller('skyhook', params=params, damper_only=True)
    loop = live_loop.ClosedLoop(car, law, sup, 1e-3)
    sup.offer(thesis_parameter_values(), 0.0)
    states = [loop.step(0.0) for _ in range(n_steps)]
    return {c: np.array([getattr(s, c) for s in states]) for c in RIDE_COLUMNS}


def _ride_figures(columns):
    """Wk RMS body acceleration and RMS dynamic tyre load ratio on the road (t >= 0)."""
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.metrics.quarter_car import ride_metrics
    keep = columns['t'] >= 0.0
    m = ride_metrics({c: columns[c][keep] for c in RIDE_COLUMNS},
                     static_load=QuarterCarParams().static_tyre_load)
    return {k: m[k] for k in ('rms_body_accel_wk', 'rms_tyre_load_ratio')}


def test_lockstep_ride_equals_the_built_in_controller(listener, tmp_path):
    from mr_damper_common.recording.columnlog import ColumnReader
    listener.diag = listener.diagnostics()       # this test's statuses only
    wait = listener.wait_for
    log = tmp_path / 'car_log'
    with NodeProcess('semi_active_controller_node', params=CTRL, namespace=NS) as ctrl:
        # the controller has the model before the car's first state: every step is normal
        assert wait(lambda: ctrl_status(listener).get('mode') == 'normal', GUARD_S,
                    procs=[ctrl]), ctrl.output()
        car_params = dict(CAR, real_time_factor=0.0, lockstep=True, lockstep_timeout_s=GUARD_S,
                          command_timeout_s=GUARD_S, log_file=str(log))
        with NodeProcess('quarter_car_node', params=car_params, namespace=NS) as car:
            assert wait(lambda: car_status(listener).get('t_sim', -1.0) >= 3.0, GUARD_S * 3,
                        procs=[car, ctrl]), (car_status(listener), car.output(), ctrl.output())
            code = car.stop()
        assert code == 0, car.output()
        z = ColumnReader(log).read()
        n = int(z['t'].size)
        # the controller answered every state of the logged steps, each with the model
        assert wait(lambda: ctrl_status(listener)['commands'] >= n, GUARD_S, procs=[ctrl])
        st = ctrl_status(listener)
        assert st['commands_normal'] == st['commands'] and st['params_accepted'] == 1
    car_final = ColumnReader(log).meta['status']
    assert car_final['lockstep_timeouts'] == 0 and car_final['command_timeouts'] == 0
    assert n > 3500 and np.all(z['mode'] == 1.0)
    ext = _ride_figures(z)
    built_in = _ride_figures(_reference_ride(n))
    for key in ext:
        assert ext[key] == pytest.approx(built_in[key], rel=0.02), (key, ext, built_in)


def _car_states(n):
    """States of a passive ride (the law's inputs), stamped 1 ms apart from 1 s (car time)."""
    from mr_damper_model.models.plant import make_plant
    from quarter_car_sim.plant.quarter_car import QuarterCar
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.plant.road import make_road
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=5, duration_s=n * 1e-3 + 2)
    car = QuarterCar(QuarterCarParams(), make_plant('kwok-current'), road, t0=1.0)
    return [car.step(1e-3, 0.7) for _ in range(n)]


def test_one_future_stamped_state_costs_one_safe_answer(listener):
    from mr_damper_interfaces.msg import QuarterCarState
    from semi_active_control.runtime.controller_core import ControllerCore, make_node_law
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from mr_damper_common.messages import corner_state_from_msg, corner_state_to_msg
    from mr_damper_common.node_utils import CONTROL_QOS
    from std_msgs.msg import Float64
    listener.diag = listener.diagnostics()       # this test's statuses only
    wait = listener.wait_for
    answers = listener.subscribe(f'/{NS}/mr_damper/current_command', Float64, CONTROL_QOS)
    pub = listener.publisher(f'/{NS}/quarter_car/car_state', QuarterCarState, CONTROL_QOS)
    # the reference: the same core on the same floats (stamps of the vehicle, in order)
    ref = ControllerCore(make_node_law('skyhook', QuarterCarParams(), 1000.0, {}),
                         ModelSupervisor(timeout_s=3600.0, safe_current_a=SAFE_A))
    ref.offer_parameters(thesis_parameter_values(), 1.0)
    states = _car_states(400)
    with NodeProcess('semi_active_controller_node', params=CTRL, namespace=NS) as ctrl:
        assert wait(lambda: ctrl_status(listener).get('mode') == 'normal', GUARD_S,
                    procs=[ctrl]), ctrl.output()
        # both topics matched both ways before the first state (reliable: nothing is lost)
        sub = next(x for x in listener.node.subscriptions
                   if x.topic_name == f'/{NS}/mr_damper/current_command')
        assert wait(lambda: pub.get_subscription_count() > 0 and sub.get_publisher_count() > 0,
                    GUARD_S, procs=[ctrl]), ctrl.output()

        def send(state, stamp_shift=0.0):
            """Publish one state and wait for its answer (lock-step); return it."""
            n = len(answers)
            msg = corner_state_to_msg(state, 0.0, True, 'ok')
            msg.header.stamp.sec += int(stamp_shift)
            pub.publish(msg)
            assert wait(lambda: len(answers) > n, GUARD_S, poll=0.001, procs=[ctrl]), (
                ctrl.output())
            assert len(answers) == n + 1
            return answers[n][1].data

        ref.command(corner_state_from_msg(corner_state_to_msg(states[0], 0.0, True, 'ok')), 1.0)
        send(states[0])
        got, want = [], []
        for j, s in enumerate(states[1:301]):
            future = j == 150
            got.append(send(s, 1e6 if future else 0.0))
            vs = corner_state_from_msg(corner_state_to_msg(s, 0.0, True, 'ok'))
            want.append(SAFE_A if future else ref.command(vs, 1.0))
        n_sent = 1 + 300
        assert got == pytest.approx(want, abs=1e-12)
        assert len({round(c, 6) for c in want}) > 20          # the law, not the safe current
        assert wait(lambda: ctrl_status(listener).get('commands') == n_sent, GUARD_S,
                    procs=[ctrl]), ctrl_status(listener)
        st = ctrl_status(listener)
        assert st['state_rejected'] == {'non_finite': 0, 'future_stamp': 1, 'out_of_order': 0}
        assert st['commands_normal'] == n_sent - 1 and st['stamp_rebases'] == 0
        assert (st['mode'], st['reason']) == ('normal', 'ok')
        assert len(answers) == n_sent
        assert ctrl.stop() == 0, ctrl.output()
    assert 'state refused (future_stamp' in ctrl.output()
