"""
Whole-run latency statistics in constant memory: a histogram on log-spaced bins (no ROS).

A control loop at 500 Hz makes 1.8 million latencies an hour; keeping them all grows memory,
keeping the last few thousand forgets the run. :class:`LatencyHistogram` counts each value
in one of ``bins_per_decade`` bins per decade between ``low_s`` and ``high_s`` (values outside
go to the end bins, and ``max_s`` keeps the largest exactly), so percentiles of the whole run
come with a relative resolution of ``10 ** (1 / bins_per_decade) - 1`` (2.3 % at the default
100 bins per decade).
"""
import math

import numpy as np


class LatencyHistogram:
    """
    Count latencies [s] in log-spaced bins; percentiles, mean and maximum of the whole run.

    Parameters
    ----------
    low_s, high_s : float
        Range of the bins [s] (0 < low_s < high_s); values below land in the first bin,
        above in the last.
    bins_per_decade : int
        Resolution.

    """

    def __init__(self, low_s=1e-6, high_s=10.0, bins_per_decade=100):
        if not (0 < low_s < high_s) or bins_per_decade < 1:
            raise ValueError('need 0 < low_s < high_s and bins_per_decade >= 1')
        self._lo = math.log10(low_s)
        self._per = float(bins_per_decade)
        n = int(math.ceil((math.log10(high_s) - self._lo) * bins_per_decade))
        self._counts = np.zeros(n + 1, dtype=np.int64)
        self._edges = 10.0 ** (self._lo + np.arange(n + 2) / self._per)
        self.n = 0
        self.sum_s = 0.0
        self.max_s = -math.inf
        self.non_finite = 0

    def add(self, value_s):
        """Count one latency [s] (a non-finite one is counted apart, ``non_finite``)."""
        v = float(value_s)
        if not math.isfinite(v):
            self.non_finite += 1
            return
        k = int((math.log10(v) - self._lo) * self._per) if v > 0 else 0
        self._counts[min(max(k, 0), len(self._counts) - 1)] += 1
        self.n += 1
        self.sum_s += v
        if v > self.max_s:
            self.max_s = v

    def percentile(self, q):
        """
        Return the ``q``-th percentile [s] (0..100), NaN without values.

        The bin's geometric centre; within one bin's resolution of the exact value, and at
        most :attr:`max_s`.
        """
        if self.n == 0:
            return math.nan
        rank = max(1, int(math.ceil(q / 100.0 * self.n)))
        k = int(np.searchsorted(np.cumsum(self._counts), rank))
        if k == len(self._counts) - 1:
            return self.max_s               # the overflow bin: the largest is known
        centre = math.sqrt(self._edges[k] * self._edges[k + 1])
        return min(centre, self.max_s)

    def fraction_above(self, limit_s):
        """Return the fraction of values above ``limit_s`` [s] (to one bin's resolution)."""
        if self.n == 0:
            return math.nan
        k = int(np.searchsorted(self._edges, limit_s, side='right')) - 1
        return float(self._counts[max(k + 1, 0):].sum()) / self.n

    def summary(self):
        """Return ``n``, ``mean_s``, ``p50_s``, ``p99_s``, ``p999_s``, ``max_s`` (JSON-ready)."""
        return {'n': self.n, 'mean_s': self.sum_s / self.n if self.n else math.nan,
                'p50_s': self.percentile(50), 'p99_s': self.percentile(99),
                'p999_s': self.percentile(99.9),
                'max_s': self.max_s if self.n else math.nan}
