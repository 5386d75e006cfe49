"""
Continuity of a batched measurement stream: samples lost between messages, counted exactly.

The rig publishes its samples in ``mr_damper_interfaces/DamperSamples`` batches, each carrying
the stream index of its first sample (``first_index``, +n per message from 0 at the
publisher's start). A reader feeds every batch's ``(first_index, n)`` to one
:class:`BatchIndex`, which counts the samples that never arrived (an index jump) and the
publisher's restarts (the index going back), so "0 lost" in a status means 0 samples, not 0
messages. An index jump the stamps do not show (a batch whose ``first_index`` is corrupt, or
a second publisher with an index of its own) is no loss: it counts as a restart of the stream
(``jumps``), so one bad message cannot put 2**64 lost samples in a status for good. No ROS
import: the identifier, the car's rig path, the recorder and the report use it.
"""
import math

import numpy as np

#: Longest forward index jump taken as a loss when no stamps judge it [samples] (2**31: 25 days
#: at 1 kHz); a longer one is a restart.
MAX_JUMP_SAMPLES = 2 ** 31
#: An index jump is a loss when it is at most this many samples more than the stamps show
#: missing (jitter of the stamps, rounding).
JUMP_SLACK_SAMPLES = 16
#: ... or at most this factor times the samples the stamps show missing.
JUMP_TOLERANCE = 1.5


class BatchIndex:
    """
    Count lost samples and publisher restarts from the ``first_index`` of consecutive batches.

    The first batch a reader sees sets the reference: samples published before the reader
    joined are not counted as lost (``skipped_at_start`` keeps how many there were).

    A forward jump of the index counts as lost samples only when it is plausible: with the
    batches' stamps given (:meth:`update` ``t``), at most :data:`JUMP_TOLERANCE` times (plus
    :data:`JUMP_SLACK_SAMPLES`) the samples the stamp step between the batches holds at the
    sample period; without stamps, at most :data:`MAX_JUMP_SAMPLES`. A larger jump is a restart
    of the stream (``restarts`` and ``jumps``), as an index going back is.

    Attributes
    ----------
    batches, samples : int
        Batches and samples taken.
    lost : int
        Samples missing between batches (plausible index jumps forward), all restarts included.
    restarts : int
        Batches whose index went back (the publisher restarted, or a replay looped its stream)
        or jumped forward further than the stamps allow (``jumps``).
    jumps : int
        Restarts on an implausible forward jump.
    skipped_at_start : int
        ``first_index`` of the first batch seen (samples published before this reader).

    """

    def __init__(self):
        self.batches = 0
        self.samples = 0
        self.lost = 0
        self.restarts = 0
        self.jumps = 0
        self.skipped_at_start = 0
        self._expected = None
        self._last_t = None        # stamp of the previous batch's last sample [s]
        self._period = None        # sample period [s] (message or stamps)

    def update(self, first_index, n, t=None, period_s=0.0):
        """
        Take one batch; return the samples lost just before it (0 if none).

        Parameters
        ----------
        first_index : int
            Stream index of the batch's first sample.
        n : int
            Samples in the batch (>= 1).
        t : array_like with shape (n,), optional
            The batch's stamps [s]: they judge whether an index jump is a loss.
        period_s : float
            Nominal sample period [s] (``DamperSamples.sample_period_s``; 0: irregular, the
            median step of the stamps is used).

        Returns
        -------
        int
            Samples missing between the previous batch and this one.

        """
        first_index, n = int(first_index), int(n)
        t0, t1 = self._stamps(t, period_s)
        lost = 0
        if self._expected is None:
            self.skipped_at_start = first_index
        elif first_index > self._expected:
            jump = first_index - self._expected
            if self._plausible(jump, t0):
                lost = jump
                self.lost += lost
            else:
                self.restarts += 1
                self.jumps += 1
        elif first_index < self._expected:
            self.restarts += 1
        self._expected = first_index + n
        if t1 is not None:
            self._last_t = t1
        self.batches += 1
        self.samples += n
        return lost

    def _stamps(self, t, period_s):
        """Return the first and last finite stamps of a batch (or None, None); note the period."""
        if t is None:
            return None, None
        t = np.asarray(t, dtype=float)
        t = t[np.isfinite(t)]
        if not t.size:
            return None, None
        period_s = float(period_s) if period_s is not None else 0.0
        if math.isfinite(period_s) and period_s > 0:
            self._period = period_s
        elif t.size > 1:
            step = float(np.median(np.diff(t)))
            if step > 0:
                self._period = step
        return float(t[0]), float(t[-1])

    def _plausible(self, jump, t0):
        """Tell whether a forward index jump is a loss (see the class docstring)."""
        if jump > MAX_JUMP_SAMPLES:
            return False
        if t0 is None or self._last_t is None or not self._period:
            return True
        missing = (t0 - self._last_t) / self._period - 1.0
        return jump <= JUMP_SLACK_SAMPLES + JUMP_TOLERANCE * max(missing, 0.0)

    def as_dict(self):
        """Return the counters as a plain dict (status values)."""
        return {'batches': self.batches, 'samples': self.samples, 'lost': self.lost,
                'restarts': self.restarts, 'jumps': self.jumps,
                'skipped_at_start': self.skipped_at_start}
