"""``bench/hypervisor_steal.py``: steal per CPU from /proc/stat, a run's intervals split by it."""
import pytest

from script_helpers import load_script

STAT = """cpu  40347 0 4526 64734 320 0 411 248 0 0
cpu0 14252 0 1651 37691 45 0 50 128 0 0
cpu1 26095 0 2874 27043 274 0 360 119 0 0
intr 123 4 5
ctxt 99
"""


@pytest.fixture(scope='module')
def steal():
    return load_script('bench/hypervisor_steal.py')


def test_steal_ticks_are_each_cpus_eighth_value(steal):
    assert steal.steal_ticks(STAT) == {0: 128, 1: 119}
    assert set(steal.steal_ticks()) >= {0}        # this machine's own file reads too


def test_the_sampler_takes_a_first_and_a_last_sample_and_the_shares_over_them(steal):
    ticks = iter([{0: 0, 1: 0}] + [{0: 5, 1: 0}] * 1000)
    with steal.StealSampler(period_s=0.01, read=lambda: next(ticks)) as s:
        pass
    assert len(s.samples) >= 2 and s.samples[0][1] == {0: 0, 1: 0}
    assert s.samples[-1][1] == {0: 5, 1: 0}
    span = s.samples[-1][0] - s.samples[0][0]
    shares = s.shares()
    assert shares[1] == 0.0 and shares[0] == pytest.approx(5 * steal.TICK_S / span)


def test_intervals_split_by_whether_a_cpu_lost_a_tick_in_them(steal):
    # statuses every second: 500 cycles each; misses 0, 7 (the stolen second), then 1
    counts = [(10.0, 0, 0), (11.0, 500, 0), (12.0, 1000, 7), (13.0, 1500, 8), (14.0, 2000, 8)]
    # samples every 0.25 s; cpu1 loses a tick between 11.5 and 11.75
    samples = [(9.75 + 0.25 * k, {0: 3, 1: 10 + (9.75 + 0.25 * k >= 11.75)})
               for k in range(15)]            # up to 13.25: the last interval unsampled
    split = steal.quiet_split(counts, samples)
    assert split['stolen'] == {'intervals': 1, 'cycles': 500, 'misses': 7,
                               'on_time': pytest.approx(1 - 7 / 500)}
    assert split['quiet'] == {'intervals': 2, 'cycles': 1000, 'misses': 1,
                              'on_time': pytest.approx(1 - 1 / 1000)}
    assert split['unsampled'] == 1


def test_a_tick_at_an_intervals_edge_counts_it_stolen_and_no_cycles_no_figure(steal):
    counts = [(1.0, 0, 0), (2.0, 10, 0)]
    edge = [(1.0, {0: 0}), (1.5, {0: 0}), (2.0, {0: 1})]
    assert steal.quiet_split(counts, edge)['stolen']['intervals'] == 1
    empty = steal.quiet_split([], edge)
    assert empty['quiet']['on_time'] is None and empty['stolen']['on_time'] is None
