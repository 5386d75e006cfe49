"""Tests of the current-dependent Kwok model."""
import numpy as np
import pytest

from mr_damper_model.kwok import Kwok
from mr_damper_model.kwok_current import (KwokCurrent, kwok_current_force_scalar,
                                          kwok_current_force_slope_at,
                                          kwok_current_terms_scalar)
from mr_damper_model.presets import thesis_kwok_current


def _p():
    return {'c0': 150.0, 'c1': 850.0, 'k': 100.0, 'alpha0': 120.0, 'alpha1': 380.0,
            'alpha2': 200.0, 'beta0': 7.0, 'beta1': -0.3, 'delta': 0.5, 'f0': 5.0}


@pytest.mark.parametrize('current', [0.0, 0.7, 2.0, 2.5])
def test_equals_kwok_at_fixed_current(current):
    q = _p()
    s = current / 2.0
    kw = {'c': q['c0'] + q['c1'] * s, 'k': q['k'],
          'alpha': q['alpha0'] + q['alpha1'] * s * (2 - s) + q['alpha2'] * s * s,
          'beta': q['beta0'] * np.exp(q['beta1'] * s), 'delta': q['delta'], 'f0': q['f0']}
    rng = np.random.default_rng(0)
    x = rng.uniform(-0.03, 0.03, 50)
    v = rng.uniform(-0.3, 0.3, 50)
    m = KwokCurrent(i_ref_a=2.0)
    np.testing.assert_allclose(m.force(m.from_dict(q), x, v, np.full(50, current)),
                               Kwok().force(Kwok().from_dict(kw), x, v), rtol=1e-12)


def test_monotone_in_current_within_default_bounds():
    m = KwokCurrent()
    lo, hi = m.default_bounds()
    rng = np.random.default_rng(1)
    P = lo + (hi - lo) * rng.uniform(size=(200, lo.size))
    s = np.linspace(0, 1, 41)
    c = P[:, [0]] + P[:, [1]] * s
    alpha = P[:, [3]] + P[:, [4]] * s * (2 - s) + P[:, [5]] * s * s
    assert np.all(np.diff(c, axis=1) >= 0)
    assert np.all(np.diff(alpha, axis=1) >= -1e-9)


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
    from mr_damper_model import presets
    from mr_damper_model.kwok_current import kwok_current_force
    model, params = presets.thesis_kwok_current()
    rng = np.random.default_rng(3)
    x, v, i = rng.normal(0, 0.01, 50), rng.normal(0, 0.1, 50), rng.uniform(0, 2, 50)
    # the model's definition written out (module docstring), s = i / i_ref_a
    p, s = params, i / model.options['i_ref_a']
    want = ((p['c0'] + p['c1'] * s) * v + p['k'] * x
            + (p['alpha0'] + p['alpha1'] * s * (2 - s) + p['alpha2'] * s * s)
            * np.tanh(p['beta0'] * np.exp(p['beta1'] * s) * v + p['delta'] * np.sign(x))
            + p['f0'])
    got = kwok_current_force(dict(params, i_ref_a=model.options['i_ref_a'], rmse_n=3.0),
                             x, v, i)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)
    other = KwokCurrent(i_ref_a=1.0)           # i_ref_a is read from the dict
    np.testing.assert_array_equal(kwok_current_force(dict(params, i_ref_a=1.0), x, v, i),
                                  other.force(other.from_dict(params), x, v, i=i))
