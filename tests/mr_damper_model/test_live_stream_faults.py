"""
Live identifier: one message cannot poison the stream (issue 32).

A batch stamped ahead of the stream (100 s of samples in one message), a batch whose stream
index jumps, a batch whose force the set in use cannot explain: each is refused or counted,
never fitted into a valid set, and the stream goes on.
"""
import numpy as np
import pytest

from live_records import cam_record
from mr_damper_model.live import LiveConfig, LiveIdentifier
from mr_damper_model.live.worker import IdentifierRuntime

BATCH = 20


def _feed(li, data, rate_factor, *, t_wall0=50.0, bunch=1, fit=True):
    """
    Feed ``data`` in batches of 20 as a rig at ``rate_factor`` would; return (estimates, now).

    The node clock is wall time: a batch arrives when its last sample is due
    (``t_wall0 + (t - t0) / rate_factor``), ``bunch`` batches together (a delayed delivery:
    each when the bunch's last one is due). Rate factor 0: the clock advances 1 ms per batch
    whatever the stamps (a replay as fast as the reader takes it). ``now``: the clock at the
    last batch.
    """
    ests, now = [], t_wall0
    t0 = float(data.t[0])
    n_batches = -(-data.n // BATCH)
    for j in range(n_batches):
        s = slice(j * BATCH, (j + 1) * BATCH)
        last = min(j - j % bunch + bunch, n_batches)          # batches up to the bunch's end
        now = (t_wall0 + (float(data.t[min(last * BATCH, data.n) - 1]) - t0) / rate_factor
               if rate_factor else t_wall0 + 1e-3 * last)
        li.add_samples(data.t[s], data.x[s], data.v[s], data.f[s], data.i[s], now=now)
        window = li.next_window() if fit else None
        if window is not None:
            est = li.process(window)
            if est is not None:
                ests.append(est)
    return ests, now


def _future_batch(after_s, model, truth):
    """Return the issue's batch: 100 000 samples, 3x the force at 1 A, stamped 0-100 s ahead."""
    n = 100_000
    t = after_s + 1e-3 + np.linspace(0.0, 100.0, n)
    w = 2 * np.pi * 1.1
    x = 0.03 * np.sin(w * t)
    v = 0.03 * w * np.cos(w * t)
    i = np.full(n, 1.0)
    p = np.array([truth[k] for k in model.param_names])
    return t, x, v, 3.0 * model.force(p, x, v, i=i), i


CONFIG = dict(window_s=1.0, hop_s=0.5, maxiter=5, swarm_size=10, budget_s=0.0)


@pytest.mark.slow
@pytest.mark.parametrize('rate_factor,bunch', [(1.0, 1), (4.0, 5), (0.0, 3)])
def test_a_batch_stamped_100_s_ahead_is_refused_at_every_rate_factor(rate_factor, bunch):
    """
    The batch is refused whole, at real time, at 4x on wall time and as fast as read.

    Before: ``max_future_s`` was 0 (off) by default, the batch was taken, carried the stream
    100 s ahead, the live samples were refused as out of order until the stream restarted, and
    a set fitted on the injected samples alone was published valid.
    """
    data, model, truth = cam_record(currents=(0.5,) * 4, hold_s=2.0, t0=1000.0)
    li = LiveIdentifier(LiveConfig(**CONFIG))
    first, rest = data.select(slice(0, 4000)), data.select(slice(4000, None))
    ests, now = _feed(li, first, rate_factor, bunch=bunch)
    rejected = li.add_samples(*_future_batch(float(first.t[-1]), model, truth), now=now)
    assert len(rejected) == 100_000 and {r for _, r in rejected} == {'future_stamp'}
    more, _ = _feed(li, rest, rate_factor, bunch=bunch,
                    t_wall0=now + (20e-3 / rate_factor if rate_factor else 1e-3))
    ests += more
    c = li.counters
    assert c['rejected']['future_stamp'] == 100_000
    assert c['rejected']['out_of_order'] == 0 and c['stream_restarts'] == 0
    assert c['samples_accepted'] == data.n
    # every estimate is of the live stream: 0.5 A, its own windows
    assert ests and all(e.current_max_a == pytest.approx(0.5) for e in ests)
    assert max(e.window_end_s for e in ests) <= data.t[-1]


@pytest.mark.parametrize('rate_factor', [1.0, 4.0, 0.0])
@pytest.mark.parametrize('bunch', [1, 10])
def test_a_clean_stream_is_never_in_the_future_whatever_its_rate(rate_factor, bunch):
    """The horizon is on the stream's clock: 4x wall time or bursts of batches are no fault."""
    data, _, _ = cam_record(currents=(0.5,), hold_s=4.0, t0=1.7e9)
    li = LiveIdentifier(LiveConfig(window_s=1.0, hop_s=0.5, max_future_s=0.1))
    _feed(li, data, rate_factor, bunch=bunch, fit=False)
    assert li.counters['rejected']['future_stamp'] == 0
    assert li.counters['samples_accepted'] == data.n
    # the measured rate: stamps per node second (rate factor 0: 20 ms of stamps per 1 ms)
    assert li._stamps.rate == pytest.approx(rate_factor or 20.0, rel=0.1)


def test_a_stream_that_really_jumps_ahead_is_followed_after_restart_samples():
    """Consecutive batches 100 s ahead that follow each other: a restart, not a refusal."""
    config = LiveConfig(window_s=0.5, hop_s=0.1, max_rate_hz=1000.0, restart_samples=100)
    li = LiveIdentifier(config)
    z = np.zeros(BATCH)
    for k in range(20):
        t = 10.0 + (k * BATCH + np.arange(BATCH)) * 1e-3
        assert li.add_samples(t, z, z, z, z, now=500.0 + t[-1]) == []
    t_jump = 110.0
    verdicts = []
    for k in range(10):
        t = t_jump + (k * BATCH + np.arange(BATCH)) * 1e-3
        verdicts.append(len(li.add_samples(t, z, z, z, z, now=500.0 + 10.4 + t[-1] - t_jump)))
    # 80 samples refused (4 batches); the fifth brings the run to restart_samples and
    # re-bases the stream (as a run of single samples: the restart_samples-th is taken)
    assert verdicts == [BATCH] * 4 + [0] * 6
    c = li.counters
    assert c['rejected']['future_stamp'] == 80 and c['stream_restarts'] == 1
    assert li._last_t == pytest.approx(t_jump + 199e-3)


def test_a_refused_batch_takes_no_place_in_the_stream_index():
    runtime = IdentifierRuntime(LiveIdentifier(LiveConfig(window_s=0.5, hop_s=0.1)),
                                clock=lambda: 77.0)
    z = np.zeros(BATCH)
    t = 10.0 + np.arange(BATCH) * 1e-3
    assert runtime.receive_batch(t, z, z, z, z, first_index=0, period_s=1e-3) == []
    far = t[-1] + 50.0 + np.arange(BATCH) * 1e-3
    assert len(runtime.receive_batch(far, z, z, z, z, first_index=BATCH, period_s=1e-3)) == BATCH
    assert runtime.receive_batch(t + 0.02, z, z, z, z, first_index=BATCH, period_s=1e-3) == []
    assert runtime.stream.as_dict() == {'batches': 2, 'samples': 2 * BATCH, 'lost': 0,
                                        'restarts': 0, 'jumps': 0, 'skipped_at_start': 0}


def test_an_absurd_first_index_is_a_stream_restart_not_lost_samples():
    """One batch with first_index 2**64 - 1: stream.lost stays 0 (was 1.8e19 for good)."""
    runtime = IdentifierRuntime(LiveIdentifier(LiveConfig(window_s=0.5, hop_s=0.1)),
                                clock=lambda: 77.0)
    z = np.zeros(BATCH)
    index = [0, BATCH, 2 ** 64 - 1, 2 * BATCH, 3 * BATCH + 10]
    for k, first in enumerate(index):
        t = 10.0 + (k * BATCH + np.arange(BATCH)) * 1e-3 + (10e-3 if k == 4 else 0.0)
        runtime.receive_batch(t, z, z, z, z, first_index=first, period_s=1e-3)
    s = runtime.stream.as_dict()
    assert (s['lost'], s['restarts'], s['jumps']) == (10, 2, 1)
    assert runtime.live.counters['samples_accepted'] == 5 * BATCH


def _two_level_identifier():
    """Return an identifier that took valid sets of a 0.5 A / 1 A cam record for 5 s."""
    data, model, truth = cam_record(currents=(0.5, 1.0) * 4, hold_s=1.0, t0=1000.0)
    li = LiveIdentifier(LiveConfig(backlog_windows=50, maxiter=10, budget_s=0.0))
    ests, now = _feed(li, data.select(slice(0, 5000)), 1.0, t_wall0=1000.0)
    assert ests and ests[-1].valid and ests[-1].current_max_a == pytest.approx(1.0)
    return li, data, model, truth, ests, now


@pytest.mark.slow
def test_a_batch_the_set_in_use_cannot_explain_is_refused_before_it_displaces_the_stream():
    """
    One batch of 1 s at 1 A with 3x the force, stamped where the stream goes on: refused whole.

    Before: the batch was taken, the live samples of the same second were refused as out of
    order until ``restart_samples`` of them restarted the stream, which dropped the reference,
    the bins and the set in use.
    """
    li, data, model, truth, ests, now = _two_level_identifier()
    t = data.t[4999] + 1e-3 * (1 + np.arange(1000))
    w = 2 * np.pi * 1.1
    x, v = 0.03 * np.sin(w * (t - 1000.0)), 0.03 * w * np.cos(w * (t - 1000.0))
    i = np.full(1000, 1.0)
    f = 3.0 * model.force(np.array([truth[k] for k in model.param_names]), x, v, i=i)
    rejected = li.add_samples(t, x, v, f, i, now=now)
    assert len(rejected) == 1000 and {r for _, r in rejected} == {'inconsistent_batch'}
    more, _ = _feed(li, data.select(slice(5000, None)), 1.0, t_wall0=now + 1e-3)
    c = li.counters
    assert c['rejected']['inconsistent_batch'] == 1000
    assert c['rejected']['out_of_order'] == 0 and c['stream_restarts'] == 0
    assert c['samples_accepted'] == data.n
    # the sets after it are the stream's: close to the ones before
    for est in more:
        assert est.valid
        for name in ('c0', 'c1', 'alpha0', 'alpha1'):
            assert est.parameters[name] == pytest.approx(ests[-1].parameters[name], rel=0.1)


@pytest.mark.slow
def test_a_lasting_change_goes_on_to_the_window_gate_after_max_gap_s():
    """A persistent +400 N offset: batches refused for max_gap_s only, then judged by windows."""
    li, data, _, _, _, now = _two_level_identifier()
    rest = data.select(slice(5000, None))
    shifted = type(rest)(rest.t, rest.x, rest.v, rest.f + 400.0, rest.i)
    _feed(li, shifted, 1.0, t_wall0=now + 1e-3)
    c = li.counters
    # 50 ms of samples (max_gap_s) at most refused as they arrived; the rest reached the
    # buffer, where the gate kept them out of the bins (no valid set from the offset)
    assert 0 < c['rejected']['inconsistent_batch'] <= 60
    assert c['samples_flagged']['inconsistent'] > 2000
    assert c['windows_skipped']['gap'] == 0


@pytest.mark.slow
def test_a_batch_with_a_spike_is_taken_for_the_outlier_screen():
    """One in-range spike in a batch: the batch is consistent; the spike is flagged alone."""
    li, data, _, _, _, now = _two_level_identifier()
    rest = data.select(slice(5000, None))
    f = rest.f.copy()
    f[np.arange(10) * 173 + 45] = 3000.0            # ten single-sample spikes
    _feed(li, type(rest)(rest.t, rest.x, rest.v, f, rest.i), 1.0, t_wall0=now + 1e-3)
    c = li.counters
    assert c['rejected']['inconsistent_batch'] == 0
    assert c['samples_accepted'] == data.n
    assert 10 <= c['samples_flagged']['outlier'] <= 12
