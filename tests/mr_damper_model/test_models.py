"""Tests of the model base class and the registry, run against every model."""
import numpy as np
import pytest

from mr_damper_model.models import get_model, MODEL_NAMES, ModelError


def _signals(n=400, fs=1000.0):
    t = np.arange(n) / fs
    w = 2 * np.pi * 1.1
    x = -0.03 * np.cos(w * t)
    v = 0.03 * w * np.sin(w * t)
    i = np.where(t < t[n // 2], 0.5, 1.5)
    return x, v, i, t


def _sample_params(model, p, rng):
    lo, hi = model.default_bounds()
    return lo + (hi - lo) * rng.uniform(0.05, 0.3, size=(p, lo.size))


@pytest.mark.parametrize('name', MODEL_NAMES)
def test_shapes_and_batch_equals_loop(name):
    model = get_model(name)
    rng = np.random.default_rng(3)
    n = 120 if name == 'spencer' else 400
    x, v, i, t = _signals(n)
    P = _sample_params(model, 3, rng)
    f = model.force(P, x, v, i=i, t=t)
    assert f.shape == (3, n)
    assert np.all(np.isfinite(f))
    for r in range(3):
        np.testing.assert_allclose(model.force(P[r], x, v, i=i, t=t), f[r], rtol=1e-12,
                                   atol=1e-9)


@pytest.mark.parametrize('name', [m for m in MODEL_NAMES if m != 'spencer'])
def test_regressors_identity(name):
    model = get_model(name)
    rng = np.random.default_rng(4)
    x, v, i, t = _signals()
    P = _sample_params(model, 4, rng)
    nl = P[:, [model.param_names.index(q) for q in model.nonlinear_names]]
    lin = P[:, [model.param_names.index(q) for q in model.linear_names]]
    phi = model.regressors(nl, x, v, i=i, t=t)
    assert phi.shape == (4, x.size, len(model.linear_names))
    f = np.einsum('pnk,pk->pn', phi, lin)
    np.testing.assert_allclose(f, model.force(P, x, v, i=i, t=t), rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize('name', MODEL_NAMES)
def test_bounds_and_names(name):
    model = get_model(name)
    for unbounded in (False, True):
        lo, hi = model.default_bounds(unbounded=unbounded)
        assert lo.shape == hi.shape == (len(model.param_names),)
        assert np.all(lo < hi)
    assert set(model.param_units) == set(model.param_names)
    assert set(model.linear_names) | set(model.nonlinear_names) == set(model.param_names)
    lo, hi = model.default_bounds()
    lo_u, hi_u = model.default_bounds(unbounded=True)
    assert np.all(lo_u <= lo) and np.all(hi_u >= hi)


@pytest.mark.parametrize('name', MODEL_NAMES)
def test_dict_round_trip_and_errors(name):
    model = get_model(name)
    lo, hi = model.default_bounds()
    p = 0.5 * (lo + hi)
    np.testing.assert_array_equal(model.from_dict(model.to_dict(p)), p)
    d = model.to_dict(p)
    missing = dict(d)
    del missing[model.param_names[0]]
    with pytest.raises(ValueError, match=model.param_names[0]):
        model.from_dict(missing)
    d[model.param_names[-1]] = float('nan')
    with pytest.raises(ValueError, match='not finite'):
        model.from_dict(d)


def test_registry_and_input_errors():
    with pytest.raises(ModelError, match='unknown model'):
        get_model('nope')
    m = get_model('kwok')
    with pytest.raises(ValueError, match='params'):
        m.force(np.ones(3), [0.0], [0.0])
    with pytest.raises(ValueError, match='`v`'):
        m.force(np.ones(6), [0.0, 1.0], [0.0, np.nan])
    with pytest.raises(ValueError, match='current'):
        get_model('kwok-current').force(np.ones(10), [0.0], [0.0])
    with pytest.raises(ValueError, match='time'):
        get_model('bouc-wen').force(np.ones(8), [0.0], [0.0])
    with pytest.raises(ValueError, match='increasing'):
        get_model('bouc-wen').force(np.ones(8), [0.0, 0.0], [0.0, 0.0], t=[0.0, 0.0])


@pytest.mark.parametrize('name', ['kwok', 'kwok-current', 'bingham', 'bouc-wen'])
def test_separable_parts_rebuild_the_regressors(name):
    model = get_model(name)
    x, v, i, t = _signals()
    lo, hi = model.default_bounds()
    rng = np.random.default_rng(3)
    P = lo + rng.random((3, lo.size)) * (hi - lo)
    N = P[:, [model.param_names.index(n) for n in model.nonlinear_names]]
    phi = model.regressors(N, x, v, i=i, t=t)
    parts = model.separable_parts(x, v, i=i, t=t)
    assert sorted(np.concatenate([parts.fixed_index, parts.factor_index])) == \
        list(range(len(model.linear_names)))
    np.testing.assert_allclose(phi[:, :, parts.fixed_index],
                               np.broadcast_to(parts.fixed, phi[:, :, parts.fixed_index].shape),
                               rtol=0, atol=1e-12)
    if parts.factor_index.size:
        h = model.nonlinear_factor(N, x, v, i=i, t=t)
        np.testing.assert_allclose(phi[:, :, parts.factor_index],
                                   h[:, :, None] * parts.weights[None], rtol=1e-12, atol=1e-12)


def test_spencer_has_no_separable_structure():
    model = get_model('spencer')
    x, v, i, t = _signals()
    assert model.separable_parts(x, v, i=i, t=t) is None


@pytest.mark.parametrize('name', ['kwok', 'kwok-current', 'bingham'])
def test_analytic_jacobian_matches_central_differences(name):
    model = get_model(name)
    x, v, i, t = _signals()
    lo, hi = model.default_bounds()
    p = lo + 0.3 * (hi - lo)
    p[model.param_names.index('f0') if 'f0' in model.param_names else 0] = 7.0
    J = model.jacobian(p, x, v, i=i, t=t)
    assert J.shape == (x.size, p.size)
    for j in range(p.size):
        h = 1e-6 * max(abs(p[j]), 1.0)
        dp = np.zeros(p.size)
        dp[j] = h
        fd = (model.force(p + dp, x, v, i=i, t=t) - model.force(p - dp, x, v, i=i, t=t)) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd)) + 1e-9)
