"""Tests of semi_active_control.supervision.health: the rules of the controller's diagnostics."""
from mr_damper_common.health import ERROR, OK, WARN
from semi_active_control.supervision.health import ControllerHealth, failsafe_message


def _ctrl_status(**changes):
    st = {'mode': 'normal', 'reason': 'ok', 'commands': 0, 'commands_normal': 0,
          'state_rejected': {'non_finite': 0, 'out_of_order': 0}, 'dropped': {}}
    st.update(changes)
    return st


def test_controller_rules():
    rules = ControllerHealth(persistent_checks=2)
    assert rules(_ctrl_status(commands=10, commands_normal=10)).level == OK
    h = rules(_ctrl_status(commands=20, state_rejected={'non_finite': 3, 'out_of_order': 0}))
    assert h.level == WARN and 'states refused since the last check: 3 non_finite' in h.message
    # only refused states for two checks in a row: ERROR
    h = rules(_ctrl_status(commands=25, state_rejected={'non_finite': 8, 'out_of_order': 0}))
    assert h.level == WARN
    h = rules(_ctrl_status(commands=30, state_rejected={'non_finite': 13, 'out_of_order': 0}))
    assert h.level == ERROR and 'refused persistently' in h.message
    h = rules(_ctrl_status(commands=40, mode='failsafe', reason='stale',
                           state_rejected={'non_finite': 13, 'out_of_order': 0}))
    assert h.level == WARN and h.message == failsafe_message('stale')
    assert h.values['commands'] == 40


def test_controller_state_reasons_and_stamp_rebases():
    rules = ControllerHealth(persistent_checks=2)
    rej = {'non_finite': 0, 'future_stamp': 1, 'out_of_order': 0}
    h = rules(_ctrl_status(commands=10, mode='failsafe', reason='state_future_stamp',
                           state_rejected=rej))
    assert h.level == WARN
    assert failsafe_message('state_future_stamp') in h.message
    assert 'beyond max_future_s' in h.message and '1 future_stamp' in h.message
    for reason in ('state_non_finite', 'state_out_of_order'):
        assert 'parameters' not in failsafe_message(reason)
    h = rules(_ctrl_status(commands=20, state_rejected=rej, stamp_rebases=1))
    assert h.level == WARN and h.message == ('vehicle clock jumped: state stamps re-based 1 '
                                             'time(s) since the last check')
    assert rules(_ctrl_status(commands=30, state_rejected=rej, stamp_rebases=1)).level == OK
