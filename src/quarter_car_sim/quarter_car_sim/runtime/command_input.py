"""
The simulated car's side of an external controller: the latest current command, checked and timed.

A car node run as the plant (``controller:=external``) applies the commands a controller node
sends: :class:`CommandInput` holds the latest, checks it with the rig's limiter and falls back
to the safe current when none came for ``timeout_s`` (ROS-free; the node converts messages).
"""
import math

from mr_damper_common.commands import CurrentCommandLimiter, OUTCOMES

#: Outcomes of a current command offered to :class:`CommandInput` (the limiter's).
COMMAND_OUTCOMES = OUTCOMES


class CommandInput:
    """
    The car side of an external controller: the latest current command, checked and timed.

    A command is checked by the rig's :class:`mr_damper_common.commands.CurrentCommandLimiter`
    (clamped into ``[i_min_a, i_max_a]``, non-finite refused, every outcome of
    :data:`COMMAND_OUTCOMES` counted). :meth:`current` returns the latest applied
    command while it is younger than ``timeout_s``, else the safe current (the transition is
    counted in :attr:`timeouts` and the time spent on the safe current in
    :attr:`timeout_s_total`).

    Parameters
    ----------
    timeout_s : float
        Longest a command is held [s, caller's clock] before the safe current applies.
    safe_current_a : float
        Coil current [A] without a fresh command.
    i_min_a, i_max_a : float
        Coil current range [A].

    """

    def __init__(self, timeout_s, safe_current_a, i_min_a=0.0, i_max_a=2.0):
        for name, value in (('timeout_s', timeout_s), ('safe_current_a', safe_current_a),
                            ('i_min_a', i_min_a), ('i_max_a', i_max_a)):
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f'`{name}` must be a finite number, got {value!r}')
        if not timeout_s > 0:
            raise ValueError(f'`timeout_s` must be > 0 s, got {timeout_s}')
        if not i_min_a < i_max_a:
            raise ValueError(f'`i_min_a` ({i_min_a}) must be below `i_max_a` ({i_max_a})')
        if not i_min_a <= safe_current_a <= i_max_a:
            raise ValueError(f'`safe_current_a` ({safe_current_a} A) must lie in '
                             f'[{i_min_a}, {i_max_a}] A')
        self.timeout_s = float(timeout_s)
        self.safe_current_a = float(safe_current_a)
        self.i_min_a, self.i_max_a = float(i_min_a), float(i_max_a)
        self.limiter = CurrentCommandLimiter(i_min_a, i_max_a)
        self.latest_a = None
        self.received_at = None
        self.n_received = 0
        self.timeouts = 0
        self.timeout_s_total = 0.0
        self.timed_out = True
        self._last_t = None

    def check_settings(self, timeout_s, safe_current_a):
        """Raise ValueError if :meth:`reconfigure` would refuse these settings."""
        CommandInput(timeout_s, safe_current_a, self.i_min_a, self.i_max_a)

    def reconfigure(self, *, timeout_s=None, safe_current_a=None):
        """
        Change the command timeout [s] and/or the safe current [A] while running.

        Validated as at construction; nothing changes on an invalid value (ValueError).
        """
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        safe_current_a = self.safe_current_a if safe_current_a is None else safe_current_a
        self.check_settings(timeout_s, safe_current_a)
        self.timeout_s = float(timeout_s)
        self.safe_current_a = float(safe_current_a)

    def offer(self, i_a, t_now):
        """
        Take one received command.

        Parameters
        ----------
        i_a : float
            Commanded coil current [A].
        t_now : float
            Receipt time [s] on the caller's clock.

        Returns
        -------
        str
            One of :data:`COMMAND_OUTCOMES` (also counted).

        """
        self.n_received += 1
        try:
            i_a = float(i_a)
        except (TypeError, ValueError):
            i_a = math.nan
        current, outcome = self.limiter.apply(i_a)
        if current is not None:
            self.latest_a = current
            self.received_at = float(t_now)
        return outcome

    def current(self, t_now):
        """
        Return the current [A] to apply at ``t_now`` (latest command, or safe when stale).

        Parameters
        ----------
        t_now : float
            Time [s] on the caller's clock; non-decreasing between calls.

        Returns
        -------
        float

        """
        t_now = float(t_now)
        fresh = self.received_at is not None and t_now - self.received_at <= self.timeout_s
        if self._last_t is not None and t_now > self._last_t and self.timed_out:
            self.timeout_s_total += t_now - self._last_t
        if not fresh and not self.timed_out:
            self.timeouts += 1
        self.timed_out = not fresh
        self._last_t = t_now if self._last_t is None else max(self._last_t, t_now)
        return self.latest_a if fresh else self.safe_current_a

    def status(self):
        """Return ``commands`` (outcome counts), ``commands_received``, timeout counters."""
        return {'commands': dict(self.limiter.counts), 'commands_received': self.n_received,
                'command_timeouts': self.timeouts, 'command_timed_out': self.timed_out,
                'command_timeout_s_total': self.timeout_s_total}
