"""Tests of the batched box-bounded least squares (mr_damper_model.identification.lsq)."""
import numpy as np
import pytest
from scipy.optimize import lsq_linear

from mr_damper_model.identification.lsq import box_qp, bounded_lstsq, gram, sum_squares


def _random_problem(rng, m, p=6, n=80):
    scales = 10.0 ** rng.uniform(-2, 2, m)          # badly scaled columns, like v, x, 1
    phi = rng.standard_normal((p, n, m)) * scales
    y = rng.standard_normal(n) * 10
    lo = rng.uniform(-1, 0.5, m) / scales
    hi = lo + rng.uniform(0.1, 2.0, m) / scales
    lo[rng.random(m) < 0.2] = -np.inf
    hi[rng.random(m) < 0.2] = np.inf
    return phi, y, lo, hi


@pytest.mark.parametrize('m', [1, 2, 4, 7, 8])
def test_matches_scipy_lsq_linear(m):
    rng = np.random.default_rng(m)
    for _ in range(15):
        phi, y, lo, hi = _random_problem(rng, m)
        theta = bounded_lstsq(phi, y, lo, hi)
        assert theta.shape == (phi.shape[0], m)
        assert np.all(theta >= lo - 1e-9 * (1 + np.abs(lo)))
        assert np.all(theta <= hi + 1e-9 * (1 + np.abs(hi)))
        for j in range(phi.shape[0]):
            ref = lsq_linear(phi[j], y, bounds=(lo, hi), method='bvls', tol=1e-12)
            ours = np.sum((phi[j] @ theta[j] - y) ** 2)
            best = np.sum((phi[j] @ ref.x - y) ** 2)
            assert ours <= best * (1 + 1e-9) + 1e-9


def test_unbounded_equals_lstsq_and_sum_squares():
    rng = np.random.default_rng(0)
    phi = rng.standard_normal((3, 50, 4))
    y = rng.standard_normal(50)
    theta = bounded_lstsq(phi, y, -np.inf, np.inf)
    G, b = gram(phi, y)
    rss = sum_squares(G, b, y @ y, theta)
    for j in range(3):
        ref = np.linalg.lstsq(phi[j], y, rcond=None)[0]
        np.testing.assert_allclose(theta[j], ref, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(rss[j], np.sum((phi[j] @ theta[j] - y) ** 2), rtol=1e-9)


def test_collinear_columns_are_solvable():
    rng = np.random.default_rng(1)
    v = rng.standard_normal(100)
    phi = np.column_stack([v, 0.5 * v, np.ones(100)])[None]   # c0 and c1*s at one current
    y = 3.0 * v + 1.0
    theta = bounded_lstsq(phi, y, [0, 0, -10], [10, 10, 10])
    np.testing.assert_allclose(phi[0] @ theta[0], y, atol=1e-6)


def test_single_problem_and_bad_shapes():
    G = np.eye(2)
    assert box_qp(G, np.array([2.0, -3.0]), [0, 0], [1, 1]).tolist() == [1.0, 0.0]
    with pytest.raises(ValueError, match='shape'):
        box_qp(np.ones((2, 2, 3)), np.ones((2, 2)), 0, 1)
    with pytest.raises(ValueError, match='above'):
        box_qp(G, np.ones(2), [1, 1], [0, 0])
