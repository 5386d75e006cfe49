"""Tests of semi_active_control.supervision.failsafe: the model supervisor of the controllers."""
import math
import subprocess
import sys

import numpy as np
import pytest

from mr_damper_model.models import get_model
from semi_active_control.supervision.failsafe import (clip_current, KWOK_CURRENT_NAMES,
                                                      ModelSupervisor, SupervisorError)

BOUNDS = {
    'c0': (0.0, 1e4), 'c1': (0.0, 1e4), 'k': (-1e4, 1e4), 'alpha0': (0.0, 2e3),
    'alpha1': (0.0, 2e3), 'alpha2': (0.0, 2e3), 'beta0': (0.1, 1e3), 'beta1': (-3.0, 3.0),
    'delta': (-3.0, 3.0), 'f0': (-200.0, 200.0),
}
GOOD = {
    'c0': 800.0, 'c1': 2000.0, 'k': 500.0, 'alpha0': 60.0, 'alpha1': 400.0, 'alpha2': 300.0,
    'beta0': 40.0, 'beta1': 0.2, 'delta': 0.3, 'f0': 5.0, 'i_ref_a': 2.0, 'window_end_s': 3.0,
    'current_min_a': 0.0, 'current_max_a': 2.0, 'rmse_n': 10.0, 'nrmse_percent': 2.0,
    'valid': 1.0,
}


def make(**kw):
    kw.setdefault('bounds', BOUNDS)
    kw.setdefault('timeout_s', 1.0)
    kw.setdefault('safe_current_a', 0.5)
    return ModelSupervisor(**kw)


def with_(**changes):
    msg = dict(GOOD)
    msg.update(changes)
    return msg


def test_starts_in_failsafe_and_leaves_on_first_valid():
    sup = make()
    assert sup.update(0.0) == 'failsafe'
    assert sup.reason == 'no_parameters_yet'
    assert sup.active is None
    verdict = sup.offer(GOOD, 0.25)
    assert verdict.accepted and verdict.reason == 'ok'
    assert sup.mode == 'normal' and sup.reason == 'ok'
    assert sup.active.parameters['c1'] == 2000.0 and sup.active.i_ref_a == 2.0
    assert sup.first_valid_at == 0.25
    # 0.25 s spent in fail-safe before the first model
    assert sup.failsafe_s == pytest.approx(0.25)


def test_goes_stale_after_timeout_and_recovers():
    sup = make(timeout_s=0.5)
    sup.offer(GOOD, 1.0)
    assert sup.update(1.5) == 'normal'          # exactly the timeout: still fresh
    assert sup.update(1.6) == 'failsafe'
    assert sup.reason == 'stale'
    assert sup.active is None
    sup.update(2.6)
    # the clock starts at the first call (1.0): only 1.6..2.6 counts, the interval 1.5..1.6
    # in which the model expired is counted as normal (the mode held during it)
    assert sup.failsafe_s == pytest.approx(1.0)
    sup.offer(GOOD, 3.0)
    assert sup.mode == 'normal'
    assert sup.failsafe_s == pytest.approx(1.4)
    assert sup.n_failsafe_entries == 1           # started in fail-safe: only the stale entry


@pytest.mark.parametrize('changes, reason', [
    ({'valid': 0.0}, 'invalid_flag'),
    ({'valid': math.nan}, 'invalid_flag'),
    ({'beta0': math.nan}, 'non_finite'),
    ({'f0': math.inf}, 'non_finite'),
    ({'c1': -1.0}, 'out_of_bounds'),
    ({'beta0': 5e3}, 'out_of_bounds'),
    ({'i_ref_a': 0.0}, 'bad_i_ref'),
    ({'i_ref_a': -2.0}, 'bad_i_ref'),
    ({'current_min_a': 1.5, 'current_max_a': 0.5}, 'bad_current_range'),
    ({'current_max_a': 5.0}, 'bad_current_range'),
    ({'current_min_a': 0.0, 'current_max_a': 0.0}, 'narrow_current_range'),
    ({'current_min_a': 0.5, 'current_max_a': 1.0}, 'narrow_current_range'),
    ({'current_min_a': 0.0, 'current_max_a': 0.9}, 'narrow_current_range'),
    ({'f0': 200.0}, 'pinned_at_bound'),
    ({'f0': -199.8}, 'pinned_at_bound'),
    ({'beta0': 0.1}, 'pinned_at_bound'),
    ({'beta1': 3.0}, 'pinned_at_bound'),
    ({'c0': 1e4, 'alpha1': 2e3}, 'pinned_at_bound'),
])
def test_refuses_bad_sets_and_counts_reason(changes, reason):
    sup = make()
    sup.offer(GOOD, 0.0)
    verdict = sup.offer(with_(**changes), 0.1)
    assert not verdict.accepted
    assert verdict.reason == reason
    assert sup.rejected[reason] == 1
    assert sum(sup.rejected.values()) == 1
    # a refused set drops the model in use at once: no guess from a model just contradicted
    assert sup.mode == 'failsafe' and sup.reason == reason and sup.active is None
    assert sup.status()['params_rejected'][reason] == 1


def test_zero_bounds_are_not_pinned_and_detail_names_the_pinned():
    # zero lower bounds: a term the damper lacks (no current slope, no loop shift) is physical
    sup = make()
    assert sup.check(with_(c1=0.0, alpha1=0.0, alpha2=0.0, delta=0.0)).accepted
    assert sup.check(with_(f0=199.5)).accepted             # 0.125 % of the span inside
    verdict = sup.check(with_(f0=199.9, beta1=-3.0))
    assert verdict.reason == 'pinned_at_bound'
    assert 'f0 = 199.9' in verdict.detail and 'beta1 = -3' in verdict.detail
    assert make(pinned_fraction=0.0).check(with_(f0=199.9)).accepted


def test_issue_set_pinned_at_bounds_but_marked_valid_is_refused():
    # the set the identifier published as valid after a 1e30 N sample (issue 8): the linear
    # parameters at their upper bounds; the supervisor refuses it even though valid == 1
    lo, hi = get_model('kwok-current').default_bounds()
    sup = ModelSupervisor(timeout_s=1.0, safe_current_a=0.0)
    msg = dict(GOOD, **{n: float(b) for n, b in zip(KWOK_CURRENT_NAMES, hi)
                        if n in ('c0', 'c1', 'k', 'alpha0', 'alpha1', 'alpha2', 'f0')})
    verdict = sup.offer(msg, 0.0)
    assert verdict.reason == 'pinned_at_bound' and not verdict.accepted
    assert sup.rejected['pinned_at_bound'] == 1 and sup.mode == 'failsafe'


def test_span_within_tolerance_accepted():
    # a DAQ-quantised 1 A level (0.999985 A) counts as a 1 A span (tolerance current_tol_a)
    sup = make(min_current_span_a=1.0, current_tol_a=0.05)
    assert sup.check(with_(current_min_a=0.0, current_max_a=0.999985)).accepted


def test_missing_element_refused():
    msg = dict(GOOD)
    del msg['delta']
    sup = make()
    verdict = sup.offer(msg, 0.0)
    assert verdict.reason == 'missing' and 'delta' in verdict.detail


def test_hold_on_reject_keeps_previous_model_until_stale():
    sup = make(hold_on_reject=True, timeout_s=1.0)
    sup.offer(GOOD, 0.0)
    sup.offer(with_(valid=0.0), 0.5)
    assert sup.mode == 'normal' and sup.active.parameters['c0'] == 800.0
    assert sup.update(1.2) == 'failsafe' and sup.reason == 'stale'


def test_failsafe_time_is_integrated_across_modes():
    sup = make(timeout_s=1.0)
    for t in np.arange(0.0, 2.0, 0.01):        # 2 s in fail-safe
        sup.update(t)
    sup.offer(GOOD, 2.0)
    for k in range(1, 301):                    # fresh messages every 10 ms for 3 s
        sup.offer(GOOD, 2.0 + 0.01 * k)
    for t in np.arange(5.0, 7.0, 0.01):        # no messages: stale from 6.0 on
        sup.update(t)
    expected = 2.0 + (6.99 - 6.0)
    assert sup.failsafe_s == pytest.approx(expected, abs=0.011)
    assert sup.n_accepted == 301


def test_time_going_backwards_is_not_counted():
    sup = make()
    sup.update(5.0)
    sup.update(4.0)
    sup.update(5.0)
    assert sup.failsafe_s == 0.0


@pytest.mark.parametrize('kw, match', [
    ({'timeout_s': 0.0}, 'timeout_s'),
    ({'safe_current_a': 3.0}, 'safe_current_a'),
    ({'i_min_a': 2.0, 'i_max_a': 1.0}, 'i_min_a'),
    ({'timeout_s': math.nan}, 'timeout_s'),
    ({'pinned_fraction': 0.5}, 'pinned_fraction'),
    ({'pinned_fraction': -0.1}, 'pinned_fraction'),
])
def test_bad_configuration_raises(kw, match):
    with pytest.raises(SupervisorError, match=match):
        make(**kw)


def test_clip_current():
    assert clip_current(3.0, 0.0, 2.0, 0.5) == 2.0
    assert clip_current(-1.0, 0.0, 2.0, 0.5) == 0.0
    assert clip_current(math.nan, 0.0, 2.0, 0.5) == 0.5
    np.testing.assert_array_equal(clip_current([1.0, math.inf], 0.0, 2.0, 0.5), [1.0, 0.5])


@pytest.mark.parametrize('lo, hi', [(0.0, 2.0), (0.5, 1.5), (1.0, 1.0), (1.5, 0.5)])
def test_clip_current_of_a_scalar_equals_the_array_path(lo, hi):
    # the scalar path (plain floats, every control step) against numpy's, value for value
    values = [-1.0, 0.0, 0.3, 0.5, 1.0, 1.2, 2.0, 7.0, math.nan, math.inf, -math.inf, 1, 3,
              np.float64(1.7), True]
    for value in values:
        scalar = clip_current(value, lo, hi, 0.25)
        array = clip_current(np.array(value, dtype=float), lo, hi, 0.25)
        assert type(scalar) is float and type(array) is float
        assert scalar == array, value


def test_default_bounds_are_the_kwok_current_model_bounds():
    model = get_model('kwok-current')
    lo, hi = model.default_bounds()
    sup = ModelSupervisor(timeout_s=1.0, safe_current_a=0.0)
    assert tuple(model.param_names) == KWOK_CURRENT_NAMES
    for name, a, b in zip(model.param_names, lo, hi):
        assert sup.bounds[name] == (a, b)
    # just outside a finite bound is refused
    name = next(n for n, b in zip(model.param_names, hi) if np.isfinite(b))
    assert sup.check(with_(**{name: float(sup.bounds[name][1]) * 1.01 + 1.0})).reason \
        == 'out_of_bounds'


def test_module_does_not_import_rclpy():
    code = 'import sys, semi_active_control.supervision.failsafe; print("rclpy" in sys.modules)'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == 'False'


def test_refuse_counts_undecodable_and_fails_safe():
    sup = make()
    sup.offer(GOOD, 0.0)
    verdict = sup.refuse('undecodable', 'no label', 0.1)
    assert not verdict.accepted and sup.rejected['undecodable'] == 1 and sup.mode == 'failsafe'
    with pytest.raises(SupervisorError, match='reason'):
        sup.refuse('whatever', '', 0.2)


def test_reconfigure_applies_valid_settings_and_refuses_the_rest_whole():
    sup = make(timeout_s=10.0)
    sup.offer(with_(), 0.0)
    assert sup.update(2.0) == 'normal'
    # a shorter timeout makes the model in use stale at the next update
    sup.reconfigure(timeout_s=1.0, safe_current_a=0.8)
    assert (sup.timeout_s, sup.safe_current_a) == (1.0, 0.8)
    assert sup.update(2.0) == 'failsafe' and sup.reason == 'stale'
    # a stricter span applies to the next message
    sup.reconfigure(min_current_span_a=1.5, hold_on_reject=1)
    assert sup.hold_on_reject is True
    assert sup.offer(with_(current_max_a=1.0), 3.0).reason == 'narrow_current_range'
    # invalid values and start-up settings: refused, nothing changed
    for changes, match in (({'safe_current_a': 3.0}, 'safe_current_a'),
                           ({'timeout_s': 0.0, 'safe_current_a': 0.1}, 'timeout_s'),
                           ({'i_max_a': 5.0}, 'cannot change i_max_a')):
        with pytest.raises(SupervisorError, match=match):
            sup.reconfigure(**changes)
    assert (sup.timeout_s, sup.safe_current_a, sup.i_max_a) == (1.0, 0.8, 2.0)
    assert sup.rejected['narrow_current_range'] == 1        # counters kept


def test_a_set_ages_from_its_stamp_and_one_received_stale_is_refused():
    """A set that sat in a queue (a starved machine) is as old as its stamp says."""
    sup = make(timeout_s=1.0)
    t = 1000.0
    verdict = sup.offer(with_(stamp_s=t - 0.4), t)        # 0.4 s in transit: used
    assert verdict.accepted and sup.mode == 'normal'
    assert sup.age(t) == pytest.approx(0.4)
    assert sup.update(t + 0.55) == 'normal'
    assert sup.update(t + 0.65) == 'failsafe' and sup.reason == 'stale'   # 1.05 s after stamp
    # received 1.5 s after its stamp: refused, counted, never used
    verdict = sup.offer(with_(stamp_s=t - 0.5), t + 1.0)
    assert not verdict.accepted and verdict.reason == 'stale_on_arrival'
    assert sup.mode == 'failsafe' and sup.active is None
    assert sup.status()['params_rejected']['stale_on_arrival'] == 1
    assert sup.stamps_not_used == {'unset': 0, 'future': 0, 'other_clock': 0}


@pytest.mark.parametrize('stamp, kind', [
    (0.0, 'unset'), (math.nan, 'unset'),           # a publisher that leaves the stamp at zero
    (5000.5, 'future'),                            # ahead of this clock
    (5000.0 - 3600.0, 'other_clock'),              # e.g. a replay's simulated time
])
def test_a_stamp_on_another_clock_leaves_the_age_from_receipt(stamp, kind):
    sup = make(timeout_s=1.0)
    assert sup.offer(with_(stamp_s=stamp), 5000.0).accepted
    assert sup.age(5000.0) == 0.0 and sup.update(5000.9) == 'normal'
    assert sup.update(5001.1) == 'failsafe'
    assert sup.status()['stamps_not_used'][kind] == 1


def test_hold_on_reject_keeps_the_model_when_a_set_arrives_stale():
    sup = make(timeout_s=1.0, hold_on_reject=True)
    sup.offer(with_(stamp_s=99.9), 100.0)
    assert sup.offer(with_(stamp_s=98.0), 100.5).reason == 'stale_on_arrival'
    assert sup.mode == 'normal' and sup.age(100.5) == pytest.approx(0.6)
