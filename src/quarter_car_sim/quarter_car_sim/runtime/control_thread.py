"""
The quarter car's control thread without ROS: paced steps, their timing, and a death certificate.

:class:`ControlThread` calls ``step(wall)`` once per control period, paced by a
:class:`quarter_car_sim.simulate.live_loop.Pacer` (real time times a factor, or as fast as
possible), and books each step's period, lateness, latency (wake-up ->
:meth:`ControlThread.command_sent`) and duration in a
:class:`quarter_car_sim.simulate.live_loop.LoopTiming`. An exception in a step ends the loop and
is kept in :attr:`ControlThread.failed` (and handed to ``on_error``), so the node can say so
(ERROR on ``/diagnostics``) and end instead of looking alive.

The pacing and the timing are wall time by nature (a real-time simulation keeps pace with the
wall clock; jitter and latency are wall-clock figures): the pacer's clock and ``clock`` are
monotonic wall clocks, injected so that tests run on a fake clock.
"""
import os
import threading
import time


class ControlThread:
    """
    Run ``step`` once per control period in a thread (or in the caller, :meth:`run`).

    Parameters
    ----------
    step : callable
        ``step(wall)`` runs one control step; ``wall`` is the pacer's wake-up time [s].
    pacer : quarter_car_sim.simulate.live_loop.Pacer
        Schedules the steps (``wait()`` -> wake-up time, ``lateness``, ``late``).
    timing : quarter_car_sim.simulate.live_loop.LoopTiming
        Takes ``add(wall, latency_s, step_s, lateness_s)`` after every step.
    clock : callable
        Monotonic wall clock [s] of latency and step duration (``time.perf_counter``).
    after_step : callable, optional
        ``after_step(wall, latency_s, lateness_s)`` after the timing is booked (the trace log).
    before_first : callable, optional
        Called in the thread before the first step (e.g. wait for a lock-step partner).
    on_error : callable, optional
        ``on_error(text)`` when a step raised (``text`` = ``'Type: message'``).
    priority : int
        SCHED_FIFO priority of the thread (0: normal scheduling); needs CAP_SYS_NICE, else
        :attr:`priority_error` says why it was not applied.

    Attributes
    ----------
    steps : int
        Steps run.
    failed : str or None
        Why the loop died (None while it did not).
    running : bool
        False once :meth:`stop` was called or the loop died.

    """

    def __init__(self, step, pacer, timing, *, clock=time.perf_counter, after_step=None,
                 before_first=None, on_error=None, priority=0):
        self.step = step
        self.pacer = pacer
        self.timing = timing
        self.clock = clock
        self.after_step = after_step
        self.before_first = before_first
        self.on_error = on_error
        self.priority = int(priority)
        self.priority_error = None
        self.steps = 0
        self.failed = None
        self.running = True
        self._sent = None
        self._thread = None

    def command_sent(self):
        """Mark the moment the step's command went out (latency = now - wake-up)."""
        self._sent = self.clock()

    def start(self, name='control'):
        """Start :meth:`run` in a daemon thread."""
        self._thread = threading.Thread(target=self.run, name=name, daemon=True)
        self._thread.start()
        return self

    def alive(self):
        """Return True while the thread runs (False before :meth:`start`)."""
        return self._thread is not None and self._thread.is_alive()

    def stop(self, timeout_s=2.0):
        """Ask the loop to end after the current step and wait up to ``timeout_s`` [s]."""
        self.running = False
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)

    def _set_priority(self):
        if self.priority <= 0:
            return
        # the loop sleeps most of each period, so a real-time priority costs the others
        # nothing but lets it preempt them at its deadlines (jitter on a loaded machine)
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.priority))
        except (AttributeError, OSError) as exc:
            self.priority_error = str(exc)

    def run(self, max_steps=None):
        """
        Run steps until :meth:`stop`, a step raises, or ``max_steps`` steps (tests).

        Returns
        -------
        str or None
            :attr:`failed`.

        """
        self._set_priority()
        try:
            if self.before_first is not None:
                self.before_first()
            while self.running and (max_steps is None or self.steps < max_steps):
                wall = self.pacer.wait()
                t0 = self.clock()
                self._sent = None
                self.step(wall)
                t1 = self.clock()
                latency = (self._sent if self._sent is not None else t1) - t0
                lateness = self.pacer.lateness
                self.timing.add(wall, latency, t1 - t0, lateness)
                self.steps += 1
                if self.after_step is not None:
                    self.after_step(wall, latency, lateness)
        except Exception as exc:  # noqa: B902 - any failure ends the loop, said loudly
            if self.running:
                self.failed = f'{type(exc).__name__}: {exc}'
                self.running = False
                if self.on_error is not None:
                    self.on_error(self.failed)
        return self.failed

    def status(self):
        """Return the loop timing (``LoopTiming.stats()``) plus ``late_reanchors``."""
        st = self.timing.stats()
        st['late_reanchors'] = int(getattr(self.pacer, 'late', 0))
        return st
