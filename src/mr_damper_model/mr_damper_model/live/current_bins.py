"""
The live identifier's samples filed by coil current (no ROS).

Screened, consistent samples are filed in bins of ``current_bin_a`` by their current; each bin
keeps its newest samples (as many as a window holds) and is dropped when it grows older than
``bin_max_age_s``.  A fit takes the bins that hold enough samples (:meth:`CurrentBins.usable`),
joined in time order (:func:`fit_samples`).
"""
import math

import numpy as np

from mr_damper_model.io.data import DamperData


class Bin:
    """Samples of one current level: ``level`` (median current [A]), ``data``, ``newest_s``."""

    __slots__ = ('level', 'data', 'newest_s')

    def __init__(self, level, data):
        self.level = level
        self.data = data
        self.newest_s = float(data.t[-1])


class CurrentBins(dict):
    """Bins by current: key ``round(i / current_bin_a)`` -> :class:`Bin`."""

    def update(self, new, keep, newest_s, bin_a, max_age_s):
        """
        File ``new`` samples by current; each bin keeps its newest ``keep`` samples.

        Parameters
        ----------
        new : DamperData
            Samples to file.
        keep : int
            Samples a bin keeps.
        newest_s : float
            Stamp the bins' age is measured from [s].
        bin_a : float
            Bin width [A].
        max_age_s : float
            Bins whose newest sample is older than this before ``newest_s`` are dropped [s]
            (0: never).

        """
        if new.n:
            keys = np.round(new.i / bin_a).astype(int)
            for key in np.unique(keys):
                part = new.select(keys == key)
                old = self.get(int(key))
                if old is not None:
                    part = DamperData.concatenate([old.data, part])
                if part.n > keep:
                    part = part.select(slice(part.n - keep, None))
                self[int(key)] = Bin(float(np.median(part.i)), part)
        if max_age_s > 0:
            for key in [k for k, b in self.items() if b.newest_s < newest_s - max_age_s]:
                del self[key]

    def usable(self, least, start=None):
        """
        Return the bins with at least ``least`` samples, by level.

        With ``start`` (samples of the window from ``start`` [s] on were kept out), a bin with
        samples of the window is fitted on those only (not on older ones, a start from rest,
        filling the gap); with too few of them, on the whole bin (dropping the level would
        narrow the set and with it the consistency reference).
        """
        usable = []
        for b in sorted(self.values(), key=lambda b: b.level):
            part = b.data
            if start is not None and b.newest_s >= start:
                own = part.select(part.t >= start)
                part = own if own.n >= least else part
            if part.n >= least:
                usable.append(Bin(b.level, part))
        return usable

    def levels(self):
        """Return the current levels held [A], ascending."""
        return sorted(b.level for b in list(self.values()))


def fit_samples(bins, max_samples=0):
    """
    Join bins into the samples of a fit: time order, every k-th when more than ``max_samples``.

    Parameters
    ----------
    bins : list of Bin
        From :meth:`CurrentBins.usable`.
    max_samples : int
        Most samples of a fit (0: all).

    Returns
    -------
    DamperData

    """
    fit = DamperData.concatenate([b.data for b in bins])
    fit = fit.select(np.argsort(fit.t, kind='stable'))
    if max_samples and fit.n > max_samples:
        fit = fit.select(slice(None, None, int(math.ceil(fit.n / max_samples))))
    return fit
