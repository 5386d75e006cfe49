"""SequenceTracker: losses counted from the stream's own numbers."""
from mr_damper_common.sequence import SequenceTracker


def test_gaps_repeats_old_and_restart_are_counted_apart():
    tr = SequenceTracker()
    answers = [tr.offer(n) for n in (5, 6, 9, 9, 7, 10, 1, 2, 4)]
    # 5 first, 6 in order, 9 after two lost, 9 again, 7 older, 10 in order,
    # 1: the writer started again (not a loss), 2 in order, 4 after one lost
    assert answers == [0, 0, 2, -1, -1, 0, 0, 0, 1]
    assert tr.status() == {'received': 9, 'lost': 3, 'repeated': 1, 'out_of_order': 1,
                           'restarts': 1}
    assert tr.last == 4


def test_restart_threshold():
    tr = SequenceTracker(restart_below=10)
    tr.offer(100)
    assert tr.offer(8) == 0 and tr.restarts == 1
    assert tr.offer(50) == 41 and tr.lost == 41
    assert tr.offer(20) == -1 and tr.out_of_order == 1
