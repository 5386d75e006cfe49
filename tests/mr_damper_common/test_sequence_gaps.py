"""Tests of mr_damper_common.sequence_gaps: messages lost, counted from their own numbers."""
import numpy as np
import pytest

from mr_damper_common.sequence_gaps import SequenceGaps


def _offer_all(gaps, numbers, stream=''):
    return [gaps.offer(k, stream) for k in numbers]


def test_random_drops_are_counted_exactly():
    """A stream of 10,000 with a known random 30 % dropped: every dropped message is counted."""
    rng = np.random.default_rng(7)
    published = np.arange(10_000)
    kept = published[rng.random(published.size) > 0.3]
    gaps = SequenceGaps()
    lost = _offer_all(gaps, kept)
    # the messages before the first one received were never meant for this reader
    truth = int(kept[-1] - kept[0] + 1 - kept.size)
    assert sum(lost) == gaps.lost == truth and gaps.received == kept.size
    assert gaps.restarts == 0


def test_first_message_repeats_restarts_and_absurd_jumps_count_nothing():
    gaps = SequenceGaps(max_gap=1000)
    assert _offer_all(gaps, [500, 501, 501, 504]) == [0, 0, 0, 2]   # joined late; 502, 503 lost
    assert _offer_all(gaps, [0, 1, 3]) == [0, 0, 1]                  # publisher restarted
    assert gaps.offer(3 + 1002) == 0                                 # absurd: not 1001 lost
    assert gaps.offer(1006) == 0 and gaps.offer(1008) == 1
    assert gaps.lost == 4 and gaps.restarts == 2 and gaps.received == 10


def test_a_publisher_that_leaves_sequence_at_zero_is_not_counted():
    gaps = SequenceGaps()
    assert _offer_all(gaps, [0] * 50) == [0] * 50
    assert gaps.lost == 0 and gaps.restarts == 0


def test_streams_are_counted_apart_and_memory_is_bounded():
    gaps = SequenceGaps(max_streams=2)
    assert _offer_all(gaps, [0, 2], 'fl') == [0, 1]
    assert _offer_all(gaps, [10, 13], 'fr') == [0, 2]
    assert gaps.offer(3, 'fl') == 0                     # interleaved streams: no false losses
    gaps.offer(0, 'rl')                                 # a third stream: 'fr' (oldest) forgotten
    assert len(gaps._last) == 2
    assert gaps.offer(20, 'fr') == 0                    # seen anew: nothing counted
    assert gaps.lost == 3


def test_bad_limits_are_refused():
    with pytest.raises(ValueError, match='max_gap'):
        SequenceGaps(max_gap=0)
