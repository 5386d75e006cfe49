"""Tests of the current-dependent Kwok model."""
import numpy as np
import pytest

from mr_damper_model.models.kwok import Kwok
from mr_damper_model.models.kwok_current import (KwokCurrent, kwok_current_coefficients,
                                                 kwok_current_force_scalar,
                                                 kwok_current_force_slope_at,
                                                 kwok_current_terms_scalar)
from mr_damper_model.models.presets import thesis_kwok_current


def _p():
    return {'c0': 150.0, 'c1': 850.0, 'k': 100.0, 'alpha0': 120.0, 'alpha1': 380.0,
            'alpha2': 200.0, 'beta0': 7.0, 'beta1': -0.3, 'delta': 0.5, 'f0': 5.0}


def _xv(n=50, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-0.03, 0.03, n), rng.uniform(-0.3, 0.3, n)


@pytest.mark.parametrize('i_ref', [1.0, 2.0])
def test_limits_at_zero_and_reference_current_are_the_plain_kwok_model(i_ref):
    """At i = 0 only the 0-coefficients act; at i = i_ref_a every current term is fully on."""
    q = _p()
    x, v = _xv()
    m = KwokCurrent(i_ref_a=i_ref)
    vec = m.from_dict(q)
    kwok = Kwok()
    off = {'c': q['c0'], 'k': q['k'], 'alpha': q['alpha0'], 'beta': q['beta0'],
           'delta': q['delta'], 'f0': q['f0']}
    full = dict(off, c=q['c0'] + q['c1'], alpha=q['alpha0'] + q['alpha1'] + q['alpha2'],
                beta=q['beta0'] * np.exp(q['beta1']))
    for current, kw in ((0.0, off), (i_ref, full)):
        np.testing.assert_allclose(m.force(vec, x, v, np.full(x.size, current)),
                                   kwok.force(kwok.from_dict(kw), x, v), rtol=1e-12, atol=1e-9)


def test_without_current_terms_the_force_does_not_depend_on_current():
    q = dict(_p(), c1=0.0, alpha1=0.0, alpha2=0.0, beta1=0.0)
    x, v = _xv(seed=2)
    m = KwokCurrent()
    want = m.force(m.from_dict(q), x, v, np.zeros(x.size))
    for current in (0.3, 1.0, 2.0, 2.7):
        np.testing.assert_allclose(m.force(m.from_dict(q), x, v, np.full(x.size, current)),
                                   want, rtol=1e-12)


def test_more_current_never_softens_the_damper_within_default_bounds():
    """
    Physical check: with the default bounds a higher current gives at least as much force.

    Piston moving outwards (x, v > 0) the force grows with current, moving inwards (x, v < 0)
    it grows in magnitude, for random parameter sets in the default box whose beta does not
    fall with current (beta1 >= 0: with beta1 < 0 the knee widens and the hysteretic term can
    shrink at low velocity, which the model allows on purpose).
    """
    m = KwokCurrent()
    lo, hi = m.default_bounds()
    lo[m.param_names.index('beta1')] = 0.0
    rng = np.random.default_rng(1)
    currents = np.linspace(0.0, 2.0, 21)
    x = np.repeat(rng.uniform(1e-3, 0.03, 20), currents.size)
    v = np.repeat(rng.uniform(1e-3, 0.5, 20), currents.size)
    i = np.tile(currents, 20)
    for row in lo + (hi - lo) * rng.uniform(size=(100, lo.size)):
        out = m.force(row, x, v, i).reshape(20, currents.size)
        inw = m.force(row, -x, -v, i).reshape(20, currents.size)
        assert np.all(np.diff(out, axis=1) >= -1e-9 * np.abs(out).max())
        assert np.all(np.diff(inw, axis=1) <= 1e-9 * np.abs(inw).max())


def test_coefficients_are_monotone_beta_log_linear_alpha1_saturates_alpha2_is_convex():
    m = KwokCurrent()
    lo, hi = m.default_bounds()
    rng = np.random.default_rng(4)
    P = lo + (hi - lo) * rng.uniform(size=(200, lo.size))
    s = np.linspace(0, 1, 41)
    c, alpha, beta = kwok_current_coefficients(P, s)
    assert np.all(np.diff(c, axis=1) >= 0) and np.all(np.diff(alpha, axis=1) >= -1e-9)
    # c is linear in the current and beta1 is the log-slope of beta (beta > 0 for every beta1)
    assert np.all(beta > 0)
    np.testing.assert_allclose(np.diff(c, 2, axis=1), 0.0, atol=1e-9 * np.abs(c).max())
    log_slope = np.broadcast_to(P[:, [7]] * (s[1] - s[0]), (P.shape[0], s.size - 1))
    np.testing.assert_allclose(np.diff(np.log(beta), axis=1), log_slope, rtol=0, atol=1e-9)
    # alpha1 alone: saturating (concave, flat at the reference current); alpha2 alone: convex
    only1 = np.zeros((1, 10))
    only1[0, 4] = 100.0
    only2 = np.zeros((1, 10))
    only2[0, 5] = 100.0
    a1 = kwok_current_coefficients(only1, s)[1][0]
    a2 = kwok_current_coefficients(only2, s)[1][0]
    assert a1[-1] == pytest.approx(100.0) and a2[-1] == pytest.approx(100.0)
    assert np.all(np.diff(a1, 2) < 0) and np.all(np.diff(a2, 2) > 0)
    assert (a1[-1] - a1[-2]) < 0.02 * (a1[1] - a1[0])      # flat at s = 1
    assert a2[1] - a2[0] < 0.02 * (a2[-1] - a2[-2])         # flat at s = 0


def test_i_ref_validation():
    with pytest.raises(ValueError, match='i_ref_a'):
        KwokCurrent(i_ref_a=0.0)


def test_scalar_force_and_slope_match_the_model():
    # the plain-float force equals the vectorised model's, and the slope-returning variant
    # gives the very same force with a slope equal to a central difference of it
    model, p = thesis_kwok_current()
    vec = model.from_dict(p)
    rng = np.random.default_rng(5)
    x, v, i = rng.uniform(-0.03, 0.03, 300), rng.uniform(-0.3, 0.3, 300), rng.uniform(0, 2, 300)
    f_model = model.force(vec, x, v, i)
    i_ref = model.options['i_ref_a']
    h = 1e-6
    for k in range(x.size):
        s = i[k] / i_ref
        f = kwok_current_force_scalar(vec, s, x[k], v[k])
        assert f == pytest.approx(f_model[k], rel=1e-12, abs=1e-9)
        f2, slope = kwok_current_force_slope_at(kwok_current_terms_scalar(vec, s), vec, x[k],
                                                v[k])
        assert f2 == f
        fd = (kwok_current_force_scalar(vec, s + h, x[k], v[k])
              - kwok_current_force_scalar(vec, s - h, x[k], v[k])) / (2 * h)
        assert slope == pytest.approx(fd, rel=1e-5, abs=1e-4)


def test_force_of_a_named_parameter_set():
    """``kwok_current_force`` on a saved-parameter dict (with ``i_ref_a``) is the model's force."""
    from mr_damper_model.models import presets
    from mr_damper_model.models.kwok_current import kwok_current_force
    model, params = presets.thesis_kwok_current()
    rng = np.random.default_rng(3)
    x, v, i = rng.normal(0, 0.01, 50), rng.normal(0, 0.1, 50), rng.uniform(0, 2, 50)
    got = kwok_current_force(dict(params, i_ref_a=model.options['i_ref_a'], rmse_n=3.0),
                             x, v, i)
    np.testing.assert_array_equal(got, model.force(model.from_dict(params), x, v, i=i))
    other = KwokCurrent(i_ref_a=1.0)           # i_ref_a is read from the dict
    np.testing.assert_array_equal(kwok_current_force(dict(params, i_ref_a=1.0), x, v, i),
                                  other.force(other.from_dict(params), x, v, i=i))
    # at 0 A no current term acts, whatever i_ref_a
    zero = np.zeros(50)
    np.testing.assert_array_equal(kwok_current_force(dict(params, i_ref_a=1.0), x, v, zero),
                                  kwok_current_force(dict(params, i_ref_a=2.0), x, v, zero))
