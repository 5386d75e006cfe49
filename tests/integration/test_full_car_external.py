"""
The simulated full car as the plant of the vehicle controller over ROS 2 (controller:=external).

Real node processes (console scripts), test publishers of identified parameter sets (latched),
LOCALHOST discovery and the private domain of tests/conftest.py. Assertions are on the order of
events and on counters only; the waits are hang guards.

- ``vehicle_controller_node`` (autostart, every corner's model live) drives ``full_car_node``
  in lock-step as fast as possible, ``rr``'s parameters withheld: one ``vehicle/state`` per
  cycle, each answered by one ``vehicle/command`` before the car goes on; ``rr`` stays on the
  safe current with the controller's reason, the other three control every step; no state
  lost, no lock-step timeout;
- a lock-step car whose controller never answers waits at most ``lockstep_timeout_s`` per
  cycle, counts each expiry and drives on the safe current (``no_command_yet``) until a command
  comes, then applies it.
"""
import pytest

from integration.ros_helpers import Listener, NodeProcess
from kwok_messages import thesis_parameter_values

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0      # hang guard of every wait
SAFE_A = 0.5
CORNERS = ('fl', 'fr', 'rl', 'rr')
CAR = {'controller': 'external', 'lockstep': True, 'command_timeout_s': 3600.0,
       'real_time_factor': 0.0, 'plant': 'kwok-current', 'safe_current_a': SAFE_A,
       'road_duration_s': 5.0, 'settle_s': 0.1, 'diagnostics_period_s': 0.05,
       'log_max_s': 5.0, 'cycle_s': 0.002}


def test_vehicle_controller_drives_the_full_car_in_lock_step_with_rr_withheld():
    from mr_damper_common.messages import kwok_parameters_msg
    from mr_damper_common.node_utils import LATCHED_QOS
    from mr_damper_interfaces.msg import KwokParameters
    ns = 'fc_vehicle_ctrl'
    # lock-step as fast as possible: no wall-clock deadline, no sensor timeout between cycles
    ctrl = {'autostart': True, 'safe_current_a': SAFE_A,      # (every model live: the default)
            'param_timeout_s': 3600.0, 'deadline_s': 10.0, 'sensor_timeout_s': 60.0,
            'diagnostics_period_s': 0.05}
    car = dict(CAR, lockstep_timeout_s=GUARD_S)
    with Listener('full_car_external_test') as lis:
        diag = lis.diagnostics()
        pubs = []
        for c in CORNERS[:3]:                                   # rr withheld
            pub = lis.publisher(f'/{ns}/{c}/mr_damper/kwok_parameters', KwokParameters,
                                LATCHED_QOS)
            pub.publish(kwok_parameters_msg(thesis_parameter_values()))
            pubs.append(pub)
        ctrl_name, car_name = f'{ns}/vehicle_controller', f'{ns}/full_car_node'
        with NodeProcess('vehicle_controller_node', params=ctrl, namespace=ns) as ctl:
            def models_taken():
                st = diag.values(ctrl_name)
                return st.get('active') in (True, 'True') and all(
                    (st['corners'][c].get('params_accepted') or 0) >= 1 for c in CORNERS[:3])

            assert lis.wait_for(models_taken, GUARD_S, procs=[ctl]), ctl.output()
            with NodeProcess('full_car_node', params=car, namespace=ns) as plant:
                assert lis.wait_for(lambda: (diag.values(car_name).get('t_sim') or -1) >= 0.2,
                                    GUARD_S, procs=[ctl, plant]), plant.output()
                assert plant.stop() == 0, plant.output()
            st_car = diag.values(car_name)                      # the final status
            states = st_car['vehicle_states']
            assert lis.wait_for(lambda: diag.values(ctrl_name).get('states_answered', 0)
                                >= states, GUARD_S, procs=[ctl]), diag.values(ctrl_name)
            st = diag.values(ctrl_name)
            assert ctl.stop() == 0, ctl.output()
    assert st_car['controller'] == 'external' and st_car['lockstep'] in (True, 'True')
    assert st_car['lockstep_timeouts'] == 0 and states > 100
    # every state was answered before the car went on, and the car took every answer
    assert st_car['answered_sequence'] == states == st_car['commands']
    assert st['states_answered'] == states and st['states']['lost'] == 0
    assert 2 * states - 1 <= st_car['steps'] <= 2 * states       # two 1 ms steps per cycle
    normal = [st_car['corners'][c]['normal_steps'] for c in CORNERS]
    assert normal[:3] == [st_car['steps']] * 3 and normal[3] == 0, st_car['corners']
    rr = st_car['corners']['rr']
    assert rr['mode'] == 'failsafe' and rr['current_a'] == SAFE_A
    assert rr['reason'] == st['corners']['rr']['reason'] != 'ok'   # the controller's reason
    for c in CORNERS:
        assert st_car['corners'][c]['command_timeouts'] == 0
    assert [st['corners'][c]['normal_commands'] for c in CORNERS] == [states] * 3 + [0]


def test_lock_step_wait_is_bounded_and_counted_without_answers():
    """The car in lock-step whose controller never answers: each cycle waits at most the bound."""
    from mr_damper_common.node_utils import VEHICLE_QOS
    from mr_damper_interfaces.msg import FullCarCommand, FullCarState
    ns = 'fc_lockstep_silent'
    car = dict(CAR, lockstep_timeout_s=0.02)
    with Listener('full_car_lockstep_silent') as lis:
        diag = lis.diagnostics()
        # a silent controller: the topics matched both ways, no command yet
        states = lis.subscribe(f'/{ns}/vehicle/state', FullCarState, VEHICLE_QOS)
        cmd_pub = lis.publisher(f'/{ns}/vehicle/command', FullCarCommand, VEHICLE_QOS)
        name = f'{ns}/full_car_node'
        with NodeProcess('full_car_node', params=car, namespace=ns) as plant:
            assert lis.wait_for(lambda: diag.values(name).get('lockstep_timeouts', 0) >= 5,
                                GUARD_S, procs=[plant]), plant.output()
            st = diag.values(name)
            # one timeout per cycle without an answer: the car goes on, on the safe current
            assert st['vehicle_states'] <= st['lockstep_timeouts'] + 1
            for c in CORNERS:
                d = st['corners'][c]
                assert (d['mode'], d['reason'], d['current_a']) == (
                    'failsafe', 'no_command_yet', SAFE_A), (c, d)
            # an answer comes: every corner leaves fail-safe on its command
            n = len(states)
            newest = max((m.sequence for _, m in states), default=1)
            cmd = FullCarCommand(sequence=1, state_sequence=newest, current_a=[1.25] * 4,
                                 mode=[FullCarCommand.MODE_NORMAL] * 4, reason=['ok'] * 4)
            cmd_pub.publish(cmd)
            assert lis.wait_for(lambda: diag.values(name).get('corners_normal') == 4
                                and all(diag.values(name)['corners'][c]['current_a'] == 1.25
                                        for c in CORNERS), GUARD_S, procs=[plant])
            assert len(states) > n                              # the car kept cycling
            assert plant.stop() == 0, plant.output()
        assert 'no command within 0.02 s' in plant.output()
