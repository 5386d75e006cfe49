"""
The rig's measurement stream in batches: which samples go out in which message, without ROS.

A DAQ at 1-10 kHz cannot afford one DDS message per sample on a small shared machine: every
reader (identifier, car, recorder) would pay the per-message overhead thousands of times a
second. :class:`BatchStream` takes the samples the pacer says are due, keeps them until a whole
batch of ``samples_per_message`` is due, and hands each batch (arrays ``t, x, v, f, i`` plus its
``sequence`` and ``first_index``) to a ``publish`` callback, the node's conversion to
``mr_damper_interfaces/DamperSamples``:

- timed pacing (``rate_factor`` > 0): a batch goes out at the first tick at which its last
  sample is due, so batching adds at most ``samples_per_message`` DAQ periods of latency; a
  partial batch goes out at the end of a finite stream;
- flow control (``rate_factor`` 0): every sample due goes out at once, cut into batches;
- a refused publish (the writer is being replaced) keeps the batch: it goes out again, with
  the same sequence and index, at the next tick, so a replaced writer loses nothing;
- hardware in the loop: :meth:`BatchStream.publish_one` sends each sample at once, alone, on
  the car's link (lockstep), and keeps it for the batches of the measurement stream, which
  go out whole (:meth:`BatchStream.publish_full`), so the identifier and the recorder read
  batches in HIL too.

``sequence`` counts messages and ``first_index`` samples, both from 0 at the start: a reader
counts lost samples exactly (:class:`mr_damper_common.recording.BatchIndex`). The batches'
counters are the stream's own; the lockstep link has its own pair (:attr:`link_sequence`, and
the pacer's ``published`` count as its index).
"""
import numpy as np


class BatchStream:
    """
    Cut the rig's due samples into measurement batches.

    Parameters
    ----------
    source : object
        ``sample(k)`` -> ``(t, x, v, f, i)`` of sample ``k`` (called with k counting up by one)
        and ``total()`` -> samples in all or None; optionally ``samples(k, n)`` -> five arrays
        of samples ``k .. k+n-1`` (a replay's arrays, taken without a Python loop).
    pacer : object
        :class:`mr_damper_rig.pacing.Pacer` or ``LockstepPacer``: ``published``, ``due()``,
        ``sent(n)``, ``rate_factor``.
    samples_per_message : int
        Samples per batch (>= 1).

    Attributes
    ----------
    sequence : int
        Number of the next batch.
    newest_s : float
        Stamp of the newest sample published [s] (NaN before the first).

    """

    def __init__(self, source, pacer, samples_per_message):
        samples_per_message = int(samples_per_message)
        if samples_per_message < 1:
            raise ValueError(f'`samples_per_message` must be >= 1, got {samples_per_message}')
        self.source = source
        self.pacer = pacer
        self.samples_per_message = samples_per_message
        self.sequence = 0
        self.first_index = 0
        self.link_sequence = 0
        self.newest_s = float('nan')
        self._rows = np.empty((0, 5))
        self._pending = 0

    @property
    def pending(self):
        """Samples produced (taken from the source) but not yet published."""
        return self._pending

    def _produce(self, n):
        """Take the next ``n`` samples from the source into the pending rows."""
        if n <= 0:
            return
        k = self.first_index + self._pending
        if hasattr(self.source, 'samples'):
            new = np.column_stack(self.source.samples(k, n))
        else:
            new = np.array([self.source.sample(k + j) for j in range(n)], dtype=float)
        need = self._pending + n
        if need > self._rows.shape[0]:
            rows = np.empty((max(need, 2 * self._rows.shape[0]), 5))
            rows[:self._pending] = self._rows[:self._pending]
            self._rows = rows
        self._rows[self._pending:need] = new
        self._pending = need

    def _end_reached(self):
        total = self.source.total()
        return total is not None and self.first_index + self._pending >= total

    def tick(self, publish):
        """
        Produce the samples due now and publish every batch that is complete.

        Parameters
        ----------
        publish : callable
            ``publish(t, x, v, f, i, sequence, first_index)`` -> True if the message went out.

        Returns
        -------
        tuple of int
            ``(due, sent)``: samples due at this tick (pacer) and samples published.

        """
        due = self.pacer.due()
        self._produce(due - self._pending)
        flush = self.pacer.rate_factor == 0 or self._end_reached()
        sent = self._publish_batches(publish, flush, count=True)
        return due, sent

    def publish_full(self, publish):
        """Publish every whole batch pending (lockstep: the pacer counted its samples); count."""
        return self._publish_batches(publish, False, count=False)

    def _publish_batches(self, publish, flush, count):
        sent = 0
        while self._pending >= self.samples_per_message or (flush and self._pending):
            n = min(self._pending, self.samples_per_message)
            if not self._send(publish, self._rows[:n]):
                break
            if count:
                self.pacer.sent(n)
            self._rows[:self._pending - n] = self._rows[n:self._pending]
            self._pending -= n
            sent += n
        return sent

    def publish_one(self, publish, free=False):
        """
        Hardware in the loop: publish the next sample at once, alone, on the car's link.

        The sample also stays pending for the measurement batches (:meth:`publish_full`).
        ``free``: the sample runs on the rig's own clock (``LockstepPacer.sent``). Returns True
        if it went out; the pacer counts it either way (a lockstep sample that could not be
        published is not sent again, the car has moved on; the car counts it missing).
        """
        first_index = self.pacer.published
        self._produce(1)
        row = self._rows[self._pending - 1]
        t, x, v, f, i = (np.array([value]) for value in row)
        ok = bool(publish(t, x, v, f, i, self.link_sequence, first_index))
        if ok:
            self.link_sequence += 1
        self.pacer.sent(1, free=free)
        return ok

    def _send(self, publish, rows):
        n = rows.shape[0]
        t, x, v, f, i = (rows[:, j].copy() for j in range(5))
        if not publish(t, x, v, f, i, self.sequence, self.first_index):
            return False
        self.sequence += 1
        self.first_index += n
        self.newest_s = float(t[-1])
        return True
