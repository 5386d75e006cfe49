"""
The simulated car's side of an external controller: the latest current command, checked and timed.

A car node run as the plant (``controller:=external``) applies the commands a controller node
sends: :class:`CommandInput` holds the latest, checks it with the rig's limiter and falls back
to the safe current when none came for ``timeout_s`` (ROS-free; the node converts messages).
:class:`VehicleCommandInput` is the full car's: one vehicle controller command per cycle for
its four dampers.
"""
import math

from mr_damper_common.commands import CurrentCommandLimiter, OUTCOMES
from mr_damper_common.sequence import SequenceTracker

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


#: Modes of a corner in a vehicle controller's command (``FullCarCommand.MODE_*``).
COMMAND_MODE_NAMES = {0: 'normal', 1: 'failsafe', 2: 'inactive'}


class VehicleCommandInput:
    """
    The simulated full car's side of a vehicle controller: one command per cycle, four dampers.

    Each command (``FullCarCommand``: its number, the state cycle it answers, four currents and
    per corner the controller's mode and reason) goes to four :class:`CommandInput` (checked,
    held for ``timeout_s``, then the safe current, counted). A command older than the newest
    taken (its number) is not used, a gap in the numbers is counted as commands lost
    (:class:`~mr_damper_common.sequence.SequenceTracker`). A corner is ``normal`` while its
    latest command is fresh and the controller had it on the law; its first such step is
    recorded on the car's time (``first_normal_t_sim``).

    Parameters
    ----------
    timeout_s, safe_current_a, i_min_a, i_max_a : float
        As :class:`CommandInput` [s, A].
    corners : sequence of str
        Corner names (``fl, fr, rl, rr``).

    Attributes
    ----------
    answered_sequence : int
        The newest state cycle a command answered (0: none yet); lock-step waits on it.

    """

    def __init__(self, timeout_s, safe_current_a, i_min_a=0.0, i_max_a=2.0,
                 corners=('fl', 'fr', 'rl', 'rr')):
        self.corners = tuple(corners)
        self.inputs = [CommandInput(timeout_s, safe_current_a, i_min_a, i_max_a)
                       for _ in self.corners]
        self.sequence = SequenceTracker()
        n = len(self.corners)
        self.modes = ['none'] * n
        self.reasons = ['no_command_yet'] * n
        self.first_normal_t_sim = [math.nan] * n
        self.normal_steps = [0] * n
        self.failsafe_s = [0.0] * n
        self._off = [True] * n
        self._last_t_sim = None
        self.answered_sequence = 0
        self.commands = 0

    def offer(self, sequence, state_sequence, currents_a, modes, reasons, t_now):
        """
        Take one command; return the outcome per corner (None: an old command, not used).

        Parameters
        ----------
        sequence, state_sequence : int
            The command's number and the state cycle it answers.
        currents_a : sequence of float
            Coil currents [A], one per corner.
        modes : sequence of int
            The controller's mode per corner (:data:`COMMAND_MODE_NAMES`).
        reasons : sequence of str
            The controller's reason per corner.
        t_now : float
            Receipt time [s, the caller's clock].

        """
        if self.sequence.offer(sequence) < 0:
            return None
        self.commands += 1
        outcomes = [ci.offer(i_a, t_now) for ci, i_a in zip(self.inputs, currents_a)]
        for j, (mode, reason) in enumerate(zip(modes, reasons)):
            self.modes[j] = COMMAND_MODE_NAMES.get(int(mode), 'failsafe')
            self.reasons[j] = str(reason)
        self.answered_sequence = max(self.answered_sequence, int(state_sequence))
        return outcomes

    def currents(self, t_now, t_sim):
        """
        Return the four currents to apply at ``t_now`` [A] (the latest, or safe when stale).

        ``t_sim`` is the car's time of the step [s]: a corner's first normal step, and the
        car time [s] a corner spends off the law (``failsafe_s``: each interval since the
        previous call counted by the corner's mode over it, the currents being held).
        """
        out = [ci.current(t_now) for ci in self.inputs]
        t_sim = float(t_sim)
        held = 0.0 if self._last_t_sim is None else max(t_sim - self._last_t_sim, 0.0)
        self._last_t_sim = t_sim
        for j in range(len(out)):
            if self._off[j]:                    # the corner's state since the previous call
                self.failsafe_s[j] += held
            self._off[j] = self.mode_reason(j)[0] != 'normal'
            if not self._off[j]:
                self.normal_steps[j] += 1
                if math.isnan(self.first_normal_t_sim[j]):
                    self.first_normal_t_sim[j] = t_sim
        return out

    def mode_reason(self, j):
        """Return corner ``j``'s ``(mode, reason)`` at the last :meth:`currents`."""
        ci = self.inputs[j]
        if ci.timed_out:
            return 'failsafe', 'no_command_yet' if ci.received_at is None else 'command_timeout'
        if self.modes[j] != 'normal':
            return 'failsafe', self.reasons[j]
        return 'normal', 'ok'

    def status(self):
        """Return per corner the input's counters, mode, reason, first normal step (JSON-ready)."""
        corners = {}
        for j, c in enumerate(self.corners):
            mode, reason = self.mode_reason(j)
            corners[c] = dict(self.inputs[j].status(), mode=mode, reason=reason,
                              controller_mode=self.modes[j],
                              normal_steps=self.normal_steps[j],
                              failsafe_s=self.failsafe_s[j],
                              first_normal_t_sim=self.first_normal_t_sim[j])
        return {'commands': self.commands, 'command_sequence': self.sequence.status(),
                'answered_sequence': self.answered_sequence, 'corners': corners}
