"""
Live identifier core: a batch of samples is taken exactly as the same samples one by one.

One DamperSamples message is one batch: clean batches are taken with array operations, others
sample by sample, with the same counters, buffer and rejections.
"""
import numpy as np
import pytest

from mr_damper_model.live import LiveConfig, LiveIdentifier


def _stream(n, seed):
    """Return a 1 kHz stream with every kind of bad sample scattered through it."""
    rng = np.random.default_rng(seed)
    t = 100.0 + np.arange(n) * 1e-3
    x = 0.01 * np.sin(2 * np.pi * t)
    v = 0.02 * np.pi * np.cos(2 * np.pi * t)
    f = 800 * np.tanh(30 * v) + rng.normal(0, 2, n)
    i = np.full(n, 1.0)
    bad = rng.choice(n, size=n // 25, replace=False)
    kinds = rng.integers(0, 6, size=bad.size)
    for k, kind in zip(bad, kinds):
        if kind == 0:
            f[k] = np.nan
        elif kind == 1:
            f[k] = 1e30                       # force out of range
        elif kind == 2:
            t[k] = t[k - 1] if k else t[k]    # duplicate stamp
        elif kind == 3:
            t[k] -= 0.5                       # out of order
        elif kind == 4:
            i[k] = -5.0                       # current out of range
        else:
            t[k:] += 0.2                      # a stamp gap
    return t, x, v, f, i


def _state(li):
    n = li._count
    idx = (li._head - n + np.arange(n)) % li._cap
    stamps = (li._seq, li._last_t, li._t_origin, li._stamps._ooo_run)
    return li.counters, li._buf[idx].copy(), stamps


@pytest.mark.parametrize('batch', [1, 7, 20, 50])
def test_batches_give_the_sample_by_sample_result(batch):
    config = LiveConfig(window_s=0.5, hop_s=0.1, max_rate_hz=1000.0, restart_samples=5)
    t, x, v, f, i = _stream(3000, seed=batch)
    one = LiveIdentifier(config)
    reasons = [one.add_sample(*row) for row in zip(t, x, v, f, i)]
    many = LiveIdentifier(config)
    rejected = []
    for k in range(0, t.size, batch):
        part = slice(k, k + batch)
        rejected += [(k + j, r) for j, r in many.add_samples(t[part], x[part], v[part],
                                                             f[part], i[part])]
    assert rejected == [(k, r) for k, r in enumerate(reasons) if r]
    assert len(rejected) > 50                 # the stream did exercise the slow path
    c1, buf1, s1 = _state(one)
    c2, buf2, s2 = _state(many)
    assert c1 == c2 and s1 == s2
    np.testing.assert_array_equal(buf1, buf2)


def test_a_batch_larger_than_the_buffer_keeps_the_newest_and_counts_the_rest_lost():
    config = LiveConfig(window_s=0.05, hop_s=0.01, max_rate_hz=1000.0)
    li = LiveIdentifier(config)
    n = li._cap + 500
    t = np.arange(n) * 1e-3
    z = np.zeros(n)
    assert li.add_samples(t, z, z, z, z) == []
    assert li.counters['samples_accepted'] == n
    assert li._count == li._cap and li._last_t == t[-1]
    window = li.next_window()
    assert window is not None
    # everything that left the buffer before a window took it is counted lost
    assert li.counters['samples_lost'] == n - li._cap


def test_one_future_sample_costs_one_sample_and_a_clock_jump_is_followed():
    """Stamps on the node clock (max_future_s): a future stamp, a backward and a forward jump."""
    config = LiveConfig(window_s=0.5, hop_s=0.1, max_rate_hz=1000.0, restart_samples=20,
                        max_future_s=1.0)
    li = LiveIdentifier(config)
    t = 1000.0 + np.arange(100) * 1e-3
    z = np.zeros(100)
    assert li.add_samples(t, z, z, z, z, now=t[-1]) == []
    # one sample stamped 1e6 s ahead: refused, not the new reference
    assert li.add_sample(t[-1] + 1e6, 0.0, 0.0, 0.0, 0.0, now=t[-1]) == 'future_stamp'
    t2 = t[-1] + 1e-3 + np.arange(50) * 1e-3
    assert li.add_samples(t2, z[:50], z[:50], z[:50], z[:50], now=t2[-1]) == []
    c = li.counters
    assert c['rejected']['future_stamp'] == 1 and c['samples_accepted'] == 150
    # the vehicle clock jumps back 100 s: refused until restart_samples increasing ones
    back = t2[-1] - 100.0 + np.arange(40) * 1e-3
    rejected = li.add_samples(back, z[:40], z[:40], z[:40], z[:40], now=back[-1])
    assert [r for _, r in rejected] == ['out_of_order'] * 19
    assert c['stream_restarts'] == 1 and li._last_t == back[-1]
    # a forward jump within the horizon is simply in order
    ahead = back[-1] + 0.5 + np.arange(10) * 1e-3
    assert li.add_samples(ahead, z[:10], z[:10], z[:10], z[:10], now=back[-1]) == []
    # a forward jump beyond it: refused, then followed after restart_samples plausible ones
    far = ahead[-1] + 50.0 + np.arange(30) * 1e-3
    rejected = [li.add_sample(s, 0.0, 0.0, 0.0, 0.0, now=ahead[-1] + k * 1e-3)
                for k, s in enumerate(far)]
    assert rejected[:19] == ['future_stamp'] * 19 and set(rejected[19:]) == {''}
    assert c['stream_restarts'] == 2 and li._stamps.rebases_forward == 1


def test_without_a_horizon_replays_ahead_of_the_clock_are_taken():
    li = LiveIdentifier(LiveConfig(window_s=0.5, hop_s=0.1, max_rate_hz=1000.0))
    t = np.arange(100) * 1e-3 + 1e9            # far ahead of a clock at 1.0 s
    z = np.zeros(100)
    assert li.add_samples(t, z, z, z, z, now=1.0) == []
    assert li.counters['rejected']['future_stamp'] == 0
