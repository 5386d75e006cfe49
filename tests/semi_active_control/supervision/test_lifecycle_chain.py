"""LifecycleChain: in order up, reverse down, a dead node deactivates the chain, recovery."""
import pytest

from fake_clock import FakeClock
from semi_active_control.supervision.lifecycle_chain import LifecycleChain, TARGET

NODES = ('bridge', 'estimator', 'controller')


class Nodes:
    """Fake managed nodes: each answers a transition by taking it (or refusing it)."""

    def __init__(self, chain, clock):
        self.chain, self.clock = chain, clock
        self.state = dict.fromkeys(NODES, 'unconfigured')
        self.alive = dict.fromkeys(NODES, True)
        self.refuse = set()
        self.mute = set()
        self.log = []

    def beat(self):
        for n in NODES:
            if self.alive[n]:
                self.chain.heartbeat(n, self.state[n], self.clock.now)

    def run(self, steps=20, dt=0.1):
        for _ in range(steps):
            self.clock.t += dt
            self.beat()
            req = self.chain.next_request(self.clock.now)
            if req is None:
                continue
            node, transition = req
            self.log.append(req)
            if not self.alive[node] or node in self.mute:
                continue                     # no answer: the service times out
            ok = (node, transition) not in self.refuse
            if ok:
                self.state[node] = TARGET[transition]
            self.chain.result(node, transition, ok, self.clock.now)


def test_up_in_order_configure_all_then_activate_all():
    clock = FakeClock(0.0)
    chain = LifecycleChain(NODES)
    nodes = Nodes(chain, clock)
    nodes.run()
    assert nodes.log == [(n, 'configure') for n in NODES] + [(n, 'activate') for n in NODES]
    assert chain.up and chain.counts['transitions'] == 6
    # the start-up: first input at 0.1 s, one transition per 0.1 s step, up at the sixth
    assert chain.first_up_s == pytest.approx(0.5) and chain.ups == 1
    st = chain.status(clock.now)
    assert st['first_up_s'] == chain.first_up_s and st['ups'] == 1


def test_the_start_up_is_timed_from_the_first_input_and_each_return_is_counted():
    clock = FakeClock(10.0)
    chain = LifecycleChain(NODES, heartbeat_timeout_s=0.5)
    nodes = Nodes(chain, clock)
    nodes.alive['controller'] = False         # started later: the chain waits for it
    nodes.run(10)
    assert not chain.up and chain.first_up_s is None and chain.ups == 0
    nodes.alive['controller'] = True
    nodes.run(10)
    assert chain.up and chain.ups == 1
    assert chain.first_up_s == pytest.approx(1.0 + 0.5)     # waited 1 s, then six transitions
    nodes.alive['bridge'] = False             # a death takes it down, a restart brings it up
    nodes.run(10)
    nodes.alive['bridge'] = True
    nodes.state['bridge'] = 'unconfigured'
    nodes.run(20)
    assert chain.up and chain.ups == 2 and chain.first_up_s == pytest.approx(1.5)
    assert [e[2] for e in chain.events].count('chain up') == 2


def test_a_dead_node_deactivates_the_chain_in_reverse_and_it_comes_back_up():
    clock = FakeClock(0.0)
    chain = LifecycleChain(NODES, heartbeat_timeout_s=0.5)
    nodes = Nodes(chain, clock)
    nodes.run()
    nodes.log.clear()
    nodes.alive['estimator'] = False          # killed
    nodes.run(10)
    assert nodes.log == [('controller', 'deactivate'), ('bridge', 'deactivate')]
    assert not chain.up and chain.counts['chain_deactivations'] == 1
    assert chain.counts['deaths'] == 1 and chain.state['estimator'] == 'unknown'
    nodes.log.clear()
    nodes.alive['estimator'] = True           # restarted: a fresh, unconfigured node
    nodes.state['estimator'] = 'unconfigured'
    nodes.run(10)
    assert nodes.log == [('estimator', 'configure'), ('bridge', 'activate'),
                         ('estimator', 'activate'), ('controller', 'activate')]
    assert chain.up and chain.counts['returns'] == 1


def test_nothing_is_activated_before_every_node_is_there():
    clock = FakeClock(0.0)
    chain = LifecycleChain(NODES)
    nodes = Nodes(chain, clock)
    nodes.alive['controller'] = False         # not started yet
    nodes.run(10)
    assert nodes.log == []                    # configure waits for the whole chain
    nodes.alive['controller'] = True
    nodes.run(10)
    assert chain.up


def test_a_refused_transition_is_retried_and_counted():
    clock = FakeClock(0.0)
    chain = LifecycleChain(NODES, retry_s=0.5)
    nodes = Nodes(chain, clock)
    nodes.refuse = {('bridge', 'configure')}  # the bus cannot be opened yet
    nodes.run(12)
    assert nodes.log.count(('bridge', 'configure')) >= 2
    assert not chain.up and chain.counts['failed'] >= 2
    nodes.refuse.clear()
    nodes.run(20)
    assert chain.up


def test_no_answer_times_out_and_shutdown_goes_down_in_reverse():
    clock = FakeClock(0.0)
    chain = LifecycleChain(NODES, service_timeout_s=0.3, retry_s=0.2)
    nodes = Nodes(chain, clock)
    nodes.mute = {'estimator'}               # alive, but its service does not answer
    nodes.run(20)
    assert chain.counts['failed'] >= 2 and chain.state['estimator'] == 'unconfigured'
    assert not chain.up
    nodes.mute.clear()
    nodes.run()
    assert chain.up
    nodes.log.clear()
    chain.shutdown()
    nodes.run()
    assert nodes.log == [(n, 'deactivate') for n in reversed(NODES)] + \
        [(n, 'cleanup') for n in reversed(NODES)]
    assert chain.status()['state'] == dict.fromkeys(NODES, 'unconfigured')
    with pytest.raises(ValueError):
        LifecycleChain(['a', 'a'])
