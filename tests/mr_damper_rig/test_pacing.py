"""
Tests of the rig's publishing schedule with an injected clock (no ROS, no wall time).

Samples due from the clock and ``rate_factor`` (exact counts of a record with known stamps),
waiting for subscribers and for the consumer's first count, flow control against the
consumer's count, restarts of the consumer, end of source, speed changes while running, and
the lockstep pacer's silent-commander schedule.
"""
import numpy as np
import pytest

from mr_damper_model.io.data import DamperData
from mr_damper_rig.pacing import LockstepPacer, Pacer
from mr_damper_rig.replay import ArraySource

from fake_clock import FakeClock


def record(n=1000, rate_hz=1000.0):
    t = np.arange(n) / rate_hz + 5.0
    z = np.zeros(n)
    return ArraySource(DamperData(t, z, z, z, z))


def run(pacer, clock, dt, ticks, subscribers=1):
    """Tick ``ticks`` times ``dt`` apart, publishing what is due; return the counts per tick."""
    counts = []
    for _ in range(ticks):
        clock.t += dt
        if pacer.waiting(subscribers):
            counts.append(0)
            continue
        n = pacer.due()
        pacer.sent(n)
        counts.append(n)
    return counts


@pytest.mark.parametrize('rate_factor', [1.0, 4.0, 0.5])
def test_samples_due_follow_the_clock_times_rate_factor(rate_factor):
    clock = FakeClock()
    pacer = Pacer(record(), rate_factor, clock=clock)
    assert not pacer.waiting(0) and pacer.due() == 1   # the sample at record time 0
    pacer.sent()
    for step in range(1, 50):
        wall_s = step * 0.002 + 0.0001    # between two sample instants at every rate_factor
        clock.t = 100.0 + wall_s
        pacer.sent(pacer.due())
        # samples whose record time (1 ms apart) is at most elapsed wall time x rate_factor
        assert pacer.published == min(int(wall_s * rate_factor * 1000) + 1, 1000)


def test_end_of_source_finishes_and_stops_publishing():
    clock = FakeClock()
    pacer = Pacer(record(n=100), 1.0, clock=clock)
    counts = run(pacer, clock, 0.01, 20)
    assert sum(counts) == 100 and pacer.finished
    # started at the first tick (100.01 s); the last sample (record time 99 ms) went out at
    # the tick 100 ms later
    assert pacer.start_s == pytest.approx(100.01) and pacer.end_s == pytest.approx(100.11)
    assert pacer.due() == 0
    assert pacer.values()['done'] and pacer.values()['samples_published'] == 100
    assert pacer.elapsed_s() == pytest.approx(0.1)


def test_looped_source_never_finishes():
    data = record(n=10)
    data.loop = True
    clock = FakeClock()
    pacer = Pacer(data, 1.0, clock=clock)
    run(pacer, clock, 0.005, 100)
    assert not pacer.finished and pacer.published == data.count_due(0.5 - 0.005)


def test_waits_for_subscribers_then_for_at_most_the_start_timeout():
    clock = FakeClock()
    pacer = Pacer(record(), 1.0, clock=clock, wait_for_subscribers=2, start_timeout_s=30.0)
    assert pacer.waiting(1) and pacer.due() == 0 and not pacer.started
    clock.t += 29.0
    assert pacer.waiting(1)
    assert not pacer.waiting(2) and pacer.started and pacer.start_s == clock.t
    # never matched: starts anyway after the timeout
    other = Pacer(record(), 1.0, clock=clock, wait_for_subscribers=2, start_timeout_s=30.0)
    clock.t += 30.0
    assert not other.waiting(0)


def test_behind_max_counts_a_stalled_tick_and_batches_are_bounded():
    clock = FakeClock()
    pacer = Pacer(record(n=20000), 1.0, clock=clock, max_batch=5000)
    assert not pacer.waiting(0)
    pacer.sent(pacer.due())
    clock.t += 7.0                       # a 7-s stall: 7000 samples due
    assert pacer.due() == 5000 and pacer.behind_max == 7000
    pacer.sent(5000)
    assert pacer.due() == 2000


def test_rate_factor_changes_keep_the_record_time_reached():
    clock = FakeClock()
    pacer = Pacer(record(n=100000), 1.0, clock=clock)
    assert not pacer.waiting(0)
    clock.t += 2.0
    assert pacer.record_time_s() == pytest.approx(2.0)
    pacer.set_rate_factor(4.0)
    clock.t += 1.0005
    assert pacer.record_time_s() == pytest.approx(6.002)
    while pacer.due():
        pacer.sent(pacer.due())
    assert pacer.published == 6003
    with pytest.raises(ValueError, match='to or from 0'):
        pacer.set_rate_factor(0.0)
    with pytest.raises(ValueError, match='rate_factor'):
        pacer.set_rate_factor(float('nan'))
    assert pacer.rate_factor == 4.0


def test_flow_control_waits_for_the_first_count_and_keeps_the_window():
    clock = FakeClock()
    pacer = Pacer(record(n=10000), 0.0, clock=clock, flow_window=100)
    assert pacer.waiting(1)               # no count from the consumer yet
    pacer.on_flow(0)
    assert not pacer.waiting(1)
    pacer.sent(pacer.due())
    assert pacer.published == 100         # a full window ahead of the consumer
    assert pacer.due() == 0               # nothing more until the consumer reports
    pacer.on_flow(40)
    assert pacer.due() == 40
    pacer.sent(40)
    pacer.on_flow(140)
    pacer.sent(pacer.due())
    assert pacer.published == 240 == pacer.flow_received + pacer.flow_window
    pacer.set_flow_window(10)
    assert pacer.due() == 0
    pacer.on_flow(240)
    assert pacer.due() == 10


def test_flow_control_counts_before_the_start_are_the_base():
    """A consumer that already received samples of an earlier stream: paced from its count."""
    clock = FakeClock()
    pacer = Pacer(record(n=10000), 0.0, clock=clock, flow_window=50)
    pacer.on_flow(7000)
    assert not pacer.waiting(0)
    pacer.sent(pacer.due())
    assert pacer.published == 50
    pacer.on_flow(7030)
    assert pacer.due() == 30


def test_consumer_restart_paces_against_its_new_count():
    clock = FakeClock()
    pacer = Pacer(record(n=10000), 0.0, clock=clock, flow_window=100)
    pacer.on_flow(0)
    assert not pacer.waiting(1)
    pacer.sent(pacer.due())
    pacer.on_flow(100)
    pacer.sent(pacer.due())
    assert pacer.published == 200 and pacer.flow_restarts == 0
    pacer.on_flow(0)                      # restarted: its count began again
    assert pacer.flow_restarts == 1
    assert pacer.due() == 100             # one window ahead of what it will now receive
    pacer.sent(100)
    pacer.on_flow(30)
    assert pacer.due() == 30
    assert pacer.values()['flow'] == {'received': 30, 'window': 100}


def test_flow_control_without_any_count_publishes_one_sample_per_tick():
    clock = FakeClock()
    pacer = Pacer(record(n=1000), 0.0, clock=clock, start_timeout_s=30.0, flow_window=100)
    assert pacer.waiting(1)
    clock.t += 30.0
    counts = run(pacer, clock, 0.002, 5)
    assert counts == [1, 1, 1, 1, 1]
    # a count arriving late: the consumer is taken to have what was published (5), so one
    # window more is due
    pacer.on_flow(3)
    assert pacer.due() == 100
    pacer.sent(100)
    pacer.on_flow(8)
    assert pacer.due() == 5


def test_bad_settings_are_refused_with_the_argument_named():
    with pytest.raises(ValueError, match='rate_factor'):
        Pacer(record(), -1.0)
    with pytest.raises(ValueError, match='flow_window'):
        Pacer(record(), 0.0, flow_window=0)
    pacer = Pacer(record(), 1.0)
    with pytest.raises(ValueError, match='flow_window'):
        pacer.set_flow_window(2.5)


def test_lockstep_runs_on_its_own_clock_only_after_the_timeout():
    clock = FakeClock()
    lock = LockstepPacer(1000.0, 0.05, 2.0, clock=clock)
    assert lock.due() == 0                # before the first command: nothing
    lock.command()
    lock.sent()
    clock.t += 0.02                       # 40 ms of rig time: within the timeout
    assert lock.due() == 0
    clock.t += 0.03                       # 100 ms of rig time silent: 100 samples due
    assert lock.due() == 100
    lock.sent(60, free=True)
    assert lock.due() == 40
    lock.command()                        # the car is back: lockstep again
    assert lock.free == 0 and lock.due() == 0
    assert lock.values()['samples_published'] == 61 and lock.values()['rate_factor'] == 2.0
    zero = LockstepPacer(1000.0, 0.05, 0.0, clock=clock)   # rate_factor 0 counts as 1
    zero.command()
    clock.t += 0.1
    assert zero.due() == 100 and zero.values()['rate_factor'] == 0.0


def test_lockstep_takes_commands_once_its_readers_matched_or_after_the_start_timeout():
    clock = FakeClock()
    lock = LockstepPacer(1000.0, 0.05, clock=clock, wait_for_subscribers=2,
                         start_timeout_s=30.0)
    assert not lock.accepting(0) and not lock.accepting(1)
    clock.t += 1.0
    assert lock.accepting(2) and lock.accepting_s == clock.t
    assert lock.accepting(0)              # latched: a reader leaving does not close it
    late = LockstepPacer(1000.0, 0.05, clock=clock, wait_for_subscribers=2,
                         start_timeout_s=30.0)
    clock.t += 29.9
    assert not late.accepting(1)
    clock.t += 0.1                        # 30 s without the readers: it takes commands anyway
    assert late.accepting(1)
    assert LockstepPacer(1000.0, 0.05, clock=clock).accepting(0)   # nothing to wait for
