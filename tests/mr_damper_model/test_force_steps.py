"""
Force steps in a set's own fit data (issue 32): a sensor offset in the first windows of a stream.

The acceptance rules compare a new set with the set in use; a fault that arrives before a good
set exists has nothing to be compared with.  ``force_step`` needs no earlier set: the mean
forces of comparable whole cycles (fast excitation) and a lasting mid-stroke jump of the set's
residual (slow strokes).
"""
import numpy as np
import pytest

from live_records import cam_record, replay_published
from mr_damper_model.io.data import DamperData
from mr_damper_model.live import LiveConfig, LiveIdentifier
from mr_damper_model.live.screening import (cycle_mean_spread, force_step, level_runs,
                                            mid_stroke_jump)
from mr_damper_model.models.kwok_current import kwok_current_force


def _sine(freq_hz, rate_hz, seconds, amp_m=0.01, noise_n=1.0, seed=0):
    """Sine motion and a Kwok-like force (asymmetric, hysteretic) with noise."""
    t = np.arange(int(round(seconds * rate_hz))) / rate_hz
    w = 2 * np.pi * freq_hz
    x, v = amp_m * np.sin(w * t), amp_m * w * np.cos(w * t)
    f = (800.0 * v + 5e3 * x + 300.0 * np.tanh(40.0 * v + 0.5 * np.sign(x)) + 20.0
         + noise_n * np.random.default_rng(seed).standard_normal(t.size))
    return t, x, v, f


def test_cycle_means_of_the_same_motion_agree_and_an_offset_moves_them():
    t, x, v, f = _sine(3.0, 1000.0, 2.0)
    assert cycle_mean_spread(x, v, f) < 1.0                 # noise: 1 N per sample
    g = f + np.where(t >= 1.0, 300.0, 0.0)                  # an offset from 1 s on
    # the cycles wholly before and wholly after it differ by the offset
    assert cycle_mean_spread(x, v, g) == pytest.approx(300.0, abs=2.0)


def test_cycles_of_another_amplitude_are_not_compared():
    """A start from rest: the damper's asymmetry moves the cycle mean, no offset does."""
    t, x, v, f = _sine(3.0, 1000.0, 2.0)
    ramp = np.clip(t / 1.0, 0.0, 1.0)                       # the amplitude grows for 1 s
    x, v = x * ramp, v * ramp
    f = 800.0 * v + 5e3 * x + 300.0 * np.tanh(40.0 * v + 0.5 * np.sign(x)) + 20.0 + 50.0 * ramp
    # the mean moves by 50 N over the ramp; only its last cycles (within 5 % of the full
    # amplitude) are compared with the steady ones
    assert cycle_mean_spread(x, v, f) < 0.2 * 50.0
    assert np.isnan(cycle_mean_spread(x[:400], v[:400], f[:400]))   # fewer than 2 cycles


def test_a_lasting_mid_stroke_jump_is_found_in_slow_strokes():
    t, x, v, _ = _sine(0.25, 200.0, 2.0, amp_m=0.025)
    resid = np.random.default_rng(1).standard_normal(t.size)
    mid = 40                                                 # 0.2 s: 95 % of full speed
    stepped = resid + np.where(np.arange(t.size) >= mid, 200.0, 0.0)
    assert mid_stroke_jump(t, v, stepped) == pytest.approx(200.0, abs=5.0)
    assert mid_stroke_jump(t, v, resid) < 5.0
    # a jump that does not last (a spike) or at a reversal (the force rises fast there) is none
    spike = resid.copy()
    spike[mid] += 200.0
    assert mid_stroke_jump(t, v, spike) < 5.0
    rev = 200                                                # 1 s: the stroke's end
    assert mid_stroke_jump(t, v, resid + np.where(np.arange(t.size) >= rev, 200.0, 0.0)) < 5.0


def test_coarsely_sampled_fast_motion_is_left_to_the_cycles():
    t, x, v, _ = _sine(5.0, 200.0, 2.0)                     # 40 samples per cycle
    jump = np.where(np.arange(t.size) >= 150, 200.0, 0.0)
    assert mid_stroke_jump(t, v, jump) == 0.0


def test_force_step_reason_names_the_level_and_can_be_switched_off():
    t, x, v, f = _sine(3.0, 1000.0, 2.0)
    g = f + np.where(t >= 1.0, 300.0, 0.0)
    data = DamperData(t, x, v, g, np.full(t.size, 0.5))
    config = LiveConfig()
    assert force_step(data, np.zeros(t.size), config) == 'force_step:0.5'
    assert force_step(DamperData(t, x, v, f, data.i), np.zeros(t.size), config) == ''
    assert force_step(data, np.zeros(t.size), LiveConfig(force_step_percent=0.0)) == ''
    # levels are judged apart, each in time order
    two = DamperData(np.r_[t, t + 10.0], np.r_[x, x], np.r_[v, v], np.r_[f, f],
                     np.r_[np.full(t.size, 0.0), np.full(t.size, 1.0)])
    assert [r.size for r in level_runs(two, 0.1, 0.05)] == [t.size, t.size]


@pytest.mark.slow
def test_an_offset_in_the_first_windows_never_becomes_the_set_in_use():
    """
    A 200 N offset from 1.5 s to 2.5 s of a stream: no valid set before a set exists.

    Without the check (``force_step_percent`` 0, the rules before) the first window's set,
    fitted on 0.5 s of the offset, is taken, and the held-back samples it was fitted on keep
    it in use for the rest of the record; with the check every window holding 0.5 s or more
    of the offset is refused, and the sets after it are the damper's.
    """
    data, model, truth = cam_record(currents=(1.0,), hold_s=7.0, noise_n=2.0)
    faulted = DamperData(data.t, data.x, data.v,
                         data.f + np.where((data.t >= 1.5) & (data.t < 2.5), 200.0, 0.0),
                         data.i)

    def error(est):
        f = kwok_current_force(dict(est.parameters, i_ref_a=2.0), data.x, data.v, data.i)
        return float(np.sqrt(np.mean((f - data.f) ** 2)))

    def overlap(end):
        return max(0.0, min(end, 2.5) - max(end - 2.0, 1.5))

    def in_use(published, end):
        return [est for e, est in published if e <= end + 1e-9][-1]

    before = replay_published(LiveIdentifier(LiveConfig(backlog_windows=300,
                                                        force_step_percent=0.0)), faulted)
    assert before[0][1].valid and overlap(before[0][0]) == pytest.approx(0.5)
    assert error(in_use(before, 5.0)) > 10.0              # 2.5 s after the offset: still its set
    li = LiveIdentifier(LiveConfig(backlog_windows=300))
    after = replay_published(li, faulted)
    for end, est in after:
        if overlap(end) >= 0.5:
            assert not est.valid and est.reason == 'force_step:1'
    assert li.counters['windows_refused']['force_step'] >= 9
    assert error(in_use(after, 5.0)) < 3.0                  # the noise is 2 N
