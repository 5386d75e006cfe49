"""
Live identifier core: in-order windows (replays under sim time) and run-time reconfiguration.

In-order mode (``backlog_windows`` > 0) fits every due window, stops each fit on ``maxiter`` and
seeds it from the window's index, so the estimate sequence of a stream does not depend on how
fast its samples arrive relative to the fits (the replay speed).
"""
import numpy as np
import pytest

from mr_damper_model.live import (DYNAMIC_FIELDS, fit_data, LiveConfig, LiveIdentifier,
                                  window_seed)

from live_records import cam_record, FAST, fed_fast, N_WINDOWS, sequence


@pytest.fixture(scope='module')
def record():
    return cam_record(currents=(0.0, 1.0, 2.0), hold_s=2.0)[0]


@pytest.mark.slow
def test_same_samples_fast_or_slow_give_the_same_estimate_sequence(record):
    slow = LiveIdentifier(LiveConfig(**FAST)).replay(record, every=1)
    fast_li = LiveIdentifier(LiveConfig(**FAST))
    fast = fed_fast(fast_li, record)
    assert len(slow) >= 8
    assert sequence(fast) == sequence(slow)
    c = fast_li.counters
    assert c['windows_due'] == N_WINDOWS
    assert c['windows_superseded'] == c['windows_overflow'] == c['samples_lost'] == 0
    # the wall-time budget plays no part: a huge or no budget gives the same sequence
    other = fed_fast(LiveIdentifier(LiveConfig(**dict(FAST, budget_s=1e-6))), record)
    assert sequence(other) == sequence(slow)


@pytest.mark.slow
def test_newest_window_mode_depends_on_the_pace(record):
    """The contrast: in real-time mode a fast feed supersedes windows (a different sequence)."""
    real_time = dict(FAST, backlog_windows=0, budget_s=0.0)
    slow = LiveIdentifier(LiveConfig(**real_time)).replay(record, every=1)
    li = LiveIdentifier(LiveConfig(**real_time))
    fast = fed_fast(li, record)
    assert li.counters['windows_superseded'] == N_WINDOWS - 1 and len(fast) == 1
    assert sequence(fast) != sequence(slow)


def test_each_window_is_fitted_with_its_own_seed_and_no_budget(record):
    calls = []

    def fit(data, model, config, x0=None):
        calls.append((config.seed, config.budget_s, config.maxiter))
        return fit_data(data, model, config, x0=x0)

    li = LiveIdentifier(LiveConfig(**dict(FAST, seed=7, budget_s=0.15)), fit=fit)
    seen = []
    for row in zip(record.t, record.x, record.v, record.f, record.i):
        li.add_sample(*row)
        window = li.next_window()
        if window is not None:
            seen.append(window.index)
            li.process(window)
    assert seen == list(range(N_WINDOWS))
    assert calls and all(b == 0.0 and m == 5 for _, b, m in calls)
    seeds = [s for s, _, _ in calls]
    assert set(seeds) <= {window_seed(7, m) for m in range(N_WINDOWS)}
    assert len(set(seeds)) == len(seeds)            # one fit per window, each its own seed
    assert window_seed(7, 3) == window_seed(7, 3) != window_seed(8, 3)


def test_backlog_overflow_is_counted_and_windows_stay_whole(record):
    # buffer: 2 windows + (3 + 1) hops at 1 kHz = 4 s (+16 samples) of the 6 s fed at once
    li = LiveIdentifier(LiveConfig(**dict(FAST, backlog_windows=1, max_rate_hz=1000.0)))
    for row in zip(record.t, record.x, record.v, record.f, record.i):
        li.add_sample(*row)
    sizes = []
    while (window := li.next_window()) is not None:
        sizes.append((window.index, window.data.n))
        li.process(window)
    c = li.counters
    # the oldest kept sample is at 1.984 s: windows 0-3 (starting before it) are passed over
    assert c['windows_overflow'] == 4 and c['windows_due'] == N_WINDOWS - 4
    assert [m for m, _ in sizes] == list(range(4, N_WINDOWS))
    assert all(n == 1000 for _, n in sizes)          # no window is cut short
    assert c['samples_lost'] == 6000 - (li._cap)      # overwritten before any window took them
    assert c['windows_superseded'] == 0


def test_reconfigure_applies_thresholds_and_names_refused_settings(record):
    li = LiveIdentifier(LiveConfig(**dict(FAST, backlog_windows=0, budget_s=0.0)))
    assert li.add_sample(0.0, 0.0, 0.0, 900.0, 1.0) == ''
    new = li.reconfigure(force_limit_n=800.0, max_nrmse_percent=5.0)
    assert new is li.config and li.config.force_limit_n == 800.0
    assert li.config.max_nrmse_percent == 5.0
    assert li.add_sample(0.001, 0.0, 0.0, 900.0, 1.0) == 'force_range'
    assert li.counters['out_of_range']['force'] == 1
    before = li.config
    with pytest.raises(ValueError, match='`window_s` is read at start-up'):
        li.reconfigure(window_s=3.0)
    with pytest.raises(ValueError, match='`current_limit_min_a`'):
        li.reconfigure(current_limit_min_a=3.0)        # above current_limit_max_a
    with pytest.raises(ValueError, match='`outlier_mad_k`'):
        li.reconfigure(outlier_mad_k=-1.0)
    with pytest.raises(ValueError, match='`foo` is not a LiveConfig setting'):
        li.reconfigure(foo=1.0)
    with pytest.raises(ValueError, match='read at start-up'):
        li.reconfigure(max_gap_s=0.1, seed=3)          # all or nothing
    assert li.config is before


def test_reconfigured_validity_threshold_takes_effect_on_the_next_window(record):
    li = LiveIdentifier(LiveConfig(**dict(FAST, backlog_windows=0, budget_s=0.0)))
    first = li.replay(record.select(slice(0, 2000)))
    assert first and first[-1].valid
    li.reconfigure(max_nrmse_percent=1e-3)            # below the 2 N noise: nothing passes
    strict = li.replay(record.select(slice(2000, 4000)))
    assert strict and all(e.reason == 'nrmse_above_threshold' for e in strict)
    li.reconfigure(max_nrmse_percent=10.0)
    loose = li.replay(record.select(slice(4000, None)))
    assert loose and loose[-1].valid


def test_dynamic_fields_are_settings():
    names = set(LiveConfig.__dataclass_fields__)
    assert set(DYNAMIC_FIELDS) <= names
    for start_up in ('window_s', 'hop_s', 'max_rate_hz', 'backlog_windows', 'seed', 'budget_s',
                     'maxiter', 'swarm_size', 'i_ref_a', 'current_bin_a', 'unbounded'):
        assert start_up not in DYNAMIC_FIELDS
    with pytest.raises(ValueError, match='backlog_windows'):
        LiveConfig(backlog_windows=-1)
    assert np.isfinite(LiveConfig(backlog_windows=3).window_s)
