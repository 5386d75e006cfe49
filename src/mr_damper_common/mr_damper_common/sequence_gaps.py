"""
Messages lost on their way to a reader, counted from the publishers' own sequence numbers (no ROS).

A message that carries a running ``sequence`` (+1 per message per publisher, as
``mr_damper_interfaces/DamperSamples`` and ``QuarterCarState`` do) tells its reader how many
messages of its stream never arrived: a jump from ``k`` to ``k + 1 + n`` is ``n`` lost.
:class:`SequenceGaps` keeps the last number of each stream and counts those jumps. It is the one
home of that count: ``DropCounter.subscribe`` (``mr_damper_common.node_utils``) and the
recorder use it.

Why not the middleware's MESSAGE_LOST event: on the Fast DDS of this suite (3.2.3,
rmw_fastrtps_cpp 9.3.3) taking that event can deadlock the node for good against the receive
thread reporting a lost sample (ros2/rmw_fastrtps#890); the suite never arms it
(``docs/faults.md``, Lost messages).

What a jump means, per stream:

- ``k + 1``: nothing lost;
- ``k + 1 + n`` (``0 < n <= max_gap``): ``n`` messages lost (never delivered, or overwritten in
  the reader's own queue before the node took them: both are messages the node never used);
- the same ``k`` again: not counted (a publisher that leaves ``sequence`` at 0 numbers nothing);
- lower than ``k``: the publisher restarted (its numbers start again at 0), counted in
  ``restarts``, nothing lost;
- more than ``max_gap`` ahead: an absurd jump (a corrupt or foreign publisher), counted in
  ``restarts`` as well, never as losses, so one bad message cannot inflate the count.

The first message of a stream counts nothing: what was published before a reader matched its
publisher was never meant for it.
"""
from collections import OrderedDict

#: default largest jump counted as losses [messages]: 1000 s of a 1 kHz stream
MAX_GAP = 1_000_000
#: default number of streams remembered (the least recently seen is forgotten first)
MAX_STREAMS = 64


class SequenceGaps:
    """
    Count the messages missing between consecutive sequence numbers of each stream.

    Not thread-safe: one instance per subscription (its callbacks run in one thread).

    Parameters
    ----------
    max_gap : int
        Largest jump counted as lost messages; a longer one is a restart.
    max_streams : int
        Streams remembered; memory stays bounded whatever the publishers do.

    Attributes
    ----------
    received : int
        Messages offered.
    lost : int
        Messages counted missing, over all streams.
    restarts : int
        Streams whose numbers went back (publisher restarted) or jumped beyond ``max_gap``.

    """

    def __init__(self, max_gap=MAX_GAP, max_streams=MAX_STREAMS):
        if int(max_gap) < 1 or int(max_streams) < 1:
            raise ValueError(f'`max_gap` ({max_gap}) and `max_streams` ({max_streams}) must '
                             'be >= 1')
        self.max_gap = int(max_gap)
        self.max_streams = int(max_streams)
        self.received = 0
        self.lost = 0
        self.restarts = 0
        self._last = OrderedDict()

    def offer(self, sequence, stream=''):
        """
        Take the sequence number of one received message; return the messages lost before it.

        Parameters
        ----------
        sequence : int
            The message's own number (``msg.sequence``).
        stream : hashable
            Which publisher's stream it belongs to (e.g. ``msg.header.frame_id``).

        Returns
        -------
        int
            Messages of ``stream`` missing between the previous one and this one (0 for the
            first, a repeat, a restart or an absurd jump).

        """
        sequence = int(sequence)
        self.received += 1
        last = self._last.pop(stream, None)
        self._last[stream] = sequence
        if len(self._last) > self.max_streams:
            self._last.popitem(last=False)
        if last is None or sequence == last:
            return 0
        jump = sequence - last - 1
        if jump < 0 or jump > self.max_gap:
            self.restarts += 1
            return 0
        self.lost += jump
        return jump
