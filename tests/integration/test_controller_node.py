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
  ``ClosedLoop``'s (in fact equal: the same floats go through the same core).
"""
import os
import signal

import numpy as np
import pytest

from integration.ros_helpers import (latest_status as _latest, Listener, NodeProcess,
                                     status_qos as _qos)
from integration.test_suite import _good_params   # the valid thesis parameter set

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0      # hang guard of every wait
SAFE_A = 0.5
PREFIX = '/ctrl_node_test'
TOPICS = {'params_topic': f'{PREFIX}/params', 'car_state_topic': f'{PREFIX}/car_state',
          'command_topic': f'{PREFIX}/current_command'}
CAR_TOPICS = dict(TOPICS, state_topic=f'{PREFIX}/state', status_topic=f'{PREFIX}/car_status',
                  metrics_topic=f'{PREFIX}/metrics')
CTRL_TOPICS = dict(TOPICS, status_topic=f'{PREFIX}/ctrl_status')


@pytest.fixture(scope='module')
def listener():
    from std_msgs.msg import Float64MultiArray
    from mr_damper_model.messages import dict_to_array_msg, KWOK_PARAMETER_LABELS
    from mr_damper_model.node_utils import LATCHED_QOS
    lis = Listener('controller_node_test')
    pub = lis.publisher(TOPICS['params_topic'], Float64MultiArray, LATCHED_QOS)
    pub.publish(dict_to_array_msg(_good_params(), KWOK_PARAMETER_LABELS))   # latched
    lis.params_pub = pub
    yield lis
    lis.close()


CAR = {'plant': 'kwok-current', 'controller': 'external', 'safe_current_a': SAFE_A,
       'road_duration_s': 30.0, 'road_seed': 3, 'status_rate_hz': 20.0, **CAR_TOPICS}
CTRL = {'safe_current_a': SAFE_A, 'param_timeout_s': 3600.0, 'status_rate_hz': 20.0,
        **CTRL_TOPICS}


def test_commands_arrive_then_controller_killed_car_goes_safe(listener):
    from std_msgs.msg import String
    car_st = listener.subscribe(CAR_TOPICS['status_topic'], String, _qos())
    ctrl_st = listener.subscribe(CTRL_TOPICS['status_topic'], String, _qos())
    wait = listener.wait_for
    car_params = dict(CAR, real_time_factor=1.0, command_timeout_s=0.05)
    with NodeProcess('quarter_car_node', params=car_params) as car:
        assert wait(lambda: len(car_st) > 2, GUARD_S, procs=[car]), car.output()
        st = _latest(car_st)
        assert (st['mode'], st['reason']) == ('failsafe', 'no_command_yet')
        assert st['commands_received'] == 0 and st['current_a'] == SAFE_A
        steps_alone = st['steps']
        assert steps_alone > 0                          # the plant runs without a controller
        ctrl = NodeProcess('semi_active_controller_node', params=CTRL)
        try:
            # order: the controller takes the model, its commands reach the car, the car is
            # normal
            assert wait(lambda: _latest(ctrl_st).get('mode') == 'normal', GUARD_S,
                        procs=[car, ctrl]), ctrl.output()
            assert wait(lambda: _latest(car_st).get('mode') == 'normal', GUARD_S,
                        procs=[car, ctrl]), (_latest(car_st), ctrl.output())
            assert wait(lambda: _latest(car_st)['commands_received'] > 500, GUARD_S,
                        procs=[car, ctrl])
            cst = _latest(ctrl_st)
            assert cst['params_accepted'] == 1 and cst['commands_normal'] > 0
            assert cst['state_rejected'] == {'non_finite': 0, 'out_of_order': 0}
            st = _latest(car_st)
            assert st['command_timeouts'] == 0 and st['reason'] == 'ok'
            assert st['commands']['refused_non_finite'] == 0
            assert 0.0 <= st['current_a'] <= 2.0
        finally:
            os.kill(ctrl.proc.pid, signal.SIGKILL)
            ctrl.proc.wait(GUARD_S)
        # the controller is gone: the car falls back to the safe current and keeps stepping
        assert wait(lambda: _latest(car_st).get('reason') == 'command_timeout', GUARD_S,
                    procs=[car]), _latest(car_st)
        st = _latest(car_st)
        assert st['mode'] == 'failsafe' and st['command_timeouts'] == 1
        steps, received = st['steps'], st['commands_received']
        assert wait(lambda: _latest(car_st)['steps'] > steps + 200, GUARD_S, procs=[car])
        st = _latest(car_st)
        assert st['current_a'] == SAFE_A and st['commands_received'] == received
        assert st['mode'] == 'failsafe' and st['command_timeouts'] == 1
        code = car.stop()
    assert code == 0, car.output()


RIDE_COLUMNS = ('t', 'a_s', 'travel', 'tyre_force', 'damper_force')


def _reference_ride(n_steps):
    """Run the built-in loop on the same car, road, seed and model; return per-step arrays."""
    from mr_damper_model.plant import make_plant
    from quarter_car_sim import live_loop
    from quarter_car_sim.controllers import make_controller
    from quarter_car_sim.dynamics import QuarterCar
    from quarter_car_sim.failsafe import ModelSupervisor
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.road import make_road
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=CAR['road_seed'],
                     duration_s=CAR['road_duration_s'], dt=1e-3)
    car = QuarterCar(params, make_plant('kwok-current'), road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=3600.0, safe_current_a=SAFE_A)
    law = make_controller('skyhook', params=params, damper_only=True)
    loop = live_loop.ClosedLoop(car, law, sup, 1e-3)
    sup.offer(_good_params(), 0.0)
    states = [loop.step(0.0) for _ in range(n_steps)]
    return {c: np.array([getattr(s, c) for s in states]) for c in RIDE_COLUMNS}


def _ride_figures(columns):
    """Wk RMS body acceleration and RMS dynamic tyre load ratio on the road (t >= 0)."""
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.ride_metrics import ride_metrics
    keep = columns['t'] >= 0.0
    m = ride_metrics({c: columns[c][keep] for c in RIDE_COLUMNS},
                     static_load=QuarterCarParams().static_tyre_load)
    return {k: m[k] for k in ('rms_body_accel_wk', 'rms_tyre_load_ratio')}


def test_lockstep_ride_equals_the_built_in_controller(listener, tmp_path):
    from std_msgs.msg import String
    from mr_damper_model.columnlog import ColumnReader
    car_st = listener.subscribe(CAR_TOPICS['status_topic'], String, _qos())
    ctrl_st = listener.subscribe(CTRL_TOPICS['status_topic'], String, _qos())
    wait = listener.wait_for
    log = tmp_path / 'car_log'
    with NodeProcess('semi_active_controller_node', params=CTRL) as ctrl:
        # the controller has the model before the car's first state: every step is normal
        assert wait(lambda: _latest(ctrl_st).get('mode') == 'normal', GUARD_S,
                    procs=[ctrl]), ctrl.output()
        car_params = dict(CAR, real_time_factor=0.0, lockstep=True, lockstep_timeout_s=GUARD_S,
                          command_timeout_s=GUARD_S, log_file=str(log))
        with NodeProcess('quarter_car_node', params=car_params) as car:
            assert wait(lambda: _latest(car_st).get('t_sim', -1.0) >= 3.0, GUARD_S * 3,
                        procs=[car, ctrl]), (_latest(car_st), car.output(), ctrl.output())
            code = car.stop()
        assert code == 0, car.output()
        z = ColumnReader(log).read()
        n = int(z['t'].size)
        # the controller answered every state of the logged steps, each with the model
        assert wait(lambda: _latest(ctrl_st)['commands'] >= n, GUARD_S, procs=[ctrl])
        st = _latest(ctrl_st)
        assert st['commands_normal'] == st['commands'] and st['params_accepted'] == 1
    car_final = ColumnReader(log).meta['status']
    assert car_final['lockstep_timeouts'] == 0 and car_final['command_timeouts'] == 0
    assert n > 3500 and np.all(z['mode'] == 1.0)
    ext = _ride_figures(z)
    built_in = _ride_figures(_reference_ride(n))
    for key in ext:
        assert ext[key] == pytest.approx(built_in[key], rel=0.02), (key, ext, built_in)
