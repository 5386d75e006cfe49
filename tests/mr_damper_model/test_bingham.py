"""Tests of the Bingham model (exact expression)."""
import numpy as np

from mr_damper_model.models.bingham import Bingham


def test_exact():
    m = Bingham()
    v = np.array([-0.2, -1e-6, 0.0, 1e-6, 0.3])
    f = m.force([100.0, 500.0, -3.0], np.zeros(5), v)
    np.testing.assert_allclose(f, 100.0 * np.sign(v) + 500.0 * v - 3.0, atol=1e-12)
    assert f[2] == -3.0
