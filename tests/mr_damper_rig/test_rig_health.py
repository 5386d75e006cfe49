"""
Tests of the rig's health (the /diagnostics level and message) from its status values.

Each finding is injected into a known status and must raise its level once, then clear when
the counter stops rising; the values are carried unchanged.
"""
from mr_damper_common.health import ERROR, OK, WARN
from mr_damper_rig.rig_health import RigHealth


def status(**changes):
    values = {'mode': 'csv', 'started': True, 'done': False, 'samples_published': 100,
              'backlog_samples': 0, 'subscribers': 1, 'wait_for_subscribers': 1,
              'writer_resets': 0, 'dropped': {}, 'rate_factor': 1.0,
              'commands': {'accepted': 0, 'clamped_low': 0, 'clamped_high': 0,
                           'refused_non_finite': 0}}
    values.update(changes)
    return values


def test_running_waiting_and_done_are_ok_with_their_message():
    health = RigHealth()
    h = health(status(started=False, subscribers=0, wait_for_subscribers=2))
    assert h.level == OK and h.message == 'waiting for subscribers (0 of 2)'
    assert health(status()).message == 'running'
    h = health(status(done=True, samples_published=5000))
    assert h.level == OK and h.message == 'done: 5000 samples published'
    assert h.values['samples_published'] == 5000


def test_a_stalled_writer_is_an_error_until_samples_flow_again():
    health = RigHealth()
    assert health(status(samples_published=100, backlog_samples=40)).level == OK   # first
    h = health(status(samples_published=100, backlog_samples=80))
    assert h.level == ERROR and 'publishing stalled: 80 samples due' in h.message
    assert health(status(samples_published=180, backlog_samples=0)).level == OK
    # nothing due and nothing published (flow control waiting for the consumer): fine
    assert health(status(samples_published=180, backlog_samples=0)).level == OK


def test_writer_resets_and_drops_warn_once_per_rise():
    health = RigHealth()
    health(status())
    h = health(status(writer_resets=1, dropped={'publish_failed': 2}))
    assert h.level == WARN
    assert 'writer replaced 1 time(s)' in h.message and 'dropped: 2 publish_failed' in h.message
    assert health(status(writer_resets=1, dropped={'publish_failed': 2})).level == OK
    h = health(status(writer_resets=1, dropped={'publish_failed': 2, 'command_lost': 3}))
    assert h.level == WARN and h.message == 'dropped: 3 command_lost'


def test_clamped_commands_and_a_silent_commander_warn():
    health = RigHealth()
    disp = {'accepted': 5, 'clamped_low': 0, 'clamped_high': 0, 'refused_non_finite': 0,
            'stale_timeouts': 0, 'stale_samples': 0}
    health(status(displacement_commands=disp))
    h = health(status(commands={'accepted': 1, 'clamped_low': 0, 'clamped_high': 2,
                                'refused_non_finite': 1}, displacement_commands=disp))
    assert h.level == WARN
    assert h.message == 'current commands clamped high: 2, refused non finite: 1'
    h = health(status(commands={'accepted': 1, 'clamped_low': 0, 'clamped_high': 2,
                                'refused_non_finite': 1},
                      displacement_commands=dict(disp, stale_timeouts=1, stale_samples=40)))
    assert h.level == WARN and h.message == ('commander silent: 40 samples held or returning '
                                             'to neutral')


def test_flow_control_without_a_count_warns():
    health = RigHealth()
    h = health(status(rate_factor=0.0, flow={'received': None, 'window': 1000}))
    assert h.level == WARN and 'no count from the consumer' in h.message
    assert health(status(rate_factor=0.0, flow={'received': 10, 'window': 1000})).level == OK
