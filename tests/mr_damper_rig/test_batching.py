"""
The rig's measurement batches (BatchStream) with an injected clock.

Which samples go out in which message, exact sequence and stream indices, the end of a finite
record, a refused publish sent again, flow control and hardware-in-the-loop single samples.
"""
import numpy as np
import pytest

from mr_damper_common.recording.batch_index import BatchIndex
from mr_damper_model.io.data import DamperData
from mr_damper_rig.batching import BatchStream
from mr_damper_rig.pacing import LockstepPacer, Pacer
from mr_damper_rig.replay import ArraySource

from fake_clock import FakeClock


def source(n=1000, rate_hz=1000.0):
    t = np.arange(n) / rate_hz + 5.0
    return ArraySource(DamperData(t, t * 2, t * 3, t * 4, t * 5))


class Wire:
    """A publish callback that records the batches (and can refuse some)."""

    def __init__(self, refuse=()):
        self.batches = []
        self.refuse = set(refuse)
        self.calls = 0

    def __call__(self, t, x, v, f, i, sequence, first_index):
        self.calls += 1
        if self.calls in self.refuse:
            return False
        self.batches.append((sequence, first_index, t, x))
        return True


def test_full_batches_go_out_when_their_last_sample_is_due_and_the_rest_at_the_end():
    clock = FakeClock()
    src = source(n=1010)
    pacer = Pacer(src, 1.0, clock=clock)
    stream = BatchStream(src, pacer, 20)
    wire = Wire()
    assert not pacer.waiting(1)
    for _ in range(600):              # 0.2 s ticks of 2 ms: samples due up to record time
        clock.t += 0.002
        stream.tick(wire)
        due = pacer.source.count_due(pacer.record_time_s())
        # every complete batch of the samples due is out, no partial one before the end
        assert pacer.published == min((min(due, 1010) // 20) * 20, 1010) or pacer.finished
    assert pacer.finished and stream.pending == 0
    sizes = [b[2].size for b in wire.batches]
    assert sizes == [20] * 50 + [10]                       # the end flushes the remainder
    assert [b[0] for b in wire.batches] == list(range(51))
    assert [b[1] for b in wire.batches] == [20 * k for k in range(51)]
    t = np.concatenate([b[2] for b in wire.batches])
    np.testing.assert_array_equal(t, src.t)                # every sample once, in order
    np.testing.assert_array_equal(np.concatenate([b[3] for b in wire.batches]), src.t * 2)


def test_a_refused_publish_is_sent_again_with_the_same_sequence_and_index():
    clock = FakeClock()
    src = source(n=200)
    pacer = Pacer(src, 1.0, clock=clock)
    stream = BatchStream(src, pacer, 25)
    wire = Wire(refuse={3, 4})        # the writer is replaced for two attempts
    pacer.waiting(1)
    for _ in range(200):
        clock.t += 0.002
        stream.tick(wire)
    assert [b[0] for b in wire.batches] == list(range(8))
    index = BatchIndex()
    for _, first, t, _ in wire.batches:
        index.update(first, t.size)
    assert index.lost == 0 and index.samples == 200


def test_flow_control_sends_every_due_sample_at_once():
    clock = FakeClock()
    src = source(n=1000)
    pacer = Pacer(src, 0.0, clock=clock, flow_window=45)
    stream = BatchStream(src, pacer, 20)
    wire = Wire()
    pacer.on_flow(0)
    pacer.waiting(1)
    stream.tick(wire)
    assert [b[2].size for b in wire.batches] == [20, 20, 5]    # the window, not whole batches
    pacer.on_flow(45)
    stream.tick(wire)
    assert pacer.published == 90


def test_lockstep_samples_go_one_per_message_and_a_refused_one_counts_as_lost():
    clock = FakeClock()
    t = np.arange(10) * 1e-3
    src = ArraySource(DamperData(t, t, t, t, t))
    pacer = LockstepPacer(1000.0, 0.05, clock=clock)
    stream = BatchStream(src, pacer, 20)
    wire = Wire(refuse={2})
    for _ in range(4):
        pacer.command()
        stream.publish_one(wire)
    assert pacer.published == 4
    assert [(b[0], b[1], b[2].size) for b in wire.batches] == [(0, 0, 1), (1, 2, 1), (2, 3, 1)]
    index = BatchIndex()
    for _, first, ts, _ in wire.batches:
        index.update(first, ts.size)
    assert index.lost == 1


def test_lockstep_samples_also_go_out_in_whole_batches_on_the_measurement_stream():
    clock = FakeClock()
    t = np.arange(10) * 1e-3
    src = ArraySource(DamperData(t, 2 * t, t, t, t))
    pacer = LockstepPacer(1000.0, 0.05, clock=clock)
    stream = BatchStream(src, pacer, 4)
    link, batches = Wire(), Wire()
    for k in range(10):
        pacer.command()
        stream.publish_one(link)
        stream.publish_full(batches)
        assert len(batches.batches) == (k + 1) // 4       # a batch once 4 samples are there
    assert [(b[0], b[1], b[2].size) for b in batches.batches] == [(0, 0, 4), (1, 4, 4)]
    np.testing.assert_array_equal(np.concatenate([b[3] for b in batches.batches]), 2 * t[:8])
    np.testing.assert_array_equal(np.concatenate([b[3] for b in link.batches]), 2 * t)
    assert pacer.published == 10 and stream.pending == 2


def test_samples_per_message_must_be_positive():
    with pytest.raises(ValueError, match='samples_per_message'):
        BatchStream(source(), Pacer(source(), 1.0), 0)
