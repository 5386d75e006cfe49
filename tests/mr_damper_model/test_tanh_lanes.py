"""
The own tanh of the gym's compiled Spencer lanes (``spencer.tanh_lanes``) against ``math.tanh``.

The lanes (``heun_substeps_lanes``) take it in the C library's place because it is cheaper
compiled; these tests hold it to a few ulp of ``math.tanh`` over the whole float64 range and
check the values its callers may pass (tiny, huge, +-0.0, +-inf, NaN).
"""
import math

import numba
import numpy as np
import pytest

from mr_damper_model.models.spencer import tanh_lanes

#: Largest relative difference from ``math.tanh`` allowed: a few ulp (4.4e-16 when written,
#: on this grid and on 4.8 million points: two ulp of tanh(0.549) = 0.50001, where an ulp is
#: 2.2e-16 of the value; each of the two functions is within 3.2e-16 of the true tanh).
MAX_REL = 6e-16


@pytest.fixture(scope='module')
def compiled():
    """``tanh_lanes`` compiled by numba, applied to an array (the kernel's form)."""
    one = numba.njit(tanh_lanes)

    @numba.njit
    def apply(xs):
        out = np.empty_like(xs)
        for i in range(xs.shape[0]):
            out[i] = one(xs[i])
        return out

    return apply


def _grid():
    rng = np.random.default_rng(3)
    x = np.concatenate([np.geomspace(1e-8, 0.5, 100_000), np.linspace(0.0, 1.0, 50_001),
                        np.linspace(1.0, 25.0, 100_001), rng.uniform(0.0, 20.0, 50_000),
                        0.5 + np.arange(-200, 200) * 2.0 ** -53,
                        19.1 + np.arange(-200, 200) * 2.0 ** -48, [300.0, 1e3, 1e308]])
    return np.concatenate([x, -x])


def test_within_a_few_ulp_of_math_tanh(compiled):
    x = _grid()
    want = np.array([math.tanh(v) for v in x])
    got = compiled(x)
    nz = want != 0.0
    rel = np.abs(got[nz] - want[nz]) / np.abs(want[nz])
    assert rel.max() <= MAX_REL
    assert np.array_equal(got[~nz], want[~nz])
    # the plain-Python function (the tests' lanes) computes the compiled one's values
    sample = x[::97]
    assert np.array_equal(np.array([tanh_lanes(v) for v in sample]), compiled(sample))


def test_tiny_x_gives_x(compiled):
    x = np.geomspace(1e-300, 1e-8, 20_001)
    x = np.concatenate([x, -x, [5e-324, -5e-324, 2.2250738585072014e-308]])
    assert np.array_equal(compiled(x), x)
    want = np.array([math.tanh(v) for v in x])
    assert np.max(np.abs(compiled(x) - want) / np.abs(want)) <= 2.3e-16


def test_huge_x_infinities_zeros_and_nan(compiled):
    x = np.array([19.1, 20.0, 710.0, 1e308, np.inf, 0.0])
    got = compiled(np.concatenate([x, -x, [np.nan]]))
    assert np.array_equal(got[:5], np.ones(5)) and np.array_equal(got[6:11], -np.ones(5))
    assert got[5] == 0.0 and math.copysign(1.0, got[5]) == 1.0
    assert got[11] == 0.0 and math.copysign(1.0, got[11]) == -1.0
    assert math.isnan(got[12])
    assert math.isnan(tanh_lanes(math.nan)) and tanh_lanes(-math.inf) == -1.0
