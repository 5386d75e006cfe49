"""BatchIndex: exact lost-sample counts from the batches' stream index."""
import numpy as np

from mr_damper_common.recording.batch_index import BatchIndex, MAX_JUMP_SAMPLES


def test_contiguous_batches_lose_nothing():
    index = BatchIndex()
    for k in range(10):
        assert index.update(20 * k, 20) == 0
    assert index.as_dict() == {'batches': 10, 'samples': 200, 'lost': 0, 'restarts': 0,
                               'jumps': 0, 'skipped_at_start': 0}


def test_a_missing_batch_counts_its_samples_and_a_late_reader_is_not_a_loss():
    index = BatchIndex()
    assert index.update(100, 20) == 0          # joined late: 100 samples before it
    assert index.update(120, 20) == 0
    assert index.update(160, 5) == 20          # batch 140..159 never arrived
    assert index.update(165, 1) == 0
    assert (index.lost, index.skipped_at_start, index.samples) == (20, 100, 46)


def test_an_index_going_back_is_a_publisher_restart():
    index = BatchIndex()
    index.update(0, 10)
    index.update(10, 10)
    assert index.update(0, 10) == 0            # the rig restarted
    assert index.update(30, 10) == 20          # and then lost two batches
    assert (index.restarts, index.lost) == (1, 20)


def _stamps(first, n, period=1e-3):
    return (first + np.arange(n)) * period


def test_an_index_jump_the_stamps_show_is_a_loss():
    index = BatchIndex()
    assert index.update(0, 20, _stamps(0, 20), 1e-3) == 0
    # 100 samples missing: the stamps step from 19 ms to 120 ms
    assert index.update(120, 20, _stamps(120, 20), 1e-3) == 100
    # the period from the stamps when the message has none (0: irregular)
    assert index.update(200, 20, _stamps(200, 20), 0.0) == 60
    assert (index.lost, index.restarts, index.jumps) == (160, 0, 0)


def test_an_absurd_index_jump_is_a_restart_and_the_count_stays_true():
    """One batch whose first_index jumps by 2**64 - 1 while its stamps go on: no loss."""
    index = BatchIndex()
    index.update(0, 20, _stamps(0, 20), 1e-3)
    assert index.update(2 ** 64 - 1, 20, _stamps(20, 20), 1e-3) == 0
    assert (index.lost, index.restarts, index.jumps) == (0, 1, 1)
    # the stream goes on from the new index: counted exactly again
    assert index.update(2 ** 64 + 19, 20, _stamps(40, 20), 1e-3) == 0
    assert index.update(2 ** 64 + 49, 20, _stamps(70, 20), 1e-3) == 10
    # and a batch back on the old index (the bad one was a stray): a restart, no loss
    assert index.update(90, 20, _stamps(90, 20), 1e-3) == 0
    assert (index.lost, index.restarts, index.jumps, index.batches) == (10, 2, 1, 5)


def test_without_stamps_only_jumps_beyond_the_bound_are_restarts():
    index = BatchIndex()
    index.update(0, 10)
    assert index.update(10 + MAX_JUMP_SAMPLES, 10) == MAX_JUMP_SAMPLES
    assert index.update(2 ** 64 - 1, 10) == 0
    assert (index.lost, index.restarts, index.jumps) == (MAX_JUMP_SAMPLES, 1, 1)
