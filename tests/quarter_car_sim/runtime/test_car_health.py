"""Tests of quarter_car_sim.runtime.car_health: the rules of the car's diagnostics."""
from mr_damper_common.health import ERROR, OK, WARN
from quarter_car_sim.runtime.car_health import CarHealth
from semi_active_control.supervision.health import failsafe_message


def _car_status(**changes):
    st = {'mode': 'normal', 'reason': 'ok', 'failsafe_s': 0.0, 'failsafe_entries': 0,
          'params_accepted': 1, 'params_rejected': {'invalid_flag': 0}, 'param_age_s': 0.1,
          'current_a': 1.0, 'steps': 100, 'late_reanchors': 0,
          'loop': {'lateness': {'p99_ms': 0.1}}, 'dropped': {}}
    st.update(changes)
    return st


def test_normal_running_car_is_ok_and_carries_status_and_ride_metrics():
    h = CarHealth()(_car_status(), {'rms_body_accel_wk': 0.8, 'rms_tyre_load_ratio': 0.1})
    assert (h.level, h.message) == (OK, 'ok')
    assert h.values['params_accepted'] == 1 and h.values['ride_metrics']['rms_body_accel_wk'] \
        == 0.8


def test_failsafe_is_a_warning_that_says_why():
    rules = CarHealth()
    for reason, words in (('no_parameters_yet', 'no identified parameters yet'),
                          ('stale', 'stale'), ('command_timeout', 'no current command'),
                          ('no_command_yet', 'no current command yet')):
        h = rules(_car_status(mode='failsafe', reason=reason))
        assert h.level == WARN and words in h.message and h.message.startswith('fail-safe')
    h = rules(_car_status(mode='failsafe', reason='out_of_bounds',
                          last_reject_detail='c1 = -100 not in [0, 1e5]'))
    assert h.message == 'fail-safe: parameters refused (out_of_bounds): c1 = -100 not in [0, 1e5]'
    assert failsafe_message('stale') == rules(_car_status(mode='failsafe',
                                                          reason='stale')).message


def test_dead_or_stopped_control_thread_is_an_error():
    rules = CarHealth()
    h = rules(_car_status(), failed='RuntimeError: boom')
    assert h.level == ERROR and 'control thread died: RuntimeError: boom' in h.message
    assert rules(_car_status(), alive=False).level == ERROR
    # an error outranks the fail-safe warning, which is then not in the message
    h = rules(_car_status(mode='failsafe', reason='stale'), failed='X: y')
    assert h.level == ERROR and 'stale' not in h.message


def test_loop_lateness_and_reanchors_warn():
    rules = CarHealth(lateness_warn_ms=2.0)
    h = rules(_car_status(loop={'lateness': {'p99_ms': 3.0}}))
    assert h.level == WARN and 'lateness p99 3.00 ms > 2 ms' in h.message
    h = rules(_car_status(late_reanchors=2))
    assert h.level == WARN and 're-anchored 2 time(s)' in h.message
    # counted since the previous check: no new re-anchor, back to OK
    assert rules(_car_status(late_reanchors=2)).level == OK


def test_drops_warn_once_per_rise():
    rules = CarHealth()
    assert rules(_car_status(dropped={'publish_failed': 3})).message == \
        'dropped since the last check: 3 publish_failed'
    assert rules(_car_status(dropped={'publish_failed': 3})).level == OK
    assert 'dropped since the last check: 1 publish_failed' in rules(
        _car_status(dropped={'publish_failed': 4})).message


def test_commands_refused_persistently_become_an_error():
    rules = CarHealth(persistent_checks=3)
    counts = {'accepted': 10, 'clamped_low': 0, 'clamped_high': 0, 'refused_non_finite': 0}
    assert rules(_car_status(commands=dict(counts))).level == OK
    levels = []
    for k in range(1, 5):            # only refused commands at every check
        levels.append(rules(_car_status(commands=dict(counts, refused_non_finite=5 * k))).level)
    assert levels == [WARN, WARN, ERROR, ERROR]
    # a usable command again: the count of checks restarts
    h = rules(_car_status(commands=dict(counts, accepted=11, refused_non_finite=25)))
    assert h.level == WARN and '5 current command(s) refused' in h.message
    assert rules(_car_status(commands=dict(counts, accepted=12, refused_non_finite=25))).level \
        == OK


def test_lockstep_timeouts_warn():
    rules = CarHealth()
    assert rules(_car_status(lockstep_timeouts=0)).level == OK
    h = rules(_car_status(lockstep_timeouts=2))
    assert h.level == WARN and '2 lock-step timeout(s)' in h.message


def test_rig_link_faults_warn_with_their_counts():
    rules = CarHealth()
    counts = {'measurements': 100, 'stale_steps': 0, 'wait_timeouts': 0}
    hil = {'tracking': {'rms_m': 1e-4}, 'counts': counts}
    h = rules(_car_status(hil=hil))
    assert h.level == OK and h.values['hil']['tracking']['rms_m'] == 1e-4
    hil['counts'] = {'measurements': 200, 'stale_steps': 4, 'wait_timeouts': 1}
    h = rules(_car_status(hil=hil))
    assert h.level == WARN
    assert h.message == 'rig link since the last check: 4 stale_steps, 1 wait_timeouts'
    hil['counts'] = {'measurements': 300, 'stale_steps': 4, 'wait_timeouts': 1}
    assert rules(_car_status(hil=hil)).level == OK
