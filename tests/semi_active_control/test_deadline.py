"""DeadlineMonitor on a fake clock: misses and lateness counted, fail-safe reasons, recovery."""
import pytest

from fake_clock import FakeClock
from semi_active_control.supervision.deadline import DeadlineMonitor

P = 0.002


def test_misses_are_counted_with_their_lateness():
    mon = DeadlineMonitor(P, max_consecutive_misses=3, recover_cycles=4)
    clock = FakeClock(10.0)
    answers = (0.0005, 0.0025, 0.001, 0.004, 0.0019)      # release -> answer [s]
    on_time = []
    for r in answers:
        t0 = clock.now
        on_time.append(mon.cycle(t0, t0 + r))
        clock.t += P
    assert on_time == [True, False, True, False, True]
    st = mon.status()
    assert (st['cycles'], st['deadline_misses'], st['consecutive_misses']) == (5, 2, 0)
    assert st['lateness']['n'] == 2
    assert st['lateness']['max_s'] == pytest.approx(0.002)
    assert st['lateness']['last_s'] == pytest.approx(0.002)
    assert st['lateness']['mean_s'] == pytest.approx(0.00125)
    assert st['response']['max_s'] == pytest.approx(0.004)
    assert st['reason'] == '' and st['entries']['deadline_misses'] == 0


def test_consecutive_misses_fail_safe_then_recover_by_itself():
    mon = DeadlineMonitor(P, max_consecutive_misses=3, recover_cycles=4)
    clock = FakeClock(0.0)
    reasons = []
    for late in [True] * 3 + [False] * 3 + [True] + [False] * 4:
        t0 = clock.now
        mon.cycle(t0, t0 + (0.003 if late else 0.001))
        reasons.append(mon.reason)
        clock.t += P
    # the third miss in a row: deadline_misses; a miss within the recovery run starts it anew;
    # four on time in a row clear it
    assert reasons[:2] == [None, None]
    assert reasons[2:10] == ['deadline_misses'] * 8
    assert reasons[10] is None
    assert mon.entries['deadline_misses'] == 1
    # from the third miss's answer (t = 0.007 s) to the fourth on-time answer (0.021 s)
    assert mon.status()['failsafe_s']['deadline_misses'] == pytest.approx(0.014)


def test_no_input_for_the_timeout_is_a_sensor_timeout_until_the_next_input():
    mon = DeadlineMonitor(P, input_timeout_s=0.02)
    clock = FakeClock(5.0)
    mon.input(clock.now)
    clock.t += 0.019
    assert mon.check(clock.now) is None
    clock.t += 0.002
    assert mon.check(clock.now) == 'sensor_timeout'
    clock.t += 0.1
    assert mon.check(clock.now) == 'sensor_timeout'
    assert mon.entries['sensor_timeout'] == 1             # one outage, one entry
    mon.input(clock.now)
    assert mon.check(clock.now) is None
    # from the check that found it (t = 5.021 s) to the next input (5.121 s)
    assert mon.status()['failsafe_s']['sensor_timeout'] == pytest.approx(0.1)
    # a sensor timeout wins over deadline misses
    for _ in range(5):
        mon.cycle(clock.now, clock.now + 0.01)
    clock.t += 0.05
    assert mon.check(clock.now) == 'sensor_timeout'
    mon.input(clock.now)
    assert mon.reason == 'deadline_misses'


def test_reset_keeps_the_counts_and_ends_the_reasons():
    mon = DeadlineMonitor(P, max_consecutive_misses=1)
    mon.cycle(0.0, 0.01)
    assert mon.reason == 'deadline_misses'
    mon.reset(t_now=0.5)
    assert mon.reason is None and mon.misses == 1
    assert mon.failsafe_s['deadline_misses'] == pytest.approx(0.49)
    with pytest.raises(ValueError):
        DeadlineMonitor(0.0)
