"""
Respawn of dead nodes with a bounded back-off, without ROS (the launcher's supervisor).

:class:`Supervisor` decides, for each death of a node, whether to restart it and when: the
``n``-th death of a node within ``restart_window_s`` waits ``backoff_s * 2 ** (n - 1)``
(at most ``backoff_max_s``) before the restart; a node that dies more than ``max_restarts``
times within ``restart_window_s`` is given up (the run ends). Every restart is recorded
(:attr:`Supervisor.restarts`): node, time of the death and of the restart [s since the start,
and epoch seconds to find it in the recording], exit code or signal, back-off.

It holds no processes: the launcher tells it of deaths (:meth:`Supervisor.died`), asks which
restarts are due (:meth:`Supervisor.due`) and reports each restart done
(:meth:`Supervisor.restarted`). Times come from the caller, so tests drive it with a fake clock.
"""
from dataclasses import dataclass
import signal


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
        node's restarts so far, this one included).
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

    def died(self, node, code, now, epoch_s=None):
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

        Returns
        -------
        bool
            True: a restart is scheduled (see :meth:`due`). False: the node died more than
            ``max_restarts`` times within ``restart_window_s``; :attr:`gave_up` says which.

        """
        if node in self._pending:
            raise ValueError(f'{node} is already waiting for a restart')
        recent = [t for t in self._deaths.get(node, ()) if now - t <= self.policy.restart_window_s]
        recent.append(now)
        self._deaths[node] = recent
        exit_code, sig = describe_exit(code)
        if len(recent) > self.policy.max_restarts:
            self.gave_up = {'node': node, 'death_s': now - self.t0, 'exit_code': exit_code,
                            'signal': sig, 'deaths_in_window': len(recent),
                            'restart_window_s': self.policy.restart_window_s}
            return False
        backoff = self.policy.delay(len(recent))
        done = sum(1 for r in self.restarts if r['node'] == node)
        self.restarts.append({'node': node, 'death_s': now - self.t0, 'death_epoch_s': epoch_s,
                              'exit_code': exit_code, 'signal': sig, 'backoff_s': backoff,
                              'restart_s': None, 'restart_epoch_s': None, 'count': done + 1})
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
