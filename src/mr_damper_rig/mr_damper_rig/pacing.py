"""
Publishing schedule of the rig node: which samples are due when (no ROS).

:class:`Pacer` (free-running rig and replays) answers, at every timer tick, how many samples
the node should publish now:

- before the start it waits until ``wait_for_subscribers`` readers matched (and, with
  ``rate_factor`` 0, until the consumer reported its first count), at most ``start_timeout_s``;
- with ``rate_factor`` > 0 the samples due are those whose record time is at most the wall time
  since the start times ``rate_factor`` (``source.count_due``), so the effective rate is exact
  even though the node's timer is not; ``rate_factor`` can change while running (the record
  time reached so far is kept);
- with ``rate_factor`` 0 it keeps at most ``flow_window`` samples ahead of the count of samples
  the consumer reports having received (``on_flow``; the identifier publishes it on
  ``mr_damper/samples_received``). A count that goes down is a restarted consumer: pacing
  continues against its new count (``flow_restarts``). Without any count yet: one sample per
  tick;
- a finite source ends when all its samples went out (``finished``).

:class:`LockstepPacer` (hardware in the loop, ``excitation:=commanded``): the rig publishes one
sample per command; when the commander falls silent for longer than ``timeout_s`` of rig time
(wall time times ``rate_factor``), the samples due on the rig's own clock since the last
command are published (the command guard holds, then returns to neutral).

Both take the clock as an argument (``clock()`` -> seconds, monotonic): the node passes
``time.monotonic`` because the rig is the clock source of a replay (its pacing stays on wall
time even when other nodes run on the ``/clock`` it publishes); the tests pass a fake clock.
"""
import math
import time

#: Most samples published in one tick (a stalled node catches up in bounded bursts).
MAX_BATCH = 5000


def _check_rate_factor(rate_factor):
    rate_factor = float(rate_factor)
    if not (math.isfinite(rate_factor) and rate_factor >= 0):
        raise ValueError(f'`rate_factor` must be a finite number >= 0, got {rate_factor}')
    return rate_factor


def _check_window(flow_window):
    if isinstance(flow_window, bool) or int(flow_window) != flow_window or flow_window < 1:
        raise ValueError(f'`flow_window` must be an integer >= 1, got {flow_window}')
    return int(flow_window)


class Pacer:
    """
    Samples due at each tick of a free-running rig or replay.

    Parameters
    ----------
    source : object
        ``count_due(record_s)`` -> samples due after ``record_s`` seconds of record time and
        ``total()`` -> number of samples or None (endless); e.g.
        :class:`mr_damper_rig.replay.ArraySource`, :class:`mr_damper_rig.replay.SimSource`.
    rate_factor : float
        Speed relative to real time (> 0), or 0: as fast as the consumer takes the samples.
    clock : callable
        ``clock()`` -> wall time [s], monotonic.
    wait_for_subscribers : int
        Readers to wait for before the first sample.
    flow_window : int
        ``rate_factor`` 0: samples allowed ahead of the consumer's count.
    start_timeout_s : float
        Longest wait for the readers (and the consumer's first count) [s]; then it starts.
    max_batch : int
        Most samples due in one tick.

    Attributes
    ----------
    published : int
        Samples published (the node reports each with :meth:`sent`).
    behind_max : int
        Largest number of samples due but not yet published at a tick (``rate_factor`` > 0).
    flow_restarts : int
        Consumer restarts seen (its count went down).
    flow_received : int or None
        The consumer's latest count.

    """

    def __init__(self, source, rate_factor=1.0, *, clock=time.monotonic, wait_for_subscribers=0,
                 flow_window=1000, start_timeout_s=30.0, max_batch=MAX_BATCH):
        self.source = source
        self._clock = clock
        self._rate = _check_rate_factor(rate_factor)
        self.flow_window = _check_window(flow_window)
        self.wait_for_subscribers = int(wait_for_subscribers)
        self.start_timeout_s = float(start_timeout_s)
        self.max_batch = int(max_batch)
        self.created_s = clock()
        self.start_s = None
        self.end_s = None
        self._record_base_s = 0.0   # record time reached at _wall_base_s
        self._wall_base_s = None
        self.published = 0
        self.behind_max = 0
        self.flow_received = None
        self.flow_restarts = 0
        self._flow_base = None

    @property
    def rate_factor(self):
        """Speed relative to real time (0: flow control)."""
        return self._rate

    def set_rate_factor(self, rate_factor):
        """
        Change the speed while running (both values > 0); the record time reached is kept.

        Raises
        ------
        ValueError
            Not a finite number > 0, or the pacer runs under flow control (``rate_factor`` 0):
            switching between timed and flow-controlled pacing needs a restart.

        """
        rate_factor = _check_rate_factor(rate_factor)
        if rate_factor == 0 or self._rate == 0:
            raise ValueError('`rate_factor` cannot change to or from 0 while running '
                             '(flow control is chosen at start-up)')
        if self._wall_base_s is not None:
            now = self._clock()
            self._record_base_s = self.record_time_s(now)
            self._wall_base_s = now
        self._rate = rate_factor

    def set_flow_window(self, flow_window):
        """Change the flow window (integer >= 1) while running."""
        self.flow_window = _check_window(flow_window)

    @property
    def started(self):
        """True once the first sample was due."""
        return self.start_s is not None

    @property
    def finished(self):
        """True when a finite source has published all its samples."""
        total = self.source.total()
        return total is not None and self.published >= total

    def record_time_s(self, now=None):
        """Record time [s] reached at wall time ``now`` (``rate_factor`` > 0; 0 before start)."""
        if self._wall_base_s is None:
            return 0.0
        now = self._clock() if now is None else now
        return self._record_base_s + (now - self._wall_base_s) * self._rate

    def waiting(self, subscribers):
        """
        Return True while the rig waits to start; start (return False) once it may.

        Parameters
        ----------
        subscribers : int
            Readers matched by the measurement writer now.

        """
        if self.started:
            return False
        now = self._clock()
        patient = now - self.created_s < self.start_timeout_s
        if patient and subscribers < self.wait_for_subscribers:
            return True
        if patient and self._rate == 0 and self._flow_base is None:
            return True   # the consumer's first count is the base of the flow control
        self.start_s = self._wall_base_s = now
        return False

    def on_flow(self, received):
        """
        Take the consumer's count of samples received.

        Parameters
        ----------
        received : int
            Samples the consumer received so far (counts up; a lower count is a restart).

        """
        received = int(received)
        if self.flow_received is not None and received < self.flow_received \
                and self._flow_base is not None:
            # the consumer restarted (its count began again): pace against the new count
            self._flow_base = received - self.published
            self.flow_restarts += 1
        elif self._flow_base is None:
            # first count: before the start, the consumer has none of ours; after a start
            # without a count (timeout), assume it has what was published
            self._flow_base = received - (self.published if self.started else 0)
        self.flow_received = received

    def due(self):
        """
        Return how many samples to publish now (0 before the start or after the end).

        With ``rate_factor`` > 0 this also updates :attr:`behind_max`.
        """
        if not self.started or self.finished:
            return 0
        total = self.source.total()
        if self._rate > 0:
            target = self.source.count_due(self.record_time_s())
        elif self._flow_base is not None:
            target = self.flow_received - self._flow_base + self.flow_window
        else:
            target = self.published + 1   # no count from the consumer: one sample per tick
        if total is not None:
            target = min(target, total)
        if self._rate > 0:
            self.behind_max = max(self.behind_max, target - self.published)
        return max(0, min(target - self.published, self.max_batch))

    def sent(self, n=1):
        """Count ``n`` samples published; note the end time when the source is done."""
        self.published += int(n)
        if self.finished and self.end_s is None:
            self.end_s = self._clock()

    def elapsed_s(self):
        """Wall time [s] from the start to the end (or to now while running)."""
        if self.start_s is None:
            return 0.0
        end = self.end_s if self.end_s is not None else self._clock()
        return end - self.start_s

    def values(self):
        """Return the pacing part of the rig's status (plain numbers)."""
        elapsed = self.elapsed_s()
        values = {'samples_published': self.published, 'rate_factor': self._rate,
                  'elapsed_s': elapsed, 'done': self.finished, 'started': self.started,
                  'effective_rate_hz': self.published / elapsed if elapsed > 0 else 0.0,
                  'behind_max_samples': self.behind_max, 'flow_restarts': self.flow_restarts}
        if self._rate == 0:
            values['flow'] = {'received': self.flow_received, 'window': self.flow_window}
        return values


class LockstepPacer:
    """
    Hardware in the loop: samples the rig runs on its own clock while the commander is silent.

    Parameters
    ----------
    sample_rate_hz : float
        Rig DAQ rate [Hz].
    timeout_s : float
        Rig time [s] of silence after which the rig runs on its own clock.
    rate_factor : float
        Rig time per wall time (0 counts as 1: lockstep has no flow control).
    clock : callable
        ``clock()`` -> wall time [s], monotonic.
    max_batch : int
        Most samples due in one tick.
    wait_for_subscribers : int
        Measurement readers to wait for before the rig takes commands (:meth:`accepting`): the
        commander (the car) cannot start before them, so no reader misses the first samples.
    start_timeout_s : float
        Longest wait for those readers [s]; then the rig takes commands anyway.

    """

    def __init__(self, sample_rate_hz, timeout_s, rate_factor=1.0, *, clock=time.monotonic,
                 max_batch=MAX_BATCH, wait_for_subscribers=0, start_timeout_s=30.0):
        self.wait_for_subscribers = int(wait_for_subscribers)
        self.start_timeout_s = float(start_timeout_s)
        self.created_s = clock()
        self.accepting_s = None
        self.sample_rate_hz = float(sample_rate_hz)
        self.timeout_s = float(timeout_s)
        self.rate_factor = _check_rate_factor(rate_factor)
        self._rate = self.rate_factor or 1.0
        self._clock = clock
        self.max_batch = int(max_batch)
        self.start_s = None
        self.last_command_s = None
        self.free = 0          # samples run on the rig's own clock since the last command
        self.published = 0

    def set_rate_factor(self, rate_factor):
        """Change the rig time per wall time (0 counts as 1)."""
        self.rate_factor = _check_rate_factor(rate_factor)
        self._rate = self.rate_factor or 1.0

    def accepting(self, subscribers):
        """
        Return True once the rig may take commands (latched).

        That is once ``subscribers`` (readers matched by the measurement writer now) reached
        ``wait_for_subscribers``, or after ``start_timeout_s`` of waiting.
        """
        if self.accepting_s is None:
            now = self._clock()
            if (subscribers >= self.wait_for_subscribers
                    or now - self.created_s >= self.start_timeout_s):
                self.accepting_s = now
        return self.accepting_s is not None

    def command(self):
        """Note a command now (its sample is published at once: count it with :meth:`sent`)."""
        now = self._clock()
        if self.start_s is None:
            self.start_s = now
        self.last_command_s = now
        self.free = 0

    def due(self):
        """Return how many samples to publish now on the rig's own clock (0 while commanded)."""
        if self.last_command_s is None:
            return 0
        silent_s = (self._clock() - self.last_command_s) * self._rate
        if silent_s <= self.timeout_s:
            return 0
        due = int(silent_s * self.sample_rate_hz + 1e-9) - self.free
        return max(0, min(due, self.max_batch))

    def sent(self, n=1, free=False):
        """Count ``n`` samples published (``free``: on the rig's own clock)."""
        self.published += int(n)
        if free:
            self.free += int(n)

    def elapsed_s(self):
        """Wall time [s] since the first command."""
        return 0.0 if self.start_s is None else self._clock() - self.start_s

    def values(self):
        """Return the pacing part of the rig's status (plain numbers)."""
        elapsed = self.elapsed_s()
        return {'samples_published': self.published, 'rate_factor': self.rate_factor,
                'elapsed_s': elapsed, 'done': False, 'started': self.start_s is not None,
                'effective_rate_hz': self.published / elapsed if elapsed > 0 else 0.0,
                'behind_max_samples': 0, 'flow_restarts': 0}
