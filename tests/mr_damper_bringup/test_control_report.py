"""Tests of mr_damper_bringup.report.control: when a run reached control, from its statuses."""
import numpy as np
import pytest

from mr_damper_bringup.report.control import (control_summary, ControlWatch, format_control,
                                              quarter_car_log_figures)
from mr_damper_common.recording.columnlog import ArrayLog

NAN = float('nan')


def _car(t_sim, first_normal=NAN, controller='skyhook', failsafe_s=0.0):
    return {'t_sim': t_sim, 'first_normal_t_sim': first_normal, 'controller': controller,
            'failsafe_s': failsafe_s}


def test_built_in_quarter_car_from_its_statuses_and_log():
    w = ControlWatch()
    start = 1000.0
    # one status a second; the identifier's first valid window at 3 s, the car normal at 5 s
    for k in range(11):
        t = start + k
        statuses = {'identifier': {'windows_valid': int(k >= 3)},
                    'quarter_car': _car(k - 1.0, first_normal=2.5 if k >= 5 else NAN)}
        w.update(statuses, t)
    # the car's log: 1 kHz, normal from 2.5 s of car time, fail-safe again 6.0-6.5 s
    t = np.arange(-500, 9001) * 1e-3
    mode = ((t >= 2.5) & ~((t >= 6.0) & (t < 6.5))).astype(float)
    log = ArrayLog({'t': t, 'mode': mode})
    first, fraction = quarter_car_log_figures(log)
    assert first == pytest.approx(2.5)
    assert fraction == pytest.approx(500 / 6501, rel=1e-9)
    summary = {'messages_lost': 0, 'ride': {
        'skyhook': {'rms_body_accel_wk': 0.9}, 'passive': {'rms_body_accel_wk': 1.1},
        'passive_0a': {'rms_body_accel_wk': 1.0}, 'passive_current_a': 0.5,
        'window_s': [2.5, 9.0]}}
    c = control_summary(w, start, summary, logs={'': log})
    # the log's first normal step (car time 2.5 s) on the car's clock (car time k - 1 at
    # 1000 + k s): 3.5 s, between the statuses
    assert c['first_valid_set_s'] == 3.0 and c['first_normal_s'] == pytest.approx(3.5)
    assert c['first_normal_t_sim'] == pytest.approx(2.5)
    assert c['failsafe_fraction'] == pytest.approx(500 / 6501, rel=1e-9)
    # car time 0..9 s over wall 1001..1010 s
    assert c['real_time_factor'] == pytest.approx(1.0)
    assert c['samples_lost'] == 0
    assert c['ride'] == {'metric': 'wk', 'live': 0.9, 'passive': 1.1, 'passive_0a': 1.0,
                         'window_s': [2.5, 9.0], 'passive_current_a': 0.5}
    assert 'first normal step 3.5 s' in format_control(c)
    # a recorder that fell behind lost the car's statuses after 5 s of car time, the one
    # saying it was normal among them: its log's first normal step (6.0 s of car time) is
    # placed past the last status at the real-time factor (1)
    w2 = ControlWatch()
    for k in range(7):
        w2.update({'identifier': {'windows_valid': 1}, 'quarter_car': _car(k - 1.0)}, start + k)
    late = ArrayLog({'t': t, 'mode': (t >= 6.0).astype(float)})
    c2 = control_summary(w2, start, summary, logs={'': late})
    assert c2['first_normal_s'] == pytest.approx(7.0) and c2['first_normal_t_sim'] == 6.0


def test_external_controller_counts_its_commands_and_the_car_timeouts():
    w = ControlWatch()
    # the controller's normal commands from its second status; the car drove 0.5 s of the
    # 4 s after that on the safe current (command timeouts)
    rows = [(0, 0, 0.0), (1000, 0, 0.0), (2000, 900, 0.0), (6000, 4500, 0.5)]
    for k, (commands, normal, timeout_s) in enumerate(rows):
        w.update({'controller': {'commands': commands, 'commands_normal': normal},
                  'quarter_car': _car(1.0 + k, controller='external', failsafe_s=timeout_s)},
                 10.0 + k)
    c = control_summary(w, 10.0, {'messages_lost': 3, 'ride': {}})
    # the controller reports no car time: the car's at the controller's first normal status
    assert c['first_normal_s'] == 2.0 and c['first_normal_t_sim'] == 3.0
    # commands after the first normal status: 3600 of 4000 normal; the car's statuses from
    # the one before it (t_sim 2 s) to the last (4 s): 0.5 s of 2 s on the safe current
    normal = (4500 - 900) / (6000 - 2000) * (1.0 - 0.5 / (4.0 - 2.0))
    assert c['failsafe_fraction'] == pytest.approx(1.0 - normal)
    assert c['first_valid_set_s'] is None           # no identifier status: never
    assert c['samples_lost'] == 3 and c['ride'] is None


def test_full_car_needs_every_corner():
    w = ControlWatch()
    corners = ('fl', 'fr', 'rl', 'rr')
    for k in range(6):
        st = {f'{c}/identifier': {'windows_valid': int(k >= 1 + i)}
              for i, c in enumerate(corners)}
        st['full_car_node'] = {
            't_sim': float(k), 'steps': 1000 * k, 'controller': 'modal-skyhook',
            'corners': {c: {'normal_steps': max(0, 1000 * (k - 2 - (c == 'rr'))),
                            'first_normal_t_sim': 2.0 + (c == 'rr') if k >= 3 + (c == 'rr')
                            else NAN} for c in corners}}
        w.update(st, 100.0 + k)
    summary = {'corners': {c: {'samples_lost': i} for i, c in enumerate(corners)},
               'full_car': {'live': {'a_v': 0.6}, 'passive': {'a_v': 0.8},
                            'passive_0a': {'a_v': 0.7}, 'window_s': [3.0, 5.0],
                            'passive_current_a': 0.5}}
    c = control_summary(w, 100.0, summary)
    assert c['first_valid_set_s'] == 4.0             # rr's identifier last
    # rr's first normal step (car time 3.0 s) on the car's clock (car time k at 100 + k s)
    assert c['first_normal_s'] == 3.0 and c['first_normal_t_sim'] == 3.0
    assert c['units']['fl']['failsafe_fraction'] == pytest.approx(0.0)
    assert c['samples_lost'] == 0 + 1 + 2 + 3
    assert c['ride']['metric'] == 'a_v' and c['ride']['passive_0a'] == 0.7
    # one corner never normal: the car never reached control
    w.laws['rr'].first_rx, w.laws['rr'].first_t_sim = None, NAN
    assert control_summary(w, 100.0, summary)['first_normal_s'] is None


def test_a_run_that_never_left_fail_safe():
    w = ControlWatch()
    for k in range(3):
        w.update({'identifier': {'windows_valid': 0}, 'quarter_car': _car(float(k))}, k)
    log = ArrayLog({'t': np.arange(3000) * 1e-3, 'mode': np.zeros(3000)})
    c = control_summary(w, 0.0, {'messages_lost': 0, 'ride': {}}, logs={'': log})
    assert c['first_valid_set_s'] is None and c['first_normal_s'] is None
    assert c['failsafe_fraction'] is None
    assert 'never' in format_control(c)


def test_a_corner_with_one_recorded_car_status_is_placed_at_the_runs_rate():
    # two corners (their own cars); the recorder, behind on a loaded machine, holds a single
    # status of fr's car: fr's first normal step (car time 2.4 s, from its status) is placed
    # on the clock at the run's real-time factor (fl's car: 1.0) instead of being lost
    w = ControlWatch()
    for k in range(6):
        st = {'fl/identifier': {'windows_valid': 1}, 'fr/identifier': {'windows_valid': 1},
              'fl/quarter_car': _car(float(k), first_normal=1.5 if k >= 2 else NAN)}
        if k == 1:
            st['fr/quarter_car'] = _car(1.0, first_normal=2.4)
        w.update(st, 100.0 + k)
    c = control_summary(w, 100.0, {'corners': {'fl': {'samples_lost': 0},
                                               'fr': {'samples_lost': 0}}})
    assert c['units']['fl']['first_normal_s'] == pytest.approx(1.5)
    assert c['units']['fr']['first_normal_t_sim'] == 2.4
    assert c['units']['fr']['first_normal_s'] == pytest.approx(1.0 + (2.4 - 1.0) / 1.0)
    assert c['first_normal_s'] == pytest.approx(2.4)


def test_a_corner_without_one_recorded_status_reached_control_by_its_log_and_states():
    # two corners with their own laws; the recording holds fr's car statuses but none of fl's
    # (seen in a CI run: the monitor saw both normal); fl's car states (stamp: car time, at
    # real time from wall 102 s) are its clock, its step log (normal from car time 3.0 s) says
    # when it reached control: wall 105 s
    w = ControlWatch()
    for k in range(8):
        w.update({'fl/identifier': {'windows_valid': 1}, 'fr/identifier': {'windows_valid': 1},
                  'fr/quarter_car': _car(float(k), first_normal=1.5 if k >= 2 else NAN)},
                 100.0 + k)
        if k >= 2:
            w.car_state('fl', 100.0 + k, float(k - 2))
    t = np.arange(6000) * 1e-3
    logs = {'fl': ArrayLog({'t': t, 'mode': (t >= 3.0).astype(float)}),
            'fr': ArrayLog({'t': t, 'mode': (t >= 1.5).astype(float)})}
    c = control_summary(w, 100.0, {'corners': {'fl': {'samples_lost': 0},
                                               'fr': {'samples_lost': 0}}}, logs=logs)
    assert c['units']['fl']['first_normal_t_sim'] == pytest.approx(3.0)
    assert c['units']['fl']['first_normal_s'] == pytest.approx(5.0)
    assert c['units']['fl']['failsafe_fraction'] == 0.0
    assert c['first_normal_s'] == pytest.approx(5.0)
    # a car never normal in its log: never, not a guess
    logs['fl'] = ArrayLog({'t': t, 'mode': np.zeros_like(t)})
    c = control_summary(w, 100.0, {'corners': {'fl': {'samples_lost': 0},
                                               'fr': {'samples_lost': 0}}}, logs=logs)
    assert c['units']['fl']['first_normal_s'] is None and c['first_normal_s'] is None


def test_the_cars_states_are_its_clock_where_the_recording_lacks_its_statuses():
    # an external controller; the recorder matched the car's /diagnostics writer too late (a
    # loaded machine): not one status of the car, but its states (stamp: car time), 1024 Hz
    # (binary fractions: exact sums) from wall 20 s at half real time; only those a second
    # apart are decoded as clock points
    w = ControlWatch()
    taken = []
    for k in range(8 * 1024 + 1):
        t_rx = 20.0 + k / 1024
        if w.wants_car_state('', t_rx):
            taken.append(k)
            w.car_state('', t_rx, 0.5 * k / 1024)
        if k % 1024 == 0:
            w.update({'controller': {'commands': k, 'commands_normal': k // 2}}, t_rx)
    # the first (car time 0 is not on the road yet, so the next one too), then one a second
    assert taken == [0, 1] + [1 + 1024 * n for n in range(1, 8)]
    c = control_summary(w, 20.0, {'messages_lost': 0, 'ride': {}})
    assert c['real_time_factor'] == pytest.approx(0.5)
    # the controller's first normal status (wall 21 s) in car time, on the states' clock
    assert c['first_normal_t_sim'] == pytest.approx(0.5)
    # where the car's statuses are there (two on the road), they are its clock, not the states
    w.update({'quarter_car': _car(1.0, controller='external')}, 30.0)
    w.update({'quarter_car': _car(3.0, controller='external')}, 31.0)
    assert w.real_time_factor() == pytest.approx(2.0)


def test_corner_car_states_give_the_clock_of_a_recording_without_the_cars_statuses(tmp_path):
    # a full-car run whose recording holds the corners' car states (stamp: car time, 20 Hz,
    # half real time from 2 s) and none of the car's statuses
    from rclpy.serialization import serialize_message

    from mr_damper_bringup.recorder import SuiteRecorder
    from mr_damper_bringup.report.control import control_from_recording
    from mr_damper_bringup.report.recording import RECORDING
    from mr_damper_bringup.topics import namespaced_table, topic_table
    from mr_damper_common.messages import seconds_to_stamp
    from mr_damper_interfaces.msg import QuarterCarState
    t0 = 1000.0
    table = namespaced_table(topic_table(), ['fl', 'fr'])
    with SuiteRecorder(tmp_path / RECORDING, table, start_ns=int(t0 * 1e9)) as rec:
        for k in range(2, 201):
            t = 0.05 * k
            for c in ('fl', 'fr'):
                state = QuarterCarState()
                seconds_to_stamp(0.5 * (t - 0.1), state.header.stamp)
                rec.write(f'{c}/car_state', serialize_message(state),
                          int(round((t0 + t) * 1e9)))
    summary = {'corners': {'fl': {'samples_lost': 0}, 'fr': {'samples_lost': 0}}}
    c = control_from_recording(tmp_path, summary, ['fl', 'fr'])
    assert c['real_time_factor'] == pytest.approx(0.5, rel=1e-6)
    assert c['samples_lost'] == 0
    # without the corners named, no clock at all (as before: the factor was None)
    assert control_from_recording(tmp_path, summary, [])['real_time_factor'] is None


def test_a_car_that_catches_up_within_one_clock_period_still_has_a_clock(tmp_path):
    # the car fell 4 s behind on a loaded machine and caught up: 4 s of road (car time 0 to
    # 4 s) recorded within 0.4 s of wall time, under one clock period (STATE_CLOCK_PERIOD_S),
    # and the run stopped then (a CI run's full car: real_time_factor None). The newest state
    # is the clock's last point: ten times real time
    from rclpy.serialization import serialize_message

    from mr_damper_bringup.recorder import SuiteRecorder
    from mr_damper_bringup.report.control import control_from_recording, STATE_CLOCK_PERIOD_S
    from mr_damper_bringup.report.recording import RECORDING
    from mr_damper_bringup.topics import namespaced_table, topic_table
    from mr_damper_common.messages import seconds_to_stamp
    from mr_damper_interfaces.msg import QuarterCarState
    t0 = 1000.0
    assert 0.4 < STATE_CLOCK_PERIOD_S
    table = namespaced_table(topic_table(), ['fl'])
    with SuiteRecorder(tmp_path / RECORDING, table, start_ns=int(t0 * 1e9)) as rec:
        for k in range(201):
            state = QuarterCarState()
            seconds_to_stamp(0.02 * k, state.header.stamp)
            rec.write('fl/car_state', serialize_message(state),
                      int(round((t0 + 40.0 + 0.002 * k) * 1e9)))
    summary = {'corners': {'fl': {'samples_lost': 0}}}
    c = control_from_recording(tmp_path, summary, ['fl'])
    # first point: the first state on the road (k = 1, car time 0.02 s); last: k = 200
    assert c['real_time_factor'] == pytest.approx((4.0 - 0.02) / (0.002 * 199), rel=1e-6)
