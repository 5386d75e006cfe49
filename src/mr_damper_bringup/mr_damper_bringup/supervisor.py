"""
Respawn of dead and hung nodes with a bounded back-off, without ROS (the launcher's supervisor).

:class:`Supervisor` decides, for each death of a node, whether to restart it and when: the
``n``-th death of a node within ``restart_window_s`` waits ``backoff_s * 2 ** (n - 1)``
(at most ``backoff_max_s``) before the restart; a node that dies more than ``max_restarts``
times within ``restart_window_s`` is given up (the run ends). Every restart is recorded
(:attr:`Supervisor.restarts`): node, time of the death and of the restart [s since the start,
and epoch seconds to find it in the recording], exit code or signal, the reason (``died``, or
``hung`` for a node the launcher killed because its heartbeat stopped), back-off.

:class:`HangWatch` tells a hung node from a live one by its heartbeat (its ``/diagnostics``
status, about 1 Hz): a node whose heartbeat stopped for its timeout is hung. The watch of a node
is armed by its first heartbeat after each (re)start, so a node still starting up (imports, a
large replay file, a loaded machine) is never called hung; and silence is only counted while
the listener itself kept listening, so a stalled launcher does not read as hung nodes.

It holds no processes: the launcher tells it of deaths (:meth:`Supervisor.died`), asks which
restarts are due (:meth:`Supervisor.due`) and reports each restart done
(:meth:`Supervisor.restarted`). Times come from the caller, so tests drive it with a fake clock.
"""
from dataclasses import dataclass
import math
import signal

#: Why a node was restarted: it ``died`` by itself, or the launcher killed it as ``hung``.
REASONS = ('died', 'hung')
#: Default ``--hang-timeout-s`` [s]: a node's heartbeat silent this long while its process is idle
#: means frozen (15 periods of the 1 Hz status; a frozen node stays frozen, docs/faults.md).
HANG_TIMEOUT_S = 15.0
#: A silent node that used less than this share of one core meanwhile counts as idle (frozen or
#: stopped). A live node that is only behind on a loaded machine keeps working: at a load of 36
#: on 2 cores a runnable process still gets about 2/36 = 5.5 % of a core.
HANG_IDLE_SHARE = 0.02
#: A silent node that keeps using CPU is hung after this many timeouts (a livelock; 10 min with
#: the default timeout). A node only behind stays silent long on a loaded machine: at load 22-29
#: on 2 cores the recorder got 6.5 % of a core, less than its stream needs, and its status timer
#: waited behind its backlog for more than 120 s (docs/nodes.md, Launcher).
HANG_BUSY_FACTOR = 40.0
#: The heartbeat timeout is never shorter than this many periods of the node's own status.
HANG_PERIODS = 3.0


@dataclass(frozen=True)
class RestartPolicy:
    """
    How dead nodes are restarted.

    Parameters
    ----------
    max_restarts : int
        Restarts of one node allowed within ``restart_window_s``; the next death in that window
        ends the run (0: never restart).
    restart_window_s : float
        Window [s] over which a node's deaths are counted.
    backoff_s : float
        Wait [s] before the first restart; doubled for each further death within the window.
    backoff_max_s : float
        Longest wait [s].

    """

    max_restarts: int = 3
    restart_window_s: float = 60.0
    backoff_s: float = 0.5
    backoff_max_s: float = 8.0

    def __post_init__(self):
        if int(self.max_restarts) != self.max_restarts or self.max_restarts < 0:
            raise ValueError(f'`max_restarts` must be an integer >= 0, got {self.max_restarts}')
        for name in ('restart_window_s', 'backoff_s', 'backoff_max_s'):
            value = getattr(self, name)
            if not value >= 0:
                raise ValueError(f'`{name}` must be >= 0, got {value}')
        if self.backoff_max_s < self.backoff_s:
            raise ValueError(f'`backoff_max_s` ({self.backoff_max_s}) must be >= `backoff_s` '
                             f'({self.backoff_s})')

    def delay(self, n):
        """Return the wait [s] before the restart after the ``n``-th death in the window."""
        return min(self.backoff_s * 2.0 ** (max(int(n), 1) - 1), self.backoff_max_s)


def describe_exit(code):
    """
    Return ``(exit_code, signal_name)`` of a process return code.

    A negative code is a death by a signal (``subprocess``): ``(None, 'SIGKILL')``; otherwise
    ``(code, None)``.
    """
    if code is not None and code < 0:
        try:
            return None, signal.Signals(-code).name
        except ValueError:
            return None, f'signal {-code}'
    return code, None


class Supervisor:
    """
    Restart decisions for the nodes of one run.

    Parameters
    ----------
    policy : RestartPolicy
    t0 : float
        Start of the run on the caller's clock (``t_s`` of a record is counted from it).

    Attributes
    ----------
    restarts : list of dict
        One entry per death that led to a restart, in order: ``node``, ``death_s``,
        ``death_epoch_s``, ``exit_code``, ``signal``, ``backoff_s``, ``restart_s``,
        ``restart_epoch_s`` (the last two None until the restart is done), ``count`` (this
        node's restarts so far, this one included), ``reason`` (``died``: it exited by
        itself; ``hung``: killed for a stopped heartbeat, then also ``silent_s``, the
        heartbeat's silence when it was killed, and ``cpu_share``, the CPU share of one core its
        process used meanwhile, when known).
    gave_up : dict or None
        The death that ended the run: ``node``, ``death_s``, ``exit_code``, ``signal``,
        ``deaths_in_window``; None while every death could be restarted.

    """

    def __init__(self, policy, t0):
        self.policy = policy
        self.t0 = float(t0)
        self.restarts = []
        self.gave_up = None
        self._deaths = {}        # node -> times of its deaths (caller's clock) in the window
        self._pending = {}       # node -> (due time, index into restarts)

    def counts(self):
        """Return ``{node: restarts done}``."""
        out = {}
        for r in self.restarts:
            if r['restart_s'] is not None:
                out[r['node']] = out.get(r['node'], 0) + 1
        return out

    def pending(self, node):
        """Tell whether a restart of ``node`` is scheduled (it is dead, not given up)."""
        return node in self._pending

    def died(self, node, code, now, epoch_s=None, *, reason='died', silent_s=None,
             cpu_share=None, spin_cpu_share=None):
        """
        Record a death of ``node`` at ``now``; return True if it will be restarted.

        Parameters
        ----------
        node : str
            Node name.
        code : int
            Its return code (negative: killed by that signal).
        now : float
            Time of the death on the caller's clock [s].
        epoch_s : float, optional
            The same instant in epoch seconds (to find it in the recording).
        reason : {'died', 'hung'}
            ``hung``: the launcher killed it because its heartbeat stopped (counted like any
            death against ``max_restarts``).
        silent_s : float, optional
            For ``hung``: how long its heartbeat had been silent [s].
        cpu_share : float, optional
            For ``hung``: the CPU share of one core it used while silent.
        spin_cpu_share : float, optional
            For ``hung``: the same of its spin thread (the one that publishes its status).

        Returns
        -------
        bool
            True: a restart is scheduled (see :meth:`due`). False: the node died more than
            ``max_restarts`` times within ``restart_window_s``; :attr:`gave_up` says which.

        """
        if node in self._pending:
            raise ValueError(f'{node} is already waiting for a restart')
        if reason not in REASONS:
            raise ValueError(f'`reason` must be one of {REASONS}, got {reason!r}')
        recent = [t for t in self._deaths.get(node, ()) if now - t <= self.policy.restart_window_s]
        recent.append(now)
        self._deaths[node] = recent
        exit_code, sig = describe_exit(code)
        if len(recent) > self.policy.max_restarts:
            self.gave_up = {'node': node, 'death_s': now - self.t0, 'exit_code': exit_code,
                            'signal': sig, 'reason': reason, 'deaths_in_window': len(recent),
                            'restart_window_s': self.policy.restart_window_s}
            return False
        backoff = self.policy.delay(len(recent))
        done = sum(1 for r in self.restarts if r['node'] == node)
        record = {'node': node, 'death_s': now - self.t0, 'death_epoch_s': epoch_s,
                  'exit_code': exit_code, 'signal': sig, 'reason': reason, 'backoff_s': backoff,
                  'restart_s': None, 'restart_epoch_s': None, 'count': done + 1}
        if silent_s is not None:
            record['silent_s'] = float(silent_s)
        if cpu_share is not None:
            record['cpu_share'] = float(cpu_share)
        if spin_cpu_share is not None:
            record['spin_cpu_share'] = float(spin_cpu_share)
        self.restarts.append(record)
        self._pending[node] = (now + backoff, len(self.restarts) - 1)
        return True

    def due(self, now):
        """Return the nodes whose restart is due at ``now``, in the order of their deaths."""
        ready = [(k, n) for n, (t, k) in self._pending.items() if t <= now]
        return [n for _, n in sorted(ready)]

    def restarted(self, node, now, epoch_s=None):
        """Record that ``node`` was restarted at ``now``; return its restart record."""
        _, k = self._pending.pop(node)
        self.restarts[k].update(restart_s=now - self.t0, restart_epoch_s=epoch_s)
        return self.restarts[k]


def hang_timeout(timeout_s, period_s=None):
    """
    Return the heartbeat timeout [s] of a node: ``timeout_s``, or more for a slow status.

    Parameters
    ----------
    timeout_s : float
        The launcher's ``--hang-timeout-s`` (0: no hang watch; returns 0).
    period_s : float, optional
        The node's status period [s] (``diagnostics_period_s``): the timeout is at least
        :data:`HANG_PERIODS` of them, so a node configured for a slow status is not killed.

    """
    if not timeout_s > 0:
        return 0.0
    period = float(period_s) if period_s is not None and math.isfinite(float(period_s)) else 0.0
    return max(float(timeout_s), HANG_PERIODS * max(period, 0.0))


class HangWatch:
    """
    Which nodes are hung: their heartbeat stopped, and they are idle or stopped for very long.

    Feed it the heartbeats (:meth:`beat`), the listener's own progress (:meth:`listening`) and
    the CPU time of the node processes (:meth:`cpu`) with times of one clock [s]; :meth:`hung`
    returns the nodes to kill. A node is hung when its heartbeat has been silent

    - longer than its timeout while its process, or its spin thread (the thread whose
      executor publishes its status: the main thread of every node of the suite), used less
      than ``idle_share`` of one core (frozen: a deadlock in the middleware leaves every thread
      in a futex wait at 0 % CPU; a stopped process uses none; a spin thread starved by one of
      the process's own threads spinning at a real-time priority, as the vehicle computer's
      executor once was by Fast DDS's writer thread, runs not at all while the process burns a
      core), or
    - longer than ``busy_factor`` times its timeout whatever its CPU (a livelock, a callback
      that never returns).

    A node that is only behind (a loaded machine: its status timer waits behind thousands of
    messages while it works through them) uses CPU in its spin thread, and is given the longer
    limit. A node is watched from its first heartbeat after :meth:`started` (never during its
    start-up);
    :meth:`forget` stops watching it (it died, finished or is being stopped). Silence is counted
    only over the time the listener was listening without a break: a listener that stalled (a
    loaded machine, the launcher stopped and continued) starts a new stretch when it comes
    back, so the heartbeats still queued for it cannot read as missing.

    Parameters
    ----------
    timeouts : dict
        Node -> heartbeat timeout [s] (:func:`hang_timeout`); a node with 0 (or not listed)
        is never called hung.
    gap_s : float
        A pause between two :meth:`listening` calls longer than this [s] breaks the
        listener's stretch.
    idle_share : float
        CPU share of one core below which a silent node counts as idle (frozen).
    busy_factor : float
        A silent node that keeps using CPU is hung after this many timeouts.

    """

    def __init__(self, timeouts, gap_s=1.0, idle_share=HANG_IDLE_SHARE,
                 busy_factor=HANG_BUSY_FACTOR):
        self.timeouts = {n: float(t) for n, t in dict(timeouts).items()}
        if any(not t >= 0 for t in self.timeouts.values()):
            raise ValueError(f'`timeouts` must be >= 0, got {self.timeouts}')
        for name, value, low in (('gap_s', gap_s, 0.0), ('idle_share', idle_share, 0.0),
                                 ('busy_factor', busy_factor, 1.0)):
            if not value > low:
                raise ValueError(f'`{name}` must be > {low:g}, got {value}')
        self.gap_s = float(gap_s)
        self.idle_share = float(idle_share)
        self.busy_factor = float(busy_factor)
        self._started = {}      # node -> time of its (re)start (not armed yet)
        self._last = {}         # node -> time of its last heartbeat (armed)
        self._cpu = {}          # node -> (time, CPU seconds, spin thread's) latest sample
        self._cpu_mark = {}     # node -> the same of the first sample after its last beat
        self._since = None      # start of the listener's current stretch
        self._heard = None      # the listener's latest progress

    def started(self, node, now):
        """Node ``node`` was (re)started at ``now``: watch it from its next heartbeat."""
        self._started[node] = float(now)
        for d in (self._last, self._cpu, self._cpu_mark):
            d.pop(node, None)

    def forget(self, node):
        """Stop watching ``node`` (dead, finished, stopping)."""
        for d in (self._started, self._last, self._cpu, self._cpu_mark):
            d.pop(node, None)

    def beat(self, node, t):
        """
        Record a heartbeat of ``node`` received at ``t``.

        A heartbeat from before the node's latest start (its previous process) is ignored; the
        first one after it arms the watch.
        """
        t = float(t)
        if node in self._started:
            if t < self._started[node]:
                return
            del self._started[node]
        elif node not in self._last or t <= self._last[node]:
            return
        self._last[node] = t
        self._cpu_mark.pop(node, None)      # CPU is counted from the next sample on

    def cpu(self, node, t, seconds, spin_seconds=None):
        """
        Record the CPU times (user + system) [s] of the process of ``node`` at ``t``.

        ``seconds`` of the whole process, ``spin_seconds`` of its spin thread (None: unknown,
        then the process's alone decides).
        """
        sample = (float(t), float(seconds),
                  None if spin_seconds is None else float(spin_seconds))
        self._cpu[node] = sample
        if node in self._last and node not in self._cpu_mark:
            self._cpu_mark[node] = sample

    def listening(self, t):
        """Record that the listener of the heartbeats was working at ``t``."""
        t = float(t)
        if self._heard is None or t - self._heard > self.gap_s:
            self._since = t                 # (re)started listening: a new stretch
        self._heard = t if self._heard is None else max(self._heard, t)

    def armed(self, node):
        """Tell whether ``node`` is watched (it sent a heartbeat since its last start)."""
        return node in self._last

    def silence(self, node):
        """Return how long ``node`` has been heard silent [s] (None when not armed)."""
        if node not in self._last or self._heard is None:
            return None
        return max(self._heard - max(self._last[node], self._since), 0.0)

    def busy(self, node, spin=False):
        """
        Return the CPU share of one core ``node`` used since its last heartbeat (None: unknown).

        Its process's, or with ``spin`` its spin thread's. Measured between the first CPU
        sample after the heartbeat and the latest one (known from the second sample on), so
        work done before the heartbeat is never counted.
        """
        if node not in self._cpu_mark or node not in self._cpu:
            return None
        t, *now = self._cpu[node]
        t0, *then = self._cpu_mark[node]
        k = 1 if spin else 0
        if not t > t0 or now[k] is None or then[k] is None:
            return None
        return (now[k] - then[k]) / (t - t0)

    def hung(self):
        """
        Return ``[(node, silent_s, cpu_share, spin_cpu_share)]`` of the hung nodes, in order.

        ``cpu_share`` and ``spin_cpu_share`` are the CPU use of the node's process and of its
        spin thread during its silence (None: unknown; without either, the timeout alone
        decides).
        """
        out = []
        for node in self._last:
            timeout = self.timeouts.get(node, 0.0)
            silent = self.silence(node)
            if not timeout > 0 or silent is None or not silent > timeout:
                continue
            share, spin = self.busy(node), self.busy(node, spin=True)
            idle = [x < self.idle_share for x in (share, spin) if x is not None]
            if not idle or any(idle) or silent > self.busy_factor * timeout:
                out.append((node, silent, share, spin))
        return out
