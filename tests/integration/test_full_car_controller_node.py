"""
The full-car controller node over ROS 2: one corner without a usable model, three controlling.

Real node processes (console scripts), test publishers of identified parameter sets (latched),
LOCALHOST discovery and the private domain of tests/conftest.py. Assertions are on the order of
events and on counters only; the waits are hang guards.

- the controller alone, the test as the plant: ``fl, fr, rl`` get a valid model, ``rr`` one
  flagged invalid. Sets of four corner states of a simulated ride are sent one set at a time;
  each set is answered by one command per corner, ``rr`` with the safe current, the other three
  with the same currents as the ROS-free core on the same floats (the law's, not the safe one);
- the controller driving ``full_car_node`` as the plant (``controller:=external``, lock-step,
  as fast as possible), ``rr``'s parameters withheld: every step waits for its four commands,
  ``rr`` stays in fail-safe in the controller and the other three control; every car step was
  answered (steps = sets answered), no lock-step timeout, no state dropped.
"""
import pytest

from integration.ros_helpers import Listener, NodeProcess
from kwok_messages import thesis_parameter_values

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0      # hang guard of every wait
SAFE_A = 0.5
CORNERS = ('fl', 'fr', 'rl', 'rr')
CTRL = {'safe_current_a': SAFE_A, 'param_timeout_s': 3600.0, 'diagnostics_period_s': 0.05}


def _publish_parameters(lis, ns, values_of):
    """Latched parameter publishers of the corners in ``values_of`` (corner -> values)."""
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.messages import kwok_parameters_msg
    from mr_damper_common.node_utils import LATCHED_QOS
    pubs = []
    for c, values in values_of.items():
        pub = lis.publisher(f'/{ns}/{c}/mr_damper/kwok_parameters', KwokParameters, LATCHED_QOS)
        pub.publish(kwok_parameters_msg(values))
        pubs.append(pub)
    return pubs


def _ride_states(n):
    """Full-car states of a passive ride (0.5 A) on the two-track road, from t = 0."""
    from mr_damper_model.models.plant import make_plant
    from quarter_car_sim.plant.two_track_road import make_two_track_road
    from semi_active_control.car.full_car import PASSENGER_CAR
    from quarter_car_sim.runtime.full_car import FullCarRuntime
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=2.0,
                               rng=4)
    rt = FullCarRuntime(PASSENGER_CAR, road, [make_plant('kwok-current') for _ in CORNERS],
                        'passive@0.5A', settle_s=0.0)
    return [rt.step(0.0)[2] for _ in range(n)]


def test_invalid_corner_gets_the_safe_current_the_others_the_law():
    from mr_damper_interfaces.msg import QuarterCarState
    from semi_active_control.car.full_car import PASSENGER_CAR
    from semi_active_control.runtime.full_car_controller_core import FullCarControllerCore
    from mr_damper_common.messages import corner_state_from_msg, corner_state_to_msg
    from mr_damper_common.node_utils import CONTROL_QOS
    from std_msgs.msg import Float64
    ns = 'fc_ctrl_alone'
    good, bad = thesis_parameter_values(), thesis_parameter_values(valid=0.0)
    ref = FullCarControllerCore(PASSENGER_CAR, 'modal-skyhook', timeout_s=3600.0,
                                safe_current_a=SAFE_A)
    for c in CORNERS:
        ref.offer_parameters(c, bad if c == 'rr' else good, 1.0)
    states = _ride_states(200)
    with Listener('full_car_controller_test') as lis:
        diag = lis.diagnostics()
        _publish_parameters(lis, ns, {c: bad if c == 'rr' else good for c in CORNERS})
        answers = {c: lis.subscribe(f'/{ns}/{c}/mr_damper/current_command', Float64,
                                    CONTROL_QOS) for c in CORNERS}
        pubs = {c: lis.publisher(f'/{ns}/{c}/quarter_car/car_state', QuarterCarState,
                                 CONTROL_QOS) for c in CORNERS}
        name = f'{ns}/full_car_controller'
        with NodeProcess('full_car_controller_node', params=CTRL, namespace=ns) as ctrl:
            def status():
                return diag.values(name)

            assert lis.wait_for(
                lambda: status().get('corners_normal') == 3
                and status()['corners']['rr']['params_rejected'].get('invalid_flag', 0) >= 1,
                GUARD_S, procs=[ctrl]), (status(), ctrl.output())
            subs = [x for x in lis.node.subscriptions if x.topic_name.endswith('current_command')]
            assert lis.wait_for(lambda: all(p.get_subscription_count() > 0 for p in pubs.values())
                                and all(s.get_publisher_count() > 0 for s in subs),
                                GUARD_S, procs=[ctrl]), ctrl.output()
            got, want = [], []
            for k, s in enumerate(states):
                msgs = [corner_state_to_msg(s.corner(i), 0.0, True, 'ok')
                        for i in range(4)]
                for c, msg in zip(CORNERS, msgs):
                    pubs[c].publish(msg)
                assert lis.wait_for(lambda: all(len(answers[c]) > k for c in CORNERS),
                                    GUARD_S, poll=0.001, procs=[ctrl]), ctrl.output()
                assert [len(answers[c]) for c in CORNERS] == [k + 1] * 4   # one per corner
                got.append([answers[c][k][1].data for c in CORNERS])
                want.append([ref.offer_state(i, corner_state_from_msg(msg), 1.0)
                             for i, msg in enumerate(msgs)][-1])
            n = len(states)
            assert got == want
            assert all(g[3] == SAFE_A for g in got)
            for i in range(3):                          # the law moves each current
                assert len({round(g[i], 6) for g in got}) > 20
            assert lis.wait_for(lambda: status().get('sets') == n, GUARD_S, procs=[ctrl])
            st = status()
            assert [st['corners'][c]['normal_commands'] for c in CORNERS] == [n, n, n, 0]
            assert [st['corners'][c]['states'] for c in CORNERS] == [n] * 4
            assert st['dropped_states'] == {'replaced': 0, 'incomplete': 0}
            assert st['corners']['rr']['mode'] == 'failsafe'
            assert ctrl.stop() == 0, ctrl.output()
        assert 'parameters refused (invalid_flag' in ctrl.output()


def test_controller_drives_the_full_car_in_lock_step_with_rr_withheld():
    ns = 'fc_ctrl_car'
    car = {'controller': 'external', 'lockstep': True, 'lockstep_timeout_s': GUARD_S,
           'command_timeout_s': 3600.0, 'real_time_factor': 0.0, 'plant': 'kwok-current',
           'safe_current_a': SAFE_A, 'road_duration_s': 5.0, 'settle_s': 0.1,
           'diagnostics_period_s': 0.05, 'log_max_s': 5.0}
    with Listener('full_car_lockstep_test') as lis:
        diag = lis.diagnostics()
        good = thesis_parameter_values()
        _publish_parameters(lis, ns, {c: good for c in CORNERS[:3]})        # rr withheld
        ctrl_name, car_name = f'{ns}/full_car_controller', f'{ns}/full_car_node'
        with NodeProcess('full_car_controller_node', params=CTRL, namespace=ns) as ctrl:
            assert lis.wait_for(lambda: diag.values(ctrl_name).get('corners_normal') == 3,
                                GUARD_S, procs=[ctrl]), ctrl.output()
            with NodeProcess('full_car_node', params=car, namespace=ns) as plant:
                assert lis.wait_for(lambda: (diag.values(car_name).get('t_sim') or -1) >= 0.2,
                                    GUARD_S, procs=[ctrl, plant]), plant.output()
                assert plant.stop() == 0, plant.output()
            st_car = diag.values(car_name)           # the newest status (steps so far)
            steps = st_car['steps']

            def all_answered():
                st = diag.values(ctrl_name)
                return (st.get('sets', 0) >= steps and [
                    st['corners'][c]['states'] for c in CORNERS] == [st['sets']] * 4)

            assert lis.wait_for(all_answered, GUARD_S, procs=[ctrl]), diag.values(ctrl_name)
            st = diag.values(ctrl_name)
            assert ctrl.stop() == 0, ctrl.output()
    assert st_car['controller'] == 'external' and st_car['lockstep'] in (True, 'True')
    assert st_car['lockstep_timeouts'] == 0 and steps > 250
    assert st['sets'] >= steps                  # every step was answered before the next
    assert [st['corners'][c]['states'] for c in CORNERS] == [st['sets']] * 4
    assert st['dropped_states'] == {'replaced': 0, 'incomplete': 0}
    normal = [st['corners'][c]['normal_commands'] for c in CORNERS]
    assert normal[3] == 0 and min(normal[:3]) == st['sets']
    assert st['corners']['rr']['mode'] == 'failsafe' and st['corners']['rr']['current_a'] == SAFE_A
    for c in CORNERS:                           # the car took every corner's commands
        assert st_car['corners'][c]['commands_received'] >= steps
        assert st_car['corners'][c]['command_timeouts'] == 0


def test_lock_step_wait_is_bounded_and_counted_without_answers():
    """The car in lock-step whose controller never answers: each step waits at most the bound."""
    from mr_damper_interfaces.msg import QuarterCarState
    from mr_damper_common.node_utils import CONTROL_QOS
    from std_msgs.msg import Float64
    ns = 'fc_lockstep_silent'
    car = {'controller': 'external', 'lockstep': True, 'lockstep_timeout_s': 0.02,
           'command_timeout_s': 3600.0, 'real_time_factor': 0.0, 'plant': 'kwok-current',
           'safe_current_a': SAFE_A, 'road_duration_s': 5.0, 'settle_s': 0.1,
           'diagnostics_period_s': 0.05, 'log_max_s': 5.0}
    with Listener('full_car_lockstep_silent') as lis:
        diag = lis.diagnostics()
        # a silent controller: the topics matched both ways, no command ever
        states = {c: lis.subscribe(f'/{ns}/{c}/quarter_car/car_state', QuarterCarState,
                                   CONTROL_QOS) for c in CORNERS}
        cmd_pubs = [lis.publisher(f'/{ns}/{c}/mr_damper/current_command', Float64, CONTROL_QOS)
                    for c in CORNERS]
        name = f'{ns}/full_car_node'
        with NodeProcess('full_car_node', params=car, namespace=ns) as plant:
            assert lis.wait_for(lambda: diag.values(name).get('lockstep_timeouts', 0) >= 5,
                                GUARD_S, procs=[plant]), plant.output()
            st = diag.values(name)
            # one timeout per step without an answer: the car goes on, on the safe current
            assert st['steps'] <= st['lockstep_timeouts'] + 1
            for c in CORNERS:
                d = st['corners'][c]
                assert (d['mode'], d['reason'], d['current_a']) == (
                    'failsafe', 'no_command_yet', SAFE_A), (c, d)
            # answers come: every corner leaves fail-safe on its command
            n = min(len(states[c]) for c in CORNERS)
            for pub in cmd_pubs:
                pub.publish(Float64(data=1.25))
            assert lis.wait_for(lambda: diag.values(name).get('corners_normal') == 4
                                and all(diag.values(name)['corners'][c]['current_a'] == 1.25
                                        for c in CORNERS), GUARD_S, procs=[plant])
            assert min(len(states[c]) for c in CORNERS) > n      # the car kept stepping
            assert plant.stop() == 0, plant.output()
        assert 'no four commands within 0.02 s' in plant.output()
