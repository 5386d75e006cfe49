"""
Current probing: make every current bin of the live identifier get data while the car drives.

Skyhook-like laws sit at the ends of the coil range (0 and 2 A) most of the time, so the
identifier's middle current bins (``mr_damper_model.live``: bins of ``current_bin_a`` = 0.1 A,
keyed by ``round(i / current_bin_a)``) starve. :class:`CurrentProbe` overrides the law's command
for ``hold_s`` once every ``period_s`` with the centre of a starving bin (counted from the
measured coil current): the one farthest from every covered bin first, until it is covered, then
the next; once all are covered, the least-filled. Its cost is bounded by the duty cycle
``hold_s / period_s`` (capped by ``max_duty``): outside the probe windows the law is untouched.

Why farthest first: the identifier uses a bin once it holds ``min_samples`` (its
``min_bin_fraction`` of a window, 500 samples at 1 kHz), and the car takes a model only over a
current span of ``min_current_span_a`` (1 A). In fail-safe the car sits at its safe current
(0.5 A), so that bin fills by itself; the first probe level that makes a span is the far end of
the coil range. Visiting the least-filled bin instead went round all starving bins in turn
(0.2 s holds at 0.25 A bins: 200 samples per visit, eight bins), so no second bin reached 500
samples before about 17 s of probing, and then several at once (``--config hil``, docs/hil.md).

Stated cost (defaults: 0.1 s every 1 s, duty 10 %, cap 20 %), skyhook on an ISO 8608 class C road
at 20 m/s, kwok-current truth: Wk-weighted body acceleration RMS +18 % (``bench/bench_hil.py``,
100 s), all 21 bins of 0..2 A hold the identifier's 500 samples after 46 s, against 11 of 21
bins in 100 s without probing; the test bounds the cost at 22 % and the cover time at 100 s.
Halving the duty roughly halves the cost and doubles the cover time.
"""
import math

import numpy as np


class ProbeError(ValueError):
    """Invalid probing settings."""


class CurrentProbe:
    """
    Scheduled probe of the current bins: farthest starving bin first, then the least-filled.

    Parameters
    ----------
    i_min_a, i_max_a : float
        Coil range [A]; bins are the multiples of ``bin_a`` inside it.
    bin_a : float
        Bin width [A] (the identifier's ``current_bin_a``).
    period_s : float
        Time between probe windows [s].
    hold_s : float
        Length of a probe window [s].
    min_samples : int
        Samples a bin needs to count as covered (bins below it are probed first); default: what
        the live identifier needs by default (``min_bin_fraction`` 0.25 of a 2 s window at
        1 kHz).
    max_duty : float
        Cap of ``hold_s / period_s``.

    """

    def __init__(self, i_min_a=0.0, i_max_a=2.0, *, bin_a=0.1, period_s=1.0, hold_s=0.1,
                 min_samples=500, max_duty=0.2):
        for name, val in (('bin_a', bin_a), ('period_s', period_s), ('hold_s', hold_s),
                          ('max_duty', max_duty)):
            if not (math.isfinite(val) and val > 0):
                raise ProbeError(f'`{name}` must be > 0, got {val}')
        if not i_max_a > i_min_a:
            raise ProbeError(f'`i_max_a` ({i_max_a}) must exceed `i_min_a` ({i_min_a})')
        if hold_s / period_s > max_duty:
            raise ProbeError(f'duty hold_s / period_s = {hold_s / period_s:.3f} exceeds '
                             f'`max_duty` = {max_duty}')
        self.bin_a = float(bin_a)
        self.keys = np.arange(math.ceil(i_min_a / bin_a - 1e-9),
                              math.floor(i_max_a / bin_a + 1e-9) + 1)
        self.levels_a = self.keys * self.bin_a
        self.period_s = float(period_s)
        self.hold_s = float(hold_s)
        self.min_samples = int(min_samples)
        self.duty = self.hold_s / self.period_s
        self.reset()

    def reset(self):
        """Clear the counts."""
        self.counts = np.zeros(self.keys.size, dtype=int)
        self.starving = int(self.keys.size) if self.min_samples > 0 else 0
        self.covered_s = None
        self.outside = 0
        self.probing = False
        self.windows = 0
        self.unreachable = np.zeros(self.keys.size, dtype=bool)
        self._window = None
        self._target = None
        self._target_count = 0

    def observe(self, current_a):
        """Count a measured coil current [A] into its bin (outside the range: ``outside``)."""
        k = int(round(current_a / self.bin_a)) - int(self.keys[0])
        if 0 <= k < self.counts.size:
            self.counts[k] += 1
            if self.counts[k] == self.min_samples:
                self.starving -= 1
        else:
            self.outside += 1

    def as_dict(self):
        """
        Return the status: ``levels_a``, ``counts``, ``covered`` / ``bins``, ``covered_s``.

        Also ``windows``, ``outside`` (samples outside the bins), ``unreachable_a`` (levels a
        probe window could not reach) and ``duty``.
        """
        return {'levels_a': self.levels_a.tolist(), 'counts': self.counts.tolist(),
                'covered': int(self.counts.size - self.starving), 'bins': int(self.counts.size),
                'covered_s': self.covered_s, 'windows': self.windows, 'outside': self.outside,
                'unreachable_a': self.levels_a[self.unreachable].tolist(), 'duty': self.duty}

    def covered(self):
        """
        Return True when every bin holds ``min_samples``.

        ``covered_s`` is the time [s] of the first call that found them all covered.
        """
        return self.starving == 0

    def __call__(self, i_law_a, t_s):
        """
        Return the current command [A]: the law's, or the probe level inside a probe window.

        Parameters
        ----------
        i_law_a : float
            Control law's command [A].
        t_s : float
            Simulation time [s].

        """
        if self.covered_s is None and self.starving == 0:
            self.covered_s = float(t_s)
        window = math.floor(t_s / self.period_s)
        self.probing = (t_s - window * self.period_s) < self.hold_s
        if not self.probing:
            return i_law_a
        if window != self._window:
            self._window = window
            self.windows += 1
            self._target = self.next_level()
        return self._target

    def next_level(self):
        """
        Return the level [A] of the next probe window.

        The starving bin farthest from every covered bin (ties: the least-filled, then the
        lowest); before any bin is covered, the farthest from the fullest one (where the car's
        current sits: its safe current in fail-safe); with all covered, or no sample yet, the
        least-filled bin. A target whose window brought it no sample (the coil current cannot
        reach it) is not targeted again (``unreachable``) while another bin can be.
        """
        counts = self.counts
        if self._target is not None:
            k = int(np.argmin(np.abs(self.levels_a - self._target)))
            if counts[k] == self._target_count:
                # its window brought it nothing (the coil current cannot get there): skip it
                self.unreachable[k] = True
        anchor = counts >= self.min_samples
        open_ = ~anchor & ~self.unreachable
        if not open_.any() or not counts.any():
            # least-filled, of the bins a window can reach
            reach = np.where(self.unreachable & ~self.unreachable.all(), np.inf, counts)
            target = int(np.argmin(reach))
            self._target_count = int(counts[target])
            return float(self.levels_a[target])
        if not anchor.any():
            anchor = counts == counts.max()
            open_ &= ~anchor
        gap = np.min(np.abs(self.levels_a[:, None] - self.levels_a[None, anchor]), axis=1)
        gap[~open_] = -1.0
        far = np.flatnonzero(gap >= gap.max() - 1e-9 * self.bin_a)
        target = int(far[int(np.argmin(counts[far]))])
        self._target_count = int(counts[target])
        return float(self.levels_a[target])
