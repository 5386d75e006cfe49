"""
Deadline supervision of a periodic control loop (a watchdog), without ROS.

Every control cycle starts when its sensor data is taken (the cycle's *release*) and must be
answered within its deadline (by default one cycle period). :class:`DeadlineMonitor` counts
the cycles, the misses and how late each miss was (as ros2_control's controller manager
reports its overruns: count, last, largest, mean, percentiles of the lateness), and turns two
conditions into a named fail-safe reason that the controller commands the safe current for:

- ``deadline_misses``: ``max_consecutive_misses`` cycles in a row answered late; cleared after
  ``recover_cycles`` cycles in a row on time;
- ``sensor_timeout``: no input for ``input_timeout_s`` (checked by :meth:`check` on a timer);
  cleared by the next input.

Both recover by themselves; each entry is counted (``entries``) and the time spent in each
(``failsafe_s``) is summed. Times are the caller's clock [s] (tests pass a fake one).
"""
import math

from mr_damper_common.latency import LatencyHistogram

#: Reasons the monitor gives for the safe current, in order of precedence.
REASONS = ('sensor_timeout', 'deadline_misses')

#: Default cycles in a row on time that end ``deadline_misses`` (20 ms at the vehicle's 2 ms):
#: a debounce, as AUTOSAR E2E's state machine takes a few valid messages back to valid, not a
#: penalty. With 50 every trip held the safe current for at least 100 ms after the loop was
#: back on time: on this project's 2-core VM 100-140 ms per trip against 21-28 ms with 10
#: (bench_vehicle, 30 Nov 2026: 6 and 18 trips, 0.62 and 2.48 s; 10 and 4 trips, 0.21 and
#: 0.11 s).
RECOVER_CYCLES = 10


class DeadlineMonitor:
    """
    Deadlines, misses and lateness of a periodic loop; fail-safe reasons (module docstring).

    Parameters
    ----------
    period_s : float
        Control period [s].
    deadline_s : float, optional
        Time from a cycle's release to its answer that is on time [s] (default ``period_s``).
    max_consecutive_misses : int
        Misses in a row that put the loop on the safe current (``deadline_misses``).
    recover_cycles : int
        Cycles in a row on time that clear ``deadline_misses``.
    input_timeout_s : float
        No input for this long: ``sensor_timeout`` [s].

    Attributes
    ----------
    cycles, misses, consecutive : int
        Cycles answered, of them late, and the current run of late ones.
    lateness : LatencyHistogram
        Lateness of the misses [s] (answer time minus deadline).
    response : LatencyHistogram
        Release to answer of every cycle [s].
    entries : dict
        Fail-safe entries per reason.
    failsafe_s : dict
        Time spent in each reason [s].

    """

    def __init__(self, period_s, *, deadline_s=None, max_consecutive_misses=5,
                 recover_cycles=RECOVER_CYCLES, input_timeout_s=0.02):
        for name, value in (('period_s', period_s), ('input_timeout_s', input_timeout_s)):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be > 0, got {value}')
        if max_consecutive_misses < 1 or recover_cycles < 1:
            raise ValueError('`max_consecutive_misses` and `recover_cycles` must be >= 1')
        self.period_s = float(period_s)
        self.deadline_s = self.period_s if deadline_s is None else float(deadline_s)
        if not self.deadline_s > 0:
            raise ValueError(f'`deadline_s` must be > 0, got {deadline_s}')
        self.max_consecutive_misses = int(max_consecutive_misses)
        self.recover_cycles = int(recover_cycles)
        self.input_timeout_s = float(input_timeout_s)
        self.lateness = LatencyHistogram()
        self.response = LatencyHistogram()
        self.cycles = 0
        self.misses = 0
        self.last_lateness_s = math.nan
        self.entries = dict.fromkeys(REASONS, 0)
        self.failsafe_s = dict.fromkeys(REASONS, 0.0)
        self._active = {r: None for r in REASONS}      # reason -> since when [s]
        self.reset()

    def reset(self, t_now=None):
        """
        Forget the inputs and the run of misses (a new activation); the counts stay.

        A reason still active ends at ``t_now`` [s] (its time is counted up to then).
        """
        for r, since in self._active.items():
            if since is not None:
                self._set(r, False, since if t_now is None else t_now)
        self.consecutive = 0
        self._on_time_run = 0
        self._last_input = None

    def input(self, t_now):
        """Note that sensor data came at ``t_now`` [s]; clears ``sensor_timeout``."""
        self._last_input = float(t_now)
        self._set('sensor_timeout', False, t_now)

    def past(self, t_release, t_now):
        """Whether a cycle released at ``t_release`` is past its deadline at ``t_now`` [s]."""
        return float(t_now) - float(t_release) > self.deadline_s

    def cycle(self, t_release, t_done):
        """
        Count one answered cycle: released at ``t_release``, answered at ``t_done`` [s].

        Returns
        -------
        bool
            True when it was on time.

        """
        self.cycles += 1
        response = float(t_done) - float(t_release)
        self.response.add(response)
        late = response - self.deadline_s
        if late > 0:
            self.misses += 1
            self.consecutive += 1
            self._on_time_run = 0
            self.last_lateness_s = late
            self.lateness.add(late)
            if self.consecutive >= self.max_consecutive_misses:
                self._set('deadline_misses', True, t_done)
            return False
        self.consecutive = 0
        self._on_time_run += 1
        if self._on_time_run >= self.recover_cycles:
            self._set('deadline_misses', False, t_done)
        return True

    def check(self, t_now):
        """
        Check the input timeout at ``t_now`` [s]; return the fail-safe reason or None.

        Before the first input the timeout counts from the first call.
        """
        if self._last_input is None:
            self._last_input = float(t_now)
        self._set('sensor_timeout', t_now - self._last_input > self.input_timeout_s, t_now)
        return self.reason

    @property
    def reason(self):
        """The reason for the safe current (:data:`REASONS`, first wins) or None."""
        for r in REASONS:
            if self._active[r] is not None:
                return r
        return None

    def _set(self, reason, on, t_now):
        since = self._active[reason]
        if on and since is None:
            self._active[reason] = float(t_now)
            self.entries[reason] += 1
        elif not on and since is not None:
            self.failsafe_s[reason] += max(float(t_now) - since, 0.0)
            self._active[reason] = None

    def status(self, t_now=None):
        """
        Return the counts and the lateness statistics (``/diagnostics`` values).

        Returns
        -------
        dict
            ``cycles``, ``deadline_misses``, ``consecutive_misses``, ``miss_fraction``,
            ``lateness`` (``last_s`` and the :class:`LatencyHistogram` summary of the misses),
            ``response`` (release to answer of every cycle), ``reason``, ``entries``,
            ``failsafe_s`` (up to ``t_now`` for a reason still active), ``period_s``,
            ``deadline_s``.

        """
        spent = dict(self.failsafe_s)
        if t_now is not None:
            for r, since in self._active.items():
                if since is not None:
                    spent[r] += max(float(t_now) - since, 0.0)
        return {'cycles': self.cycles, 'deadline_misses': self.misses,
                'consecutive_misses': self.consecutive,
                'miss_fraction': self.misses / self.cycles if self.cycles else 0.0,
                'lateness': dict(self.lateness.summary(), last_s=self.last_lateness_s),
                'response': self.response.summary(), 'reason': self.reason or '',
                'entries': dict(self.entries), 'failsafe_s': spent,
                'period_s': self.period_s, 'deadline_s': self.deadline_s}
