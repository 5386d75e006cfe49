"""BatchIndex: exact lost-sample counts from the batches' stream index."""
from mr_damper_model.live.sample_stream import BatchIndex


def test_contiguous_batches_lose_nothing():
    index = BatchIndex()
    for k in range(10):
        assert index.update(20 * k, 20) == 0
    assert index.as_dict() == {'batches': 10, 'samples': 200, 'lost': 0, 'restarts': 0,
                               'skipped_at_start': 0}


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
