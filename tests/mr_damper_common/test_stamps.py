"""Tests of mr_damper_common.stamps: stamp sanity (future, order, duplicates, clock jumps)."""
import math

import numpy as np
import pytest

from mr_damper_model.live import LiveConfig, LiveIdentifier
from mr_damper_common.stamps import ACCEPTED, REBASED, STAMP_REFUSALS, StampGuard

NOW0 = 1.7e9          # a node clock on the epoch (ROS time)


def _offer_all(guard, stamps, nows):
    return [guard.offer(t, now) for t, now in zip(stamps, nows)]


def test_in_order_stream_is_accepted_and_counted():
    g = StampGuard(max_future_s=1.0, rebase_after=5)
    t = NOW0 + 1e-3 * np.arange(100)
    assert _offer_all(g, t, t + 2e-4) == [ACCEPTED] * 100
    assert g.n_accepted == 100 and g.n_refused == 0 and g.last == t[-1]
    assert g.status()['stamps_refused'] == dict.fromkeys(STAMP_REFUSALS, 0)


def test_one_future_stamp_is_refused_not_taken_as_reference():
    """The issue's fault: one stamp +1e6 s; the next valid stamps are in order."""
    for base in (NOW0, 0.0):         # stamped on the node clock, or on a car's own from 0 s
        g = StampGuard(max_future_s=1.0, rebase_after=5)
        t = base + 1e-3 * np.arange(1, 201)
        now = NOW0 + 1e-3 * np.arange(1, 201)
        verdicts = []
        for k in range(200):
            if k == 100:
                verdicts.append(g.offer(t[k] + 1e6, now[k]))
            else:
                verdicts.append(g.offer(t[k], now[k]))
        assert verdicts[100] == 'future_stamp'
        assert verdicts[:100] + verdicts[101:] == [ACCEPTED] * 199
        assert g.counts['future_stamp'] == 1 and g.n_refused == 1 and g.rebases == 0
        assert g.last == t[-1]


def test_first_stamp_in_the_future_of_the_node_clock():
    g = StampGuard(max_future_s=2.0)
    assert g.offer(NOW0 + 10.0, NOW0) == 'future_stamp'
    assert g.offer(NOW0 + 1.9, NOW0) == ACCEPTED      # within the horizon
    assert g.last == NOW0 + 1.9


def test_no_clock_means_no_future_check():
    """A simulated clock not started yet (0) or no clock: nothing is in the future."""
    for now in (None, 0.0, math.nan):
        g = StampGuard(max_future_s=1.0)
        assert g.offer(5e6, now) == ACCEPTED
        assert g.offer(5e6 + 1e5, now) == ACCEPTED


def test_forward_jump_within_the_horizon_is_in_order():
    g = StampGuard(max_future_s=1.0, rebase_after=3)
    assert g.offer(10.0, NOW0) == ACCEPTED
    assert g.offer(10.9, NOW0 + 0.001) == ACCEPTED      # +0.9 s in 1 ms of node time
    assert g.offer(20.0, NOW0 + 9.2) == ACCEPTED        # the clock advanced with it
    assert g.n_refused == 0 and g.rebases == 0


def test_horizon_follows_the_node_clock_not_the_stamp_rate():
    """A replay faster than the clock: each step small, so every stamp is in order."""
    g = StampGuard(max_future_s=0.5)
    t = np.arange(0, 60.0, 1e-3)
    now = NOW0 + t / 100.0                              # 100x faster than real time
    assert set(_offer_all(g, t, now)) == {ACCEPTED}


def test_forward_jump_beyond_the_horizon_is_followed_after_a_run():
    g = StampGuard(max_future_s=1.0, rebase_after=4)
    for k in range(10):
        assert g.offer(10.0 + 1e-3 * k, NOW0 + 1e-3 * k) == ACCEPTED
    jumped = [3610.0 + 1e-3 * k for k in range(6)]      # the vehicle clock jumped 1 h
    verdicts = [g.offer(t, NOW0 + 0.01 + 1e-3 * k) for k, t in enumerate(jumped)]
    assert verdicts == ['future_stamp'] * 3 + [REBASED, ACCEPTED, ACCEPTED]
    assert g.counts['future_stamp'] == 3 and g.rebases_forward == 1 and g.rebases == 1
    assert g.last_rebase == {'direction': 'forward', 'from_s': 10.009, 'to_s': jumped[3]}
    assert g.last == jumped[-1]


def test_future_stamps_that_are_not_a_clock_jump_never_re_base():
    """Junk stamps far ahead, not increasing plausibly among themselves: refused for good."""
    g = StampGuard(max_future_s=1.0, rebase_after=3)
    g.offer(10.0, NOW0)
    rng = np.random.default_rng(1)
    for k in range(50):
        junk = 1e6 + rng.uniform(0, 1e5)
        assert g.offer(junk, NOW0 + 1e-3 * k) == 'future_stamp'
    assert g.rebases == 0 and g.counts['future_stamp'] == 50


def test_backward_clock_jump_re_bases_after_the_run():
    g = StampGuard(max_future_s=1.0, rebase_after=5)
    for k in range(10):
        g.offer(100.0 + 1e-3 * k, NOW0 + 1e-3 * k)
    back = [50.0 + 1e-3 * k for k in range(8)]
    verdicts = [g.offer(t, NOW0 + 0.01 + 1e-3 * k) for k, t in enumerate(back)]
    assert verdicts == ['out_of_order'] * 4 + [REBASED] + [ACCEPTED] * 3
    assert g.counts['out_of_order'] == 4 and g.rebases_backward == 1
    assert g.last_rebase['direction'] == 'backward' and g.last_rebase['to_s'] == back[4]
    # one late stamp (not a run) is refused and does not re-base
    assert g.offer(back[-1] - 0.5, NOW0 + 0.02) == 'out_of_order'
    assert g.offer(back[-1] + 1e-3, NOW0 + 0.021) == ACCEPTED
    assert g.rebases == 1


def test_out_of_order_run_is_restarted_by_a_non_increasing_stamp():
    g = StampGuard(rebase_after=3)
    g.offer(10.0)
    assert [g.offer(t) for t in (5.0, 6.0, 5.5, 5.6)] == ['out_of_order'] * 4
    assert g.offer(5.7) == REBASED                       # 5.5, 5.6, 5.7: three increasing


def test_duplicates():
    g = StampGuard(rebase_after=2)
    g.offer(1.0)
    assert g.offer(1.0) == 'duplicate' and g.offer(1.0) == 'duplicate'
    assert g.counts['duplicate'] == 2 and g.rebases == 0
    eq = StampGuard(accept_equal=True)
    eq.offer(1.0)
    assert eq.offer(1.0) == ACCEPTED and eq.offer(0.5) == 'out_of_order'


def test_non_finite_stamps():
    g = StampGuard()
    g.offer(1.0)
    for bad in (math.nan, math.inf, -math.inf):
        assert g.offer(bad, NOW0) == 'non_finite'
    assert g.counts['non_finite'] == 3 and g.last == 1.0


def test_check_without_commit_keeps_the_reference():
    """A sample refused for another reason: the next stamp is judged against the old one."""
    g = StampGuard()
    g.offer(1.0)
    assert g.check(2.0) == ACCEPTED                     # not committed (out of range, say)
    assert g.offer(1.5) == ACCEPTED and g.last == 1.5


@pytest.mark.parametrize('kwargs, match', [
    (dict(max_future_s=0.0), 'max_future_s'), (dict(max_future_s=math.nan), 'max_future_s'),
    (dict(rebase_after=0), 'rebase_after'), (dict(rebase_after=2.5), 'rebase_after')])
def test_bad_settings_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        StampGuard(**kwargs)


def _random_stream(rng, n=3000):
    """Stamps with every fault: late, duplicate, backward and forward jumps, junk, NaN."""
    t, out = 0.0, []
    while len(out) < n:
        r = rng.uniform()
        if r < 0.01:
            t -= rng.uniform(0.5, 50.0)                 # clock jump back
        elif r < 0.015:
            t += rng.uniform(2.0, 100.0)                # clock jump forward
        t += 1e-3
        u = rng.uniform()
        if u < 0.03:
            out.append(t - rng.uniform(0, 0.05))        # a late one
        elif u < 0.05:
            out.append(out[-1] if out else t)           # a duplicate
        elif u < 0.06:
            out.append(t + rng.uniform(10, 1e6))        # junk far ahead
        elif u < 0.065:
            out.append(math.nan)
        else:
            out.append(t)
    return np.array(out)


def test_screen_equals_one_by_one_in_batches():
    rng = np.random.default_rng(7)
    stamps = _random_stream(rng)
    nows = NOW0 + 1e-3 * np.arange(stamps.size)
    seq = StampGuard(max_future_s=1.0, rebase_after=4)
    want = [seq.offer(t, now) for t, now in zip(stamps, nows)]
    bat = StampGuard(max_future_s=1.0, rebase_after=4)
    got, rebased, counts = [], [], dict.fromkeys(STAMP_REFUSALS, 0)
    k = 0
    while k < stamps.size:
        n = int(rng.integers(10, 51))
        res = bat.screen(stamps[k:k + n], nows[min(k + n, stamps.size) - 1])
        got.extend(res.accepted.tolist())
        rebased.extend(k + i for i in res.rebased_at)
        for r in STAMP_REFUSALS:
            counts[r] += res.counts[r]
        k += n
    # a batch has one now (its receipt): judge the sequence with the batch's now too
    ref = StampGuard(max_future_s=1.0, rebase_after=4)
    k, ref_verdicts = 0, []
    rng = np.random.default_rng(7)
    _random_stream(rng)
    while k < stamps.size:
        n = int(rng.integers(10, 51))
        now = nows[min(k + n, stamps.size) - 1]
        ref_verdicts.extend(ref.offer(t, now) for t in stamps[k:k + n])
        k += n
    assert got == [v in (ACCEPTED, REBASED) for v in ref_verdicts]
    assert rebased == [i for i, v in enumerate(ref_verdicts) if v == REBASED]
    assert counts == ref.counts == bat.counts
    assert bat.status() == ref.status()
    # the stream had every fault, and the per-stamp answer differs only by the batch's now
    assert all(ref.counts[r] > 0 for r in ('future_stamp', 'out_of_order', 'duplicate',
                                           'non_finite'))
    assert ref.rebases_backward > 0 and ref.rebases_forward > 0
    assert sum(v in (ACCEPTED, REBASED) for v in want) > 0.8 * stamps.size


def test_screen_fast_path_and_commit_mask():
    g = StampGuard(max_future_s=1.0)
    t = NOW0 + 1e-3 * np.arange(50)
    res = g.screen(t, NOW0 + 0.05)
    assert res.accepted.all() and res.n_refused == 0 and g.last == t[-1]
    assert g.n_accepted == 50
    # commit=False on the last two: accepted, but the reference stays on the one before
    t2 = t[-1] + 1e-3 * np.arange(1, 6)
    res = g.screen(t2, NOW0 + 0.06, commit=[True, True, True, False, False])
    assert res.accepted.all() and g.last == t2[2]
    with pytest.raises(ValueError, match='commit'):
        g.screen(t2, NOW0, commit=[True])
    with pytest.raises(ValueError, match='one-dimensional'):
        g.screen(np.zeros((2, 2)))
    assert g.screen([]).accepted.size == 0


def test_same_semantics_as_the_identifier_sample_rule():
    """
    ``LiveIdentifier.add_sample``'s stamp rule, sample for sample (restart_samples runs).

    With no horizon (``max_future_s=inf``) the guard, used as check, then range test, then
    commit, gives the identifier's verdicts and stream restarts on a stream with late,
    duplicate, out-of-range and non-finite samples and clock jumps back.
    """
    rng = np.random.default_rng(3)
    stamps = _random_stream(rng, 4000)
    f = np.where(rng.uniform(size=stamps.size) < 0.05, 9e3, 100.0)     # 5 % out of range
    cfg = LiveConfig(restart_samples=4)
    li = LiveIdentifier(cfg)
    g = StampGuard(max_future_s=math.inf, rebase_after=cfg.restart_samples)
    restarts = 0
    for t, fk in zip(stamps, f):
        want = li.add_sample(t, 0.0, 0.1, fk, 1.0)
        if not math.isfinite(t):
            got = 'nonfinite'                   # the identifier's all-field check comes first
        else:
            verdict = g.check(t)
            restarts += verdict == REBASED
            if verdict not in (ACCEPTED, REBASED):
                got = verdict
            elif fk > cfg.force_limit_n:
                got = 'force_range'
            else:
                g.commit(t)
                got = ''
        assert got == want
    assert restarts == li.counters['stream_restarts'] > 0
    for r in ('out_of_order', 'duplicate'):
        assert g.counts[r] == li.counters['rejected'][r] > 0


def test_stream_clock_judges_a_batch_as_a_whole_at_the_stream_rate():
    """A batch may reach the horizon past where the stream's own clock is, at any rate."""
    g = StampGuard(max_future_s=0.5, rebase_after=1000, stream_clock=True)
    # before any reference the stream's clock is unknown: nothing is in the future
    assert g.batch_verdict(5e6 + np.arange(20) * 1e-3, NOW0) == ACCEPTED
    g = StampGuard(max_future_s=0.5, rebase_after=1000, stream_clock=True)
    # a replay at 4x: 20 ms of stamps every 5 ms of node time, for 1 s
    for k in range(200):
        t = 100.0 + (20 * k + np.arange(20)) * 1e-3
        now = NOW0 + 5e-3 * (k + 1)
        assert g.batch_verdict(t, now) == ACCEPTED and g.screen(t, now).n_refused == 0
    assert g.rate == pytest.approx(4.0, rel=0.02)
    # 0.2 s of node time later the stream may be 0.8 s further, plus the horizon
    now = NOW0 + 1.2
    t = g.last + 0.8 + 0.5 - 1e-3 + np.arange(2) * 1e-4
    assert g.limit(now) == pytest.approx(g.last + 1.3)
    assert g.batch_verdict(t, now) == ACCEPTED
    # one batch whose samples follow each other at 1 ms but reach 100 s ahead: refused whole
    last = g.last
    far = last + 1e-3 + np.linspace(0.0, 100.0, 100_000)
    assert g.batch_verdict(far, now) == 'future_stamp'
    assert g.counts['future_stamp'] == 100_000 and g.last == last
    # the per-stamp horizon of a guard without stream_clock lets such a batch through
    plain = StampGuard(max_future_s=0.5)
    plain.offer(99.0, NOW0)
    assert plain.screen(far - far[0] + 99.001, NOW0).n_refused == 0
