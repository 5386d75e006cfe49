"""LatencyHistogram: whole-run percentiles within one bin of the exact ones."""
import math

import numpy as np
import pytest

from mr_damper_common.latency import LatencyHistogram


def test_percentiles_within_the_resolution_of_the_exact_ones():
    rng = np.random.default_rng(1)
    values = rng.lognormal(mean=math.log(4e-4), sigma=0.6, size=20000)
    h = LatencyHistogram()
    for v in values:
        h.add(v)
    res = 10 ** (1 / 100) - 1
    for q in (50, 90, 99, 99.9):
        exact = np.percentile(values, q, method='inverted_cdf')
        assert abs(h.percentile(q) / exact - 1) <= res, q
    assert h.max_s == values.max() and h.n == len(values)
    assert h.summary()['mean_s'] == pytest.approx(values.mean())
    assert h.fraction_above(2e-3) == pytest.approx(np.mean(values > 2e-3), abs=2e-3)


def test_out_of_range_and_bad_values():
    h = LatencyHistogram(low_s=1e-5, high_s=1.0)
    for v in (0.0, 5e-6, 2.0, math.nan, math.inf):
        h.add(v)
    assert h.n == 3 and h.non_finite == 2
    assert h.percentile(100) == 2.0          # the largest kept exactly
    assert math.isnan(LatencyHistogram().percentile(50))
    with pytest.raises(ValueError):
        LatencyHistogram(low_s=1.0, high_s=0.1)
