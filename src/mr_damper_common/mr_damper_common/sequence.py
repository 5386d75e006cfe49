"""
Losses of a message stream counted from its messages' own sequence numbers (no ROS).

A reader never arms Fast DDS's MESSAGE_LOST event (it can deadlock a node, ros2/rmw_fastrtps
#890); a writer that numbers its messages (+1 per message) lets the reader count what did not
arrive instead: :class:`SequenceTracker` takes each number and counts the gaps (``lost``), the
same number again (``repeated``), an older one (``out_of_order``, not used) and a writer that
started again from a low number (``restarts``: its numbers are taken as the new reference and
nothing is counted lost).
"""


class SequenceTracker:
    """
    Count lost, repeated, out-of-order and restarted messages of one stream.

    Parameters
    ----------
    restart_below : int
        A number lower than the last one and at most this is a restarted writer (its
        numbering starts again near 0 or 1), not an old message.

    Attributes
    ----------
    received, lost, repeated, out_of_order, restarts : int
        Counts since construction.
    last : int or None
        The newest number taken (None before the first).

    """

    def __init__(self, restart_below=1):
        self.restart_below = int(restart_below)
        self.last = None
        self.received = 0
        self.lost = 0
        self.repeated = 0
        self.out_of_order = 0
        self.restarts = 0

    def offer(self, sequence):
        """
        Take one message's number; return how to use it.

        Parameters
        ----------
        sequence : int
            The message's sequence number.

        Returns
        -------
        int
            The messages missing just before this one (0 in order, > 0 after a gap), or -1
            for a message not to use (the same number again, or older than the newest).

        """
        sequence = int(sequence)
        self.received += 1
        last = self.last
        if last is None:
            self.last = sequence
            return 0
        if sequence == last:
            self.repeated += 1
            return -1
        if sequence < last:
            if sequence <= self.restart_below:
                self.restarts += 1
                self.last = sequence
                return 0
            self.out_of_order += 1
            return -1
        gap = sequence - last - 1
        self.lost += gap
        self.last = sequence
        return gap

    def status(self):
        """Return the counts as a dict (JSON-ready)."""
        return {'received': self.received, 'lost': self.lost, 'repeated': self.repeated,
                'out_of_order': self.out_of_order, 'restarts': self.restarts}
