"""
The identifier node's runtime around :class:`~mr_damper_model.live.LiveIdentifier`; no ROS.

The identifier node converts messages and calls one :class:`IdentifierRuntime`, which holds:

- the fitting worker (:meth:`IdentifierRuntime.step` processes one due window; a thread runs it
  in a loop so the measurement callbacks keep up while a window is fitted);
- the throttled parameter-file saving (:class:`SaveThrottle`: at most one write per
  ``save_period_s`` of the injected clock, the newest pending set written later, the last valid
  set forced at shutdown);
- the stamp ages of the received samples (:class:`StampAges`, a ring buffer: receipt time minus
  the sample's stamp, i.e. the transport latency when stamps are the rig's clock);
- the health rules (:class:`IdentifierHealth`): a level, a reason and every status value.

Time is whatever the injected ``clock()`` returns [s]: the node passes its ROS clock, so under
``use_sim_time`` every age and timeout here is in the replay's time; tests pass a fake clock.
"""
import math
import os
import threading

import numpy as np

from mr_damper_common.health import dropped_since, ERROR, OK, Rising, WARN, worst
from mr_damper_common.recording.batch_index import BatchIndex

#: Window skips that point at the data or the sensors (WARN while they rise); the other skip
#: reasons (few samples, no motion, no force, one direction) mean the rig is idle.
WARN_SKIPS = ('gap', 'inconsistent', 'no_bins')


class StampAges:
    """
    Ring buffer of the newest stamp ages [s] and their percentiles.

    Parameters
    ----------
    size : int
        Ages kept (the newest ``size``).

    """

    def __init__(self, size=10000):
        if int(size) < 1:
            raise ValueError(f'`size` must be >= 1, got {size!r}')
        self._ages = np.zeros(int(size))
        self.count = 0

    def add(self, age_s):
        """Record one age [s] (receipt time minus stamp)."""
        self._ages[self.count % self._ages.size] = age_s
        self.count += 1

    def summary(self):
        """
        Return ``{'p50', 'p99', 'max'}`` [ms] and ``'n'`` of the ages kept ({} if none).

        Returns
        -------
        dict
            Median, 99th percentile and maximum age [ms] and the number of ages they rest on.

        """
        ages = self._ages[:min(self.count, self._ages.size)]
        if not ages.size:
            return {}
        p50, p99 = np.percentile(ages, [50, 99]) * 1e3
        return {'p50': float(p50), 'p99': float(p99), 'max': float(ages.max()) * 1e3,
                'n': int(ages.size)}


class SaveThrottle:
    """
    Write parameter sets at most once per period; keep the newest one pending meanwhile.

    Parameters
    ----------
    save : callable
        ``save(estimate)`` writes a set; may raise ``OSError`` (counted, kept pending).
    period_s : float
        Shortest time between two writes [s of ``clock``].
    clock : callable
        ``clock()`` -> now [s].

    """

    def __init__(self, save, period_s, clock):
        if not period_s >= 0:
            raise ValueError(f'`period_s` must be >= 0, got {period_s!r}')
        self._save = save
        self.period_s = float(period_s)
        self._clock = clock
        self._lock = threading.Lock()
        self._last = None
        self.pending = None
        self.writes = 0
        self.errors = 0
        self.last_error = ''

    def offer(self, estimate, force=False):
        """
        Write ``estimate`` now if the period has passed (or ``force``), else keep it pending.

        Returns
        -------
        str
            '' (written or pending), or the error of a failed write (the set stays pending).

        """
        with self._lock:
            return self._offer_locked(estimate, force)

    def _offer_locked(self, estimate, force=False):
        now = self._clock()
        if (not force and self._last is not None and now >= self._last
                and now - self._last < self.period_s):
            self.pending = estimate
            return ''
        try:
            self._save(estimate)
        except OSError as exc:
            self.errors += 1
            self.last_error = f'{type(exc).__name__}: {exc}'
            self.pending = estimate
            return self.last_error
        self.writes += 1
        self._last = now
        self.pending = None
        return ''

    def flush(self):
        """Write the pending set if its period has passed; return '' or the write error."""
        with self._lock:        # taken and written in one step: a newer offer cannot interleave
            pending = self.pending
            return self._offer_locked(pending) if pending is not None else ''


class WindowOutcome:
    """
    What processing one window gave: an estimate, a skip, or a fit error.

    Attributes
    ----------
    end_s : float
        Scheduled end of the window [s, sample time].
    estimate : LiveEstimate or None
        The new estimate (None when skipped or failed).
    skip : str
        Why the window was skipped ('' if not).
    error : str
        The fit error ('' if none).

    """

    __slots__ = ('end_s', 'estimate', 'skip', 'error')

    def __init__(self, end_s, estimate=None, skip='', error=''):
        self.end_s = end_s
        self.estimate = estimate
        self.skip = skip
        self.error = error


def _publish_failed(reason):
    """Whether a drop reason is a failed publish of the identifier's own (not a lost sample)."""
    return reason.endswith('_publish_failed')


class IdentifierHealth:
    """
    Health rules of the identifier, judged on the change of its counters since the last call.

    Levels (the message names every finding at the top level):

    - ERROR: fit worker thread dead; fit process dead; fit errors on every window since the last
      report; no sample received for ``no_sample_timeout_s`` (since the first report, if none
      ever came).
    - WARN: last estimate not valid (its reason); windows skipped for ``gap``, ``inconsistent``
      or ``no_bins`` since the last report; samples rejected (bad messages, out of range) since
      the last report; samples lost (buffer, transport: exact, from the batches' stream index)
      since the last report; measurement messages lost (their sequence numbers); failed
      publishes of its own topics since the last report; other drops since the last report
      (by reason); windows passed over in in-order mode
      (``windows_overflow``); some fit errors; no valid model yet although windows were
      processed.
    - OK: fitting, last estimate valid; or waiting for samples / for the first window.

    Parameters
    ----------
    no_sample_timeout_s : float
        Longest silence of the measurement stream before ERROR [s of ``now_s``]; 0: never.

    """

    def __init__(self, no_sample_timeout_s=5.0):
        self.no_sample_timeout_s = float(no_sample_timeout_s)
        self._rising = Rising()
        self._received = None
        self._since = None      # time of the last change of samples_received (or first call)

    @staticmethod
    def _counts(v):
        dropped = v.get('dropped', {})
        return {
            'rejected': sum(v.get('rejected', {}).values())
            + sum(v.get('out_of_range', {}).values()),
            # samples only: a failed publish of our own is not a lost sample (it is counted
            # under its own reason in ``dropped``); the transport's losses are counted exactly
            # in samples from the batches' stream index (``message_lost``, from the batches'
            # sequence numbers, counts messages of any size: it stays in ``dropped``)
            'lost': v.get('samples_lost', 0) + v.get('stream', {}).get('lost', 0),
            'messages_lost': dropped.get('message_lost', 0),
            'publish_failed': sum(n for r, n in dropped.items() if _publish_failed(r)),
            'overflow': v.get('windows_overflow', 0),
            'fitted': v.get('windows_fitted', 0),
            'errors': v.get('fit_errors', 0),
            **{f'skips.{r}': v.get('windows_skipped', {}).get(r, 0) for r in WARN_SKIPS}}

    def __call__(self, values, now_s):
        """
        Judge the status ``values`` at time ``now_s`` [s]; return a :class:`Health`.

        Parameters
        ----------
        values : dict
            :meth:`IdentifierRuntime.values` (``LiveIdentifier.status()`` keys plus
            ``worker_alive``, ``fit_process_alive``, ``has_valid``, ``dropped``).
        now_s : float
            Now [s], the clock of the sample receipts (ROS time in the node).

        Returns
        -------
        Health
            Level, message and ``values`` (with ``last_sample_age_s`` added).

        """
        rose = {key: self._rising.rise(key, n) for key, n in self._counts(values).items()}
        received = values.get('samples_received', 0)
        if self._since is None or received != self._received or now_s < self._since:
            self._since = now_s
            self._received = received
        silent = now_s - self._since
        values = dict(values, last_sample_age_s=silent if received else math.nan)
        found = []
        if not values.get('worker_alive', True):
            found.append((ERROR, 'fit worker dead'))
        if not values.get('fit_process_alive', True):
            found.append((ERROR, 'fit process dead'))
        errors = rose['errors']
        if errors > 0 and rose['fitted'] == 0:
            found.append((ERROR, f'fit errors on every window ({errors}): '
                                 f'{values.get("last_error", "")}'))
        elif errors > 0:
            found.append((WARN, f'{errors} fit error(s)'))
        if 0 < self.no_sample_timeout_s <= silent:
            found.append((ERROR, f'no samples for {silent:.1f} s'))
        fitted = values.get('windows_fitted', 0) > 0
        if fitted and not values.get('last_valid', False):
            found.append((WARN, f'last estimate not valid: {values.get("last_reason", "")}'))
        for reason in WARN_SKIPS:
            n = rose[f'skips.{reason}']
            if n > 0:
                found.append((WARN, f'{n} window(s) skipped: {reason}'))
        for key, what in (('rejected', 'sample(s) rejected'), ('lost', 'sample(s) lost'),
                          ('messages_lost', 'message(s) lost (sequence gaps)'),
                          ('publish_failed', 'publish(es) failed'),
                          ('overflow', 'window(s) passed over (backlog full)')):
            n = rose[key]
            if n > 0:
                found.append((WARN, f'{n} {what}'))
        other = dropped_since(self._rising, {
            r: n for r, n in values.get('dropped', {}).items()
            if r != 'message_lost' and not _publish_failed(r)})
        if other:
            found.append(other)
        if values.get('windows_due', 0) > 0 and not values.get('has_valid', False):
            found.append((WARN, 'no valid model yet'))
        health = worst(found, values)
        if health.level == OK:
            health.message = ('fitting, last estimate valid' if fitted else
                              'collecting the first window' if received else
                              'waiting for samples')
        return health


class IdentifierRuntime:
    """
    The identifier node's core object: samples in, windows fitted, sets saved, health out.

    Parameters
    ----------
    live : LiveIdentifier
        The identifier.
    clock : callable
        ``clock()`` -> now [s] (the node's ROS time).
    save : callable, optional
        ``save(estimate)`` writes a valid set to the parameter file (None: no file).
    save_period_s : float
        Shortest time between two file writes [s of ``clock``].
    fit_process : FitProcess, optional
        The fit process ``live`` fits in (its liveness is reported; closed at shutdown).
    no_sample_timeout_s : float
        See :class:`IdentifierHealth`.
    ages : int
        Stamp ages kept for the percentiles.
    initial_source : str
        Where the initial estimate came from (``'none'``, ``'file'``, ``'file_error'``).

    """

    def __init__(self, live, clock, *, save=None, save_period_s=2.0, fit_process=None,
                 no_sample_timeout_s=5.0, ages=10000, initial_source='none'):
        self.live = live
        self.clock = clock
        self.saver = SaveThrottle(save, save_period_s, clock) if save is not None else None
        self.fit_process = fit_process
        self.ages = StampAges(ages)
        self.stream = BatchIndex()
        self.health_rules = IdentifierHealth(no_sample_timeout_s)
        self.initial_source = initial_source
        self.parameters_published = 0
        self.fit_ready = True
        self._stop = threading.Event()
        self._thread = None

    # ---------------------------------------------------------------- samples (receiving thread)
    def receive(self, t, x, v, f, i):
        """Offer one sample (``LiveIdentifier.add_sample``), record its stamp age [s]."""
        now = self.clock()
        reason = self.live.add_sample(t, x, v, f, i, now=now)
        self.ages.add(now - t)
        return reason

    def receive_batch(self, t, x, v, f, i, first_index=None, period_s=0.0):
        """
        Offer a batch of samples (``LiveIdentifier.add_samples``); return the rejected ones.

        Parameters
        ----------
        t, x, v, f, i : numpy.ndarray with shape (n,)
            Stamps [s], displacement [m], velocity [m/s], force [N], current [A].
        first_index : int, optional
            Stream index of the first sample (``DamperSamples.first_index``): samples missing
            before it are counted in :attr:`stream` (``lost``; an index jump the stamps do not
            show is a restart there). A batch refused whole (stamped in the future) takes no
            place in the stream.
        period_s : float
            The batch's nominal sample period [s] (``DamperSamples.sample_period_s``; 0:
            irregular): judges index jumps against the stamps.

        Returns
        -------
        list of (int, str)
            ``(index in the batch, reason)`` of each rejected sample.

        """
        now = self.clock()
        rejected = self.live.add_samples(t, x, v, f, i, now=now)
        refused = len(t) and len(rejected) == len(t) and rejected[0][1] == 'future_stamp'
        if first_index is not None and not refused:
            self.stream.update(first_index, len(t), t, period_s)
        if len(t):
            self.ages.add(now - float(t[-1]))   # the batch's transport latency
        return rejected

    def reject(self, reason):
        """Count a message that did not convert to a sample (e.g. ``'joint_names'``)."""
        self.live.count_rejected(reason)

    # ---------------------------------------------------------------- windows (worker thread)
    def step(self):
        """
        Process the next due window; return its :class:`WindowOutcome` (None if none is due).

        A fit error is counted (``fit_errors``, ``last_error``) and returned, never raised: one
        window never ends the worker.  A valid estimate is offered to the parameter file.
        """
        window = self.live.next_window()
        if window is None:
            return None
        try:
            est = self.live.process(window)
        except Exception as exc:  # noqa: B902 - counted and reported, the worker goes on
            if self._stop.is_set():
                raise          # shutdown ended the fit process: the loop ends quietly
            self.live.counters['fit_errors'] += 1
            self.live.last_error = f'{type(exc).__name__}: {exc}'
            return WindowOutcome(window.end_s, error=self.live.last_error)
        if est is None:
            return WindowOutcome(window.end_s, skip=self.live.last_skip)
        if est.valid and self.saver is not None:
            self.saver.offer(est)
        return WindowOutcome(window.end_s, estimate=est)

    def start(self, on_outcome, *, poll_s=0.005, normal_priority=False):
        """
        Run :meth:`step` in a daemon thread until :meth:`shutdown`.

        Parameters
        ----------
        on_outcome : callable
            ``on_outcome(outcome)`` for every window processed (the node publishes and logs);
            a true return value counts the estimate as published.
        poll_s : float
            Wall-time wait when no window is due [s] (a polling interval, not a time of the
            identification: wall time on purpose).
        normal_priority : bool
            Reset the thread to SCHED_OTHER (when the receiving threads run SCHED_FIFO).

        """
        def loop():
            if normal_priority:
                try:
                    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
                except OSError:
                    pass
            while not self._stop.is_set():
                try:
                    outcome = self.step()
                except Exception:  # noqa: B902 - only raised once shutdown has begun
                    break
                if outcome is None:
                    self._stop.wait(poll_s)
                elif on_outcome(outcome) and outcome.estimate is not None:
                    self.parameters_published += 1

        self._thread = threading.Thread(target=loop, name='identifier_fit', daemon=True)
        self._thread.start()

    def worker_alive(self):
        """Return True while the worker thread runs (True before :meth:`start`)."""
        return self._thread is None or self._thread.is_alive()

    def fit_process_alive(self):
        """Return True unless the fit process died (True for in-thread fits)."""
        return self.fit_process is None or not self.fit_ready or self.fit_process.alive()

    def flush_saves(self):
        """Write a pending set whose save period has passed; return '' or the write error."""
        return self.saver.flush() if self.saver is not None else ''

    def shutdown(self, wait_s=1.0):
        """
        Stop the worker and the fit process; write the last valid fitted set.

        Returns
        -------
        str
            '' or the error of the final write.

        """
        self._stop.set()
        if self.fit_process is not None:
            # a fit in progress ends with its process (the worker sees a failed fit and stops)
            self.fit_process.close(wait_s=0.5)
        if self._thread is not None:
            self._thread.join(timeout=wait_s)
        good = self.live.last_good
        if self.saver is not None and good is not None and good.model_fitted != 'file':
            return self.saver.offer(good, force=True)
        return ''

    # ---------------------------------------------------------------- status
    def values(self, extra=None):
        """
        Return every status value: ``LiveIdentifier.status()`` plus the runtime's.

        Added keys: ``last_rmse_n`` (RMSE of the last estimate [N]), ``stamp_age_ms``
        {p50, p99, max, n} (receipt minus the newest stamp of each batch), ``stream`` (the
        measurement batches: :meth:`BatchIndex.as_dict`, ``lost`` samples exactly),
        ``parameters_published``, ``params_file_writes``,
        ``params_file_errors``, ``initial_source``, ``worker_alive``, ``fit_process_alive``,
        ``fit_ready_at_subscribe``, ``has_valid`` (a valid set exists, fitted or loaded), then
        ``extra`` (e.g. the node's ``dropped`` counts).
        """
        v = self.live.status()
        est = self.live.estimate
        v.update(last_rmse_n=est.rmse_n if est is not None else math.nan,
                 stamp_age_ms=self.ages.summary(), stream=self.stream.as_dict(),
                 parameters_published=self.parameters_published,
                 params_file_writes=self.saver.writes if self.saver else 0,
                 params_file_errors=self.saver.errors if self.saver else 0,
                 initial_source=self.initial_source, worker_alive=self.worker_alive(),
                 fit_process_alive=self.fit_process_alive(),
                 fit_ready_at_subscribe=self.fit_ready,
                 has_valid=self.live.last_good is not None)
        v.update(extra or {})
        return v

    def health(self, extra=None):
        """Return the :class:`Health` now (see :class:`IdentifierHealth`)."""
        return self.health_rules(self.values(extra), self.clock())
