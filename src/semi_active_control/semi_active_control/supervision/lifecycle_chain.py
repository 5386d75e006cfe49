"""
The order of a chain of managed (lifecycle) nodes, as nav2's lifecycle manager keeps it (no ROS).

:class:`LifecycleChain` decides, one request at a time, which transition of which node comes
next: ``configure`` every node in the chain's order, then ``activate`` every node in that order
(the vehicle: bridge, estimator, controller, so the controller starts commanding only when the
whole chain is there). Each node is watched through a heartbeat that carries its lifecycle
state: a node whose heartbeat stops for ``heartbeat_timeout_s`` is dead (not while a
transition it was asked for runs: the node's executor is busy with it, up to
``service_timeout_s``), and a dead node
deactivates the chain: every active node left is deactivated in the reverse order (the
controller first: its deactivation puts every corner on the safe current; the bridge last: it
then sends the safe current itself). When the node is back (restarted: its heartbeat says
``unconfigured``) the chain comes up again by the same rules. :meth:`shutdown` takes the chain
down (deactivate, then clean up, in reverse order).

A transition the node refuses or that gets no answer within ``service_timeout_s`` is counted and
tried again after ``retry_s``. The caller sends each request (a ``ChangeState`` service call)
and reports its outcome with :meth:`result`; heartbeats go to :meth:`heartbeat`. Times are
the caller's clock [s].
"""
from collections import deque

#: Primary lifecycle states (``lifecycle_msgs/State`` labels).
PRIMARY = ('unconfigured', 'inactive', 'active', 'finalized')
#: The state each transition leads to when it succeeds.
TARGET = {'configure': 'inactive', 'activate': 'active', 'deactivate': 'inactive',
          'cleanup': 'unconfigured', 'shutdown': 'finalized'}


class LifecycleChain:
    """
    Bring a chain of managed nodes up in order, down in reverse; a dead node deactivates it.

    Parameters
    ----------
    nodes : sequence of str
        Node names in the chain's order (first up, last down).
    heartbeat_timeout_s : float
        A node without a heartbeat for this long is dead [s].
    service_timeout_s : float
        A transition request without an answer for this long has failed [s].
    retry_s : float
        Wait before trying a failed transition again [s].

    Attributes
    ----------
    state : dict
        Node -> its lifecycle state as last known (``unknown`` before its first heartbeat and
        while dead).
    counts : dict
        ``transitions``, ``failed``, ``deaths``, ``chain_deactivations``, ``returns``.
    events : deque
        The last events ``(t, node, what)``.
    first_up_s : float or None
        Time [s] from the chain's first input (a heartbeat or a request asked for) to the
        first time every node was alive and active (None: not yet): the start-up.
    ups : int
        Times the chain came up (every node alive and active after one was not).

    """

    def __init__(self, nodes, *, heartbeat_timeout_s=1.0, service_timeout_s=2.0, retry_s=1.0):
        self.nodes = tuple(nodes)
        if not self.nodes or len(set(self.nodes)) != len(self.nodes):
            raise ValueError(f'`nodes` must be distinct names, got {nodes!r}')
        for name, value in (('heartbeat_timeout_s', heartbeat_timeout_s),
                            ('service_timeout_s', service_timeout_s), ('retry_s', retry_s)):
            if not value > 0:
                raise ValueError(f'`{name}` must be > 0, got {value}')
        self.heartbeat_timeout_s = float(heartbeat_timeout_s)
        self.service_timeout_s = float(service_timeout_s)
        self.retry_s = float(retry_s)
        self.state = dict.fromkeys(self.nodes, 'unknown')
        self.seen = dict.fromkeys(self.nodes, None)
        self.alive = dict.fromkeys(self.nodes, False)
        self.goal = 'active'
        self.pending = None               # (node, transition, t_sent)
        self._retry_at = {}
        self.counts = {'transitions': 0, 'failed': 0, 'deaths': 0, 'chain_deactivations': 0,
                       'returns': 0}
        self._deactivating = False
        self.events = deque(maxlen=50)
        self.t_start = None
        self.first_up_s = None
        self.ups = 0
        self._was_up = False

    # --- inputs -------------------------------------------------------------------------------
    def heartbeat(self, node, label, t):
        """Take a node's heartbeat: its lifecycle state ``label`` at time ``t`` [s]."""
        if node not in self.state:
            return
        self._started(t)
        self.seen[node] = float(t)
        if not self.alive[node]:
            self.alive[node] = True
            if self.state[node] != 'unknown' or self.counts['deaths']:
                self.counts['returns'] += 1
                self.events.append((t, node, f'back ({label})'))
        if self.pending is None or self.pending[0] != node:
            self.state[node] = str(label)
        self._track_up(t)

    def result(self, node, transition, ok, t):
        """Take the outcome of the pending request (True: the node made the transition)."""
        if self.pending is None or self.pending[:2] != (node, transition):
            return
        self.pending = None
        if ok:
            self.state[node] = TARGET[transition]
            self.counts['transitions'] += 1
            self.events.append((t, node, transition))
        else:
            self.counts['failed'] += 1
            self._retry_at[(node, transition)] = float(t) + self.retry_s
            self.events.append((t, node, f'{transition} refused'))
        self._track_up(t)

    def shutdown(self):
        """Take the chain down from now on (deactivate, then clean up, in reverse order)."""
        self.goal = 'down'

    def watch(self):
        """Only watch from now on: no transition is asked for (deaths are still counted)."""
        self.goal = 'watch'

    def _started(self, t):
        if self.t_start is None:
            self.t_start = float(t)

    def _track_up(self, t):
        """Count the chain coming up; the first time, its start-up time."""
        up = self.up
        if up and not self._was_up:
            self.ups += 1
            if self.first_up_s is None:
                self.first_up_s = float(t) - self.t_start
            self.events.append((t, None, 'chain up'))
        self._was_up = up

    # --- decisions ------------------------------------------------------------------------------
    def _check_alive(self, t):
        busy = self.pending[0] if self.pending is not None else None
        for n in self.nodes:
            seen = self.seen[n]
            if n == busy:
                continue        # a transition runs in the node's executor: no heartbeat then
            if self.alive[n] and (seen is None or t - seen > self.heartbeat_timeout_s):
                self.alive[n] = False
                self.state[n] = 'unknown'
                self.counts['deaths'] += 1
                self.events.append((t, n, 'dead'))
                if self.pending is not None and self.pending[0] == n:
                    self.pending = None
                if any(self.state[m] == 'active' for m in self.nodes):
                    self.counts['chain_deactivations'] += 1
                    self.events.append((t, n, 'chain deactivated'))

    def next_request(self, t):
        """
        Return the next transition to request now, ``(node, transition)``, or None.

        One request at a time: while one is pending (until :meth:`result`, a death of its
        node, or ``service_timeout_s``) nothing else is asked.
        """
        t = float(t)
        self._started(t)
        self._check_alive(t)
        self._track_up(t)
        if self.pending is not None:
            node, transition, sent = self.pending
            if t - sent <= self.service_timeout_s:
                return None
            self.result(node, transition, False, t)
        want = self._plan()
        if want is None:
            return None
        if t < self._retry_at.get(want, -float('inf')):
            return None
        self.pending = (want[0], want[1], t)
        return want

    def _plan(self):
        state, alive = self.state, self.alive
        if self.goal == 'watch':
            return None
        if self.goal == 'down':
            for n in reversed(self.nodes):
                if alive[n] and state[n] == 'active':
                    return n, 'deactivate'
            for n in reversed(self.nodes):
                if alive[n] and state[n] == 'inactive':
                    return n, 'cleanup'
            return None
        if not all(alive.values()):
            # a node is dead (or not there yet): nothing may be active
            for n in reversed(self.nodes):
                if alive[n] and state[n] == 'active':
                    return n, 'deactivate'
            return None
        for n in self.nodes:
            if state[n] == 'unconfigured':
                return n, 'configure'
        if not all(state[n] in ('inactive', 'active') for n in self.nodes):
            return None                # a node in a transition state: wait for its heartbeat
        for n in self.nodes:
            if state[n] == 'inactive':
                return n, 'activate'
        return None

    @property
    def up(self):
        """True while every node is alive and active."""
        return all(self.alive[n] and self.state[n] == 'active' for n in self.nodes)

    def status(self, t=None):
        """Summarise the chain: state of each node, pending request, counts (JSON-ready)."""
        return {'up': self.up, 'goal': self.goal, 'nodes': list(self.nodes),
                'state': dict(self.state), 'alive': dict(self.alive),
                'heartbeat_age_s': {n: (t - s if t is not None and s is not None else None)
                                    for n, s in self.seen.items()},
                'pending': list(self.pending[:2]) if self.pending else None,
                'counts': dict(self.counts), 'first_up_s': self.first_up_s, 'ups': self.ups,
                'events': [list(e) for e in self.events][-10:]}
