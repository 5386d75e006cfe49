"""Tests of the Kwok model against analytic limits."""
import numpy as np

from mr_damper_model.models.kwok import Kwok
from mr_damper_model.models.presets import THESIS_TABLE_4_3


def test_large_velocity_limit():
    m = Kwok()
    p = m.from_dict({'c': 300.0, 'k': 50.0, 'alpha': 400.0, 'beta': 20.0, 'delta': 0.5,
                     'f0': 7.0})
    x = np.array([0.01, -0.02, 0.02, -0.01])
    v = np.array([5.0, 5.0, -5.0, -5.0])
    expected = 300.0 * v + 50.0 * x + 400.0 * np.sign(v) + 7.0
    np.testing.assert_allclose(m.force(p, x, v), expected, atol=1e-9)


def test_zero_velocity_and_delta():
    m = Kwok()
    p = m.from_dict({'c': 300.0, 'k': 0.0, 'alpha': 400.0, 'beta': 20.0, 'delta': 0.5,
                     'f0': 0.0})
    f = m.force(p, [0.02, -0.02, 0.0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(f, [400 * np.tanh(0.5), -400 * np.tanh(0.5), 0.0], atol=1e-12)


def test_thesis_table_inside_unbounded_ranges():
    m = Kwok()
    lo, hi = m.default_bounds(unbounded=True)
    for current, row in THESIS_TABLE_4_3.items():
        p = m.from_dict(row)
        assert np.all(p >= lo) and np.all(p <= hi), current
    lo, hi = m.default_bounds()
    assert lo[m.param_names.index('beta')] > 0
    assert hi[m.param_names.index('beta')] - lo[m.param_names.index('beta')] > 100
