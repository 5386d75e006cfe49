"""Tests of mr_damper_bringup.supervisor: back-off, the restart window, give-up (fake clock)."""
import signal

import pytest

from mr_damper_bringup.supervisor import describe_exit, RestartPolicy, Supervisor


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
                           'signal': None, 'deaths_in_window': 3, 'restart_window_s': 20.0}


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
