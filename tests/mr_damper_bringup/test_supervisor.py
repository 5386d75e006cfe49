"""Tests of mr_damper_bringup.supervisor: back-off, the restart window, give-up (fake clock)."""
import signal

import pytest

from fake_clock import FakeClock
from mr_damper_bringup.supervisor import (describe_exit, HANG_PERIODS, hang_timeout, HangWatch,
                                          RestartPolicy, Supervisor)


class FakeNode:
    """A node process that dies when told to; restarts are counted."""

    def __init__(self):
        self.alive = True
        self.starts = 1

    def start(self):
        assert not self.alive
        self.alive = True
        self.starts += 1


def drive(sup, nodes, deaths, t_end, step=0.05):
    """
    Run the launcher's loop on a fake clock: kill at the given times, restart when due.

    ``deaths`` is a list of ``(time, node, code)``; returns the time the run ended (a give-up)
    or ``t_end``.
    """
    deaths = sorted(deaths)
    now = 0.0
    while now < t_end:
        while deaths and deaths[0][0] <= now:
            _, name, code = deaths.pop(0)
            if nodes[name].alive:
                nodes[name].alive = False
                if not sup.died(name, code, now, epoch_s=1000.0 + now):
                    return now
        for name in sup.due(now):
            nodes[name].start()
            sup.restarted(name, now, epoch_s=1000.0 + now)
        now = round(now + step, 6)
    return t_end


def test_backoff_doubles_up_to_the_cap():
    policy = RestartPolicy(max_restarts=10, restart_window_s=100.0, backoff_s=0.5,
                           backoff_max_s=3.0)
    assert [policy.delay(n) for n in range(1, 7)] == [0.5, 1.0, 2.0, 3.0, 3.0, 3.0]


def test_each_death_is_restarted_after_its_backoff_and_recorded():
    sup = Supervisor(RestartPolicy(max_restarts=3, restart_window_s=60.0, backoff_s=1.0,
                                   backoff_max_s=8.0), t0=0.0)
    nodes = {'ident': FakeNode(), 'car': FakeNode()}
    end = drive(sup, nodes, [(5.0, 'ident', -signal.SIGKILL), (10.0, 'car', 1),
                             (12.0, 'ident', -signal.SIGKILL)], t_end=30.0)
    assert end == 30.0 and sup.gave_up is None
    assert sup.counts() == {'ident': 2, 'car': 1}
    assert all(n.alive for n in nodes.values())
    r = sup.restarts
    assert [x['node'] for x in r] == ['ident', 'car', 'ident']
    assert r[0]['signal'] == 'SIGKILL' and r[0]['exit_code'] is None
    assert r[1]['signal'] is None and r[1]['exit_code'] == 1
    # first death in the window waits backoff_s, the second of the same node twice that
    assert r[0]['restart_s'] - r[0]['death_s'] == pytest.approx(1.0)
    assert r[1]['restart_s'] - r[1]['death_s'] == pytest.approx(1.0)
    assert r[2]['restart_s'] - r[2]['death_s'] == pytest.approx(2.0)
    assert r[2]['backoff_s'] == 2.0 and r[2]['count'] == 2
    assert r[0]['death_epoch_s'] == pytest.approx(1005.0)
    assert r[0]['restart_epoch_s'] == pytest.approx(1006.0)


def test_a_node_dying_too_often_within_the_window_ends_the_run():
    sup = Supervisor(RestartPolicy(max_restarts=2, restart_window_s=20.0, backoff_s=0.5,
                                   backoff_max_s=8.0), t0=0.0)
    nodes = {'car': FakeNode()}
    kills = [(t, 'car', 2) for t in (1.0, 3.0, 6.0, 9.0)]
    end = drive(sup, nodes, kills, t_end=30.0)
    assert end == pytest.approx(6.0)                     # the third death within 20 s
    assert sup.counts() == {'car': 2}
    assert sup.gave_up == {'node': 'car', 'death_s': pytest.approx(6.0), 'exit_code': 2,
                           'signal': None, 'reason': 'died', 'deaths_in_window': 3,
                           'restart_window_s': 20.0}


def test_deaths_outside_the_window_are_forgotten():
    sup = Supervisor(RestartPolicy(max_restarts=1, restart_window_s=5.0, backoff_s=0.5,
                                   backoff_max_s=8.0), t0=0.0)
    nodes = {'rig': FakeNode()}
    end = drive(sup, nodes, [(t, 'rig', -9) for t in (1.0, 7.0, 13.0, 19.0)], t_end=25.0)
    assert end == 25.0 and sup.gave_up is None
    assert sup.counts() == {'rig': 4}
    # each death is the first of its window again: the back-off starts over
    assert [r['backoff_s'] for r in sup.restarts] == [0.5] * 4


def test_no_restart_with_max_restarts_zero():
    sup = Supervisor(RestartPolicy(max_restarts=0), t0=10.0)
    assert sup.died('car', 1, 12.0) is False
    assert sup.gave_up['death_s'] == pytest.approx(2.0) and sup.restarts == []


def test_a_pending_restart_cannot_be_scheduled_twice():
    sup = Supervisor(RestartPolicy(), t0=0.0)
    assert sup.died('car', 1, 1.0)
    assert sup.pending('car') and sup.due(1.1) == []
    with pytest.raises(ValueError, match='car'):
        sup.died('car', 1, 1.2)


@pytest.mark.parametrize('kwargs, name', [({'max_restarts': -1}, 'max_restarts'),
                                          ({'max_restarts': 1.5}, 'max_restarts'),
                                          ({'restart_window_s': -1.0}, 'restart_window_s'),
                                          ({'backoff_s': float('nan')}, 'backoff_s'),
                                          ({'backoff_s': 2.0, 'backoff_max_s': 1.0},
                                           'backoff_max_s')])
def test_bad_policies_are_refused(kwargs, name):
    with pytest.raises(ValueError, match=name):
        RestartPolicy(**kwargs)


def test_describe_exit():
    assert describe_exit(-signal.SIGKILL) == (None, 'SIGKILL')
    assert describe_exit(3) == (3, None)


class Heart:
    """
    Nodes' heartbeats, CPU use and the listener, on one fake clock.

    Each node beats every ``period_s`` while ``beating[node]``, and uses ``cpu[node]`` of a
    core (sampled every second, as the launcher does); ``cpu[node] = None``: no CPU samples.
    Of that, its spin thread uses ``spin[node]`` of a core (None: not sampled).
    """

    def __init__(self, watch, clock, nodes, period_s=1.0, step_s=0.1):
        self.watch, self.clock, self.period_s, self.step_s = watch, clock, period_s, step_s
        self.beating = dict.fromkeys(nodes, True)
        self.cpu = dict.fromkeys(nodes, 0.3)
        self.used = dict.fromkeys(nodes, 0.0)
        self.spin = dict.fromkeys(nodes, None)
        self.used_spin = dict.fromkeys(nodes, 0.0)
        self.next = dict.fromkeys(nodes, clock.now + period_s)
        self.next_cpu = clock.now + 1.0
        self.verdicts = []      # (t, node, silent_s, cpu_share, spin_cpu_share) of every verdict

    def run(self, seconds, listening=True):
        """Advance the clock by ``seconds``; return ``[(t, node)]`` of the hang verdicts."""
        out = []
        end = self.clock.now + seconds
        while self.clock.now < end - 1e-9:
            self.clock.now = round(self.clock.now + self.step_s, 9)
            for node, beating in self.beating.items():
                self.used[node] += (self.cpu[node] or 0.0) * self.step_s
                self.used_spin[node] += (self.spin[node] or 0.0) * self.step_s
                if self.clock.now >= self.next[node]:
                    self.next[node] += self.period_s
                    if beating:
                        self.watch.beat(node, self.clock.now)
            if self.clock.now >= self.next_cpu:
                self.next_cpu += 1.0
                for node, share in self.cpu.items():
                    if share is not None:
                        spin = None if self.spin[node] is None else self.used_spin[node]
                        self.watch.cpu(node, self.clock.now, self.used[node], spin)
            if listening:
                self.watch.listening(self.clock.now)
            for node, *shares in self.watch.hung():
                self.verdicts.append((self.clock.now, node, *shares))
                out.append((self.clock.now, node))
                self.watch.forget(node)
        return out


def test_a_node_whose_heartbeat_stops_is_hung_after_its_timeout_and_no_other():
    clock = FakeClock(0.0)
    watch = HangWatch({'car': 5.0, 'rig': 5.0})
    for n in ('car', 'rig'):
        watch.started(n, clock.now)
    heart = Heart(watch, clock, ('car', 'rig'))
    assert heart.run(30.0) == []                            # both beating: never hung
    heart.beating['car'] = False                            # frozen: silent and idle
    heart.cpu['car'] = 0.0
    last = heart.next['car'] - 1.0                          # its last beat
    verdicts = heart.run(30.0)
    assert [n for _, n in verdicts] == ['car']              # once (then forgotten), not the rig
    t, _ = verdicts[0]
    assert 5.0 < t - last <= 5.0 + heart.step_s + 1e-9      # the first check past the timeout


def test_a_silent_node_that_keeps_working_gets_the_longer_limit():
    """Behind on a loaded machine (its status waits behind its backlog), not frozen."""
    clock = FakeClock(0.0)
    watch = HangWatch({'rec': 5.0}, busy_factor=8.0)
    watch.started('rec', 0.0)
    heart = Heart(watch, clock, ('rec',))
    heart.cpu['rec'] = 0.06             # 6 % of a core: a starved but runnable process
    assert heart.run(10.0) == []
    heart.beating['rec'] = False
    last = heart.next['rec'] - 1.0
    verdicts = heart.run(60.0)
    assert [n for _, n in verdicts] == ['rec']              # a livelock is still found
    assert 40.0 < verdicts[0][0] - last <= 40.0 + heart.step_s + 1e-9
    # a node without CPU samples: the timeout alone decides
    watch = HangWatch({'x': 5.0})
    watch.started('x', 0.0)
    heart = Heart(watch, FakeClock(0.0), ('x',))
    heart.cpu['x'] = None
    heart.run(3.0)
    heart.beating['x'] = False
    assert len(heart.run(7.0)) == 1


def test_a_silent_node_whose_spin_thread_starved_is_hung_after_one_timeout():
    """Its process burns a core, but the thread that publishes its status runs not at all."""
    clock = FakeClock(0.0)
    watch = HangWatch({'vehicle': 5.0, 'rec': 5.0}, busy_factor=8.0)
    for n in ('vehicle', 'rec'):
        watch.started(n, 0.0)
    heart = Heart(watch, clock, ('vehicle', 'rec'))
    heart.cpu.update(vehicle=0.95, rec=0.5)
    heart.spin.update(vehicle=0.05, rec=0.3)
    assert heart.run(10.0) == []
    # the vehicle computer: a real-time thread of its own starves its executor
    heart.beating['vehicle'] = False
    heart.spin['vehicle'] = 0.0
    # the recorder: behind, its status waits behind its backlog, its spin thread at work
    heart.beating['rec'] = False
    heart.spin['rec'] = 0.06
    last = heart.next['vehicle'] - 1.0
    assert [n for _, n in heart.run(20.0)] == ['vehicle']
    t, node, silent, share, spin = heart.verdicts[0]
    assert 5.0 < t - last <= 5.0 + heart.step_s + 1e-9 and silent > 5.0
    assert share == pytest.approx(0.95) and spin == 0.0
    verdicts = heart.run(30.0)                             # the recorder keeps the long limit
    assert [n for _, n in verdicts] == ['rec']
    assert 40.0 < verdicts[0][0] - last <= 40.0 + heart.step_s + 1e-9
    assert heart.verdicts[1][3:] == (pytest.approx(0.5), pytest.approx(0.06))


def test_a_spin_thread_share_is_only_known_from_two_samples_after_the_beat():
    watch = HangWatch({'car': 5.0})
    watch.started('car', 0.0)
    watch.beat('car', 1.0)
    watch.cpu('car', 2.0, 10.0, 3.0)
    assert watch.busy('car') is None and watch.busy('car', spin=True) is None
    watch.cpu('car', 4.0, 11.0, 3.5)
    assert watch.busy('car') == 0.5 and watch.busy('car', spin=True) == 0.25
    watch.cpu('car', 6.0, 12.0, None)           # the thread could not be read this time
    assert watch.busy('car') == 0.5 and watch.busy('car', spin=True) is None


def test_the_watch_is_armed_by_the_first_heartbeat_after_each_start():
    clock = FakeClock(0.0)
    watch = HangWatch({'ident': 5.0})
    watch.started('ident', 0.0)
    heart = Heart(watch, clock, ('ident',))
    heart.beating['ident'] = False              # a long start-up (a large file, a busy machine)
    assert heart.run(120.0) == [] and not watch.armed('ident')
    heart.beating['ident'] = True
    assert heart.run(3.0) == [] and watch.armed('ident')
    # a restart disarms it; a heartbeat of the old process (received before) does not re-arm
    watch.started('ident', clock.now)
    watch.beat('ident', clock.now - 0.5)
    assert not watch.armed('ident') and watch.silence('ident') is None


def test_a_stalled_listener_does_not_make_hung_nodes():
    """The launcher itself stopped (SIGSTOP, starved): silence it did not hear is not counted."""
    clock = FakeClock(0.0)
    watch = HangWatch({'car': 5.0}, gap_s=1.0)
    watch.started('car', 0.0)
    heart = Heart(watch, clock, ('car',))
    assert heart.run(10.0) == []
    # 60 s without listening: the node's beats of that time are only delivered afterwards
    clock.now += 60.0
    watch.listening(clock.now)                  # first turn after the stall: a new stretch
    assert watch.hung() == [] and watch.silence('car') == 0.0
    heart.next['car'] = clock.now + 0.2         # the queued beats arrive
    assert heart.run(20.0) == []
    # a node that really stopped is still found, the timeout counted from the new stretch
    heart.beating['car'] = False
    heart.cpu['car'] = 0.0
    assert [n for _, n in heart.run(20.0)] == ['car']


def test_a_forgotten_node_is_not_watched_until_restarted():
    watch = HangWatch({'rec': 2.0})
    watch.started('rec', 0.0)
    watch.beat('rec', 1.0)
    watch.forget('rec')                         # it died: the supervisor restarts it
    for t in range(2, 30):
        watch.listening(float(t))
    assert watch.hung() == [] and not watch.armed('rec')


def test_hang_timeout_covers_slow_statuses_and_zero_is_off():
    assert hang_timeout(15.0, 1.0) == 15.0
    assert hang_timeout(15.0, 10.0) == HANG_PERIODS * 10.0     # a node set to a 10 s status
    assert hang_timeout(15.0, None) == 15.0
    assert hang_timeout(0.0, 1.0) == 0.0
    watch = HangWatch({'car': 0.0})
    watch.started('car', 0.0)
    watch.beat('car', 0.5)
    for t in range(1, 100):
        watch.listening(float(t))
    assert watch.hung() == [] and watch.silence('car') > 90.0


def test_a_hung_node_counts_as_a_death_with_its_reason():
    sup = Supervisor(RestartPolicy(max_restarts=1, restart_window_s=60.0), t0=0.0)
    assert sup.died('car', -signal.SIGKILL, 20.0, reason='hung', silent_s=15.3, cpu_share=0.9,
                    spin_cpu_share=0.0)
    r = sup.restarts[-1]
    assert (r['reason'], r['signal'], r['silent_s'], r['cpu_share'], r['spin_cpu_share']) == \
        ('hung', 'SIGKILL', 15.3, 0.9, 0.0)
    sup.restarted('car', 21.0)
    assert not sup.died('car', 1, 30.0)          # hung + died: two deaths in the window
    assert sup.gave_up['reason'] == 'died' and sup.gave_up['deaths_in_window'] == 2
    with pytest.raises(ValueError, match='reason'):
        Supervisor(RestartPolicy(), 0.0).died('x', 1, 0.0, reason='bored')
