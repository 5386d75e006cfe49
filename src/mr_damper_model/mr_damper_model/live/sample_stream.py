"""
Continuity of a batched measurement stream: samples lost between messages, counted exactly.

The rig publishes its samples in ``mr_damper_interfaces/DamperSamples`` batches, each carrying
the stream index of its first sample (``first_index``, +n per message from 0 at the
publisher's start). A reader feeds every batch's ``(first_index, n)`` to one
:class:`BatchIndex`, which counts the samples that never arrived (an index jump) and the
publisher's restarts (the index going back), so "0 lost" in a status means 0 samples, not 0
messages. No ROS import: the identifier, the car's rig path, the recorder and the report use it.
"""


class BatchIndex:
    """
    Count lost samples and publisher restarts from the ``first_index`` of consecutive batches.

    The first batch a reader sees sets the reference: samples published before the reader
    joined are not counted as lost (``skipped_at_start`` keeps how many there were).

    Attributes
    ----------
    batches, samples : int
        Batches and samples taken.
    lost : int
        Samples missing between batches (index jumps forward), all restarts included.
    restarts : int
        Batches whose index went back (the publisher restarted, or a replay looped its stream).
    skipped_at_start : int
        ``first_index`` of the first batch seen (samples published before this reader).

    """

    def __init__(self):
        self.batches = 0
        self.samples = 0
        self.lost = 0
        self.restarts = 0
        self.skipped_at_start = 0
        self._expected = None

    def update(self, first_index, n):
        """
        Take one batch; return the samples lost just before it (0 if none).

        Parameters
        ----------
        first_index : int
            Stream index of the batch's first sample.
        n : int
            Samples in the batch (>= 1).

        Returns
        -------
        int
            Samples missing between the previous batch and this one.

        """
        first_index, n = int(first_index), int(n)
        lost = 0
        if self._expected is None:
            self.skipped_at_start = first_index
        elif first_index > self._expected:
            lost = first_index - self._expected
            self.lost += lost
        elif first_index < self._expected:
            self.restarts += 1
        self._expected = first_index + n
        self.batches += 1
        self.samples += n
        return lost

    def as_dict(self):
        """Return the counters as a plain dict (status values)."""
        return {'batches': self.batches, 'samples': self.samples, 'lost': self.lost,
                'restarts': self.restarts, 'skipped_at_start': self.skipped_at_start}
