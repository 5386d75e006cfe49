"""Tests of the particle swarm (mr_damper_model.identification.pso)."""
import numpy as np
import pytest

from mr_damper_model.identification.pso import pso

SHIFT = np.array([0.3, -1.2, 2.0, 0.7])
LO, HI = -np.full(4, 5.0), np.full(4, 5.0)


def sphere(X):
    return np.sum((X - SHIFT) ** 2, axis=1)


def rosenbrock(X):
    return (1 - X[:, 0]) ** 2 + 100.0 * (X[:, 1] - X[:, 0] ** 2) ** 2


def test_sphere_converges_to_known_minimum():
    res = pso(sphere, (LO, HI), maxiter=200, rng=0, tol=0, patience=500)
    np.testing.assert_allclose(res.x, SHIFT, atol=1e-3)
    assert res.fun < 1e-6
    assert res.history.shape == (res.nit + 1,)
    assert np.all(np.diff(res.history) <= 0)          # best cost never increases


def test_rosenbrock_within_bounds():
    # the curved flat valley is hard for a swarm: ask for the valley floor near (1, 1)
    for seed in range(3):
        res = pso(rosenbrock, ([-2.0, -1.0], [2.0, 3.0]), swarm_size=30, maxiter=400,
                  rng=seed, tol=0, patience=400)
        assert res.fun < 1e-3
        np.testing.assert_allclose(res.x, [1.0, 1.0], atol=0.1)


def test_same_seed_same_result_different_seed_differs():
    a = pso(sphere, (LO, HI), maxiter=30, rng=7)
    b = pso(sphere, (LO, HI), maxiter=30, rng=7)
    c = pso(sphere, (LO, HI), maxiter=30, rng=8)
    assert np.array_equal(a.x, b.x) and a.fun == b.fun and a.nfev == b.nfev
    assert not np.array_equal(a.x, c.x)


def test_maxiter_stops_with_success_false():
    res = pso(sphere, (LO, HI), maxiter=5, rng=0, tol=0)
    assert res.nit == 5 and res.status == 0
    assert res.success is False
    assert 'maxiter' in res.message
    assert res.nfev == 25 * 6


def test_stagnation_stops_with_success():
    res = pso(lambda X: np.zeros(len(X)), (LO, HI), maxiter=500, patience=10, rng=0)
    assert res.success and res.status == 1 and res.nit == 10


def test_callback_can_stop_and_sees_progress():
    seen = []

    def cb(r):
        seen.append(r.fun)
        return r.nit >= 3

    res = pso(sphere, (LO, HI), maxiter=50, rng=0, callback=cb)
    assert res.nit == 3 and res.status == -1 and not res.success
    assert seen == list(res.history[1:])


def test_particles_stay_in_bounds():
    lo, hi = np.array([0.0, 1.0]), np.array([0.1, 4.0])
    seen = []

    def fun(X):
        seen.append(X.copy())
        return -X.sum(axis=1)         # optimum on the upper corner: pushes against bounds
    res = pso(fun, (lo, hi), maxiter=40, rng=1, tol=0)
    allx = np.concatenate(seen)
    assert np.all(allx >= lo) and np.all(allx <= hi)
    np.testing.assert_allclose(res.x, hi)


def test_warm_start_reaches_threshold_in_fewer_iterations():
    def iterations_to(threshold, **kw):
        out = []
        for seed in range(8):
            hist = pso(sphere, (LO, HI), maxiter=100, rng=seed, tol=0, patience=1000,
                       **kw).history
            hit = np.flatnonzero(hist <= threshold)
            out.append(hit[0] if hit.size else 999)
        return np.array(out)
    cold = iterations_to(1e-4)
    warm = iterations_to(1e-4, x0=SHIFT + 0.05)
    assert np.all(warm < cold)
    assert np.median(warm) < 0.7 * np.median(cold)


def test_nonfinite_costs_are_never_best():
    def fun(X):
        c = sphere(X)
        c[X[:, 0] > 0] = np.nan
        return c
    res = pso(fun, (LO, HI), maxiter=60, rng=2)
    assert np.isfinite(res.fun) and res.x[0] <= 0


@pytest.mark.parametrize('bounds,match', [
    (([0.0, 1.0], [1.0]), 'same'),
    (([0.0], [np.inf]), 'finite'),
    (([1.0], [0.0]), 'lower bound above'),
    ((1.0,), 'pair'),
])
def test_bad_bounds(bounds, match):
    with pytest.raises(ValueError, match=match):
        pso(sphere, bounds)


def test_bad_fun_shape_and_x0():
    with pytest.raises(ValueError, match='fun'):
        pso(lambda X: X, (LO, HI))
    with pytest.raises(ValueError, match='x0'):
        pso(sphere, (LO, HI), x0=[1.0])
