"""
The consistency reference of the live identifier: the set in use and its error by state (no ROS).

The last valid set of a stream is kept with its mean square error on the data it was fitted on,
per state cell (current level x displacement cell x velocity cell over the fit data's range):
the model error of a Kwok fit depends on the phase of the cycle (e.g. larger on one stroke of a
real damper), so new samples are compared with the error the set made at the same current and
state (:meth:`ConsistencyReference.figures`).  The window's new samples are judged with it
(``LiveIdentifier._consistency``, block by block at the onset of a fault:
:meth:`ConsistencyReference.consistent_blocks`), and so is each measurement batch as it arrives
(:meth:`ConsistencyReference.judge_batch`): a batch whose force the set in use cannot explain
is refused before its stamps can carry the stream ahead.
"""
from dataclasses import dataclass, field

import numpy as np

from mr_damper_model.io.data import DamperData
from mr_damper_model.models.kwok_current import kwok_current_force

#: Fewest screened samples on which the last valid set's consistency is judged.
MIN_CHECK_SAMPLES = 20
#: Cells per axis of the (displacement, velocity) grid of the consistency reference.
STATE_CELLS = 8
#: Fewest fitted samples in a reference cell for its error to count as known.
MIN_CELL_SAMPLES = 10
#: Samples per block when an inconsistent part is judged block by block.
BLOCK_SAMPLES = 2 * MIN_CHECK_SAMPLES


def model_force(params, data, i_ref_a):
    """Kwok-current force [N] of a parameter dict on ``data`` (reference current ``i_ref_a``)."""
    return kwok_current_force(dict(params, i_ref_a=i_ref_a), data.x, data.v, data.i)


@dataclass
class ConsistencyReference:
    """
    A valid set as a consistency reference: its mean square error per state cell.

    Attributes
    ----------
    parameters : dict
        The set's kwok-current parameters (SI units).
    current_min_a, current_max_a : float
        Current range it was fitted on [A].
    window_end_s : float
        End of the window it was fitted on [s].
    x_edges, v_edges : numpy.ndarray with shape (STATE_CELLS + 1,)
        Displacement [m] and velocity [m/s] cell edges over its fit data's range.
    scale : float
        Robust force range of its fit data [N] (the error floor is a fraction of it).
    cell_ms : dict
        Cell code -> mean square error [N^2] on its fit data, cells with at least
        :data:`MIN_CELL_SAMPLES` samples.

    """

    parameters: dict
    current_min_a: float
    current_max_a: float
    window_end_s: float
    x_edges: np.ndarray
    v_edges: np.ndarray
    scale: float
    cell_ms: dict = field(default_factory=dict)

    @classmethod
    def from_fit(cls, est, fit, f_new, scale, bin_a):
        """
        Make the reference of a valid set.

        Parameters
        ----------
        est : LiveEstimate
            The valid set (parameters, covered current range, window end).
        fit : DamperData
            The samples it was fitted on.
        f_new : numpy.ndarray
            Its force on ``fit`` [N].
        scale : float
            Robust force range of ``fit`` [N].
        bin_a : float
            Current bin width [A].

        Returns
        -------
        ConsistencyReference

        """
        ref = cls(dict(est.parameters), est.current_min_a, est.current_max_a,
                  float(est.window_end_s),
                  np.linspace(float(fit.x.min()), float(fit.x.max()), STATE_CELLS + 1),
                  np.linspace(float(fit.v.min()), float(fit.v.max()), STATE_CELLS + 1), scale)
        codes = ref.cell_codes(fit, bin_a)
        sq = (fit.f - f_new) ** 2
        ok = codes >= 0
        uniq, inverse, counts = np.unique(codes[ok], return_inverse=True, return_counts=True)
        sums = np.bincount(inverse, weights=sq[ok], minlength=uniq.size)
        ref.cell_ms = {int(u): float(m) for u, m, n in zip(uniq, sums / counts, counts)
                       if n >= MIN_CELL_SAMPLES}
        return ref

    def cell_codes(self, data, bin_a):
        """Return the cell codes (current, x, v cell) of samples of ``data``; -1 off the grid."""
        xe, ve = self.x_edges, self.v_edges
        ix = np.searchsorted(xe, data.x, side='right') - 1
        iv = np.searchsorted(ve, data.v, side='right') - 1
        ix[data.x == xe[-1]] = STATE_CELLS - 1
        iv[data.v == ve[-1]] = STATE_CELLS - 1
        inside = (ix >= 0) & (ix < STATE_CELLS) & (iv >= 0) & (iv < STATE_CELLS)
        keys = np.round(data.i / bin_a).astype(np.int64)
        code = (keys * STATE_CELLS + ix) * STATE_CELLS + iv
        return np.where(inside, code, -1)

    def covered(self, data, bin_a):
        """Mask of the samples of ``data`` at current levels the set was fitted on."""
        tol = 0.5 * bin_a
        return (data.i >= self.current_min_a - tol) & (data.i <= self.current_max_a + tol)

    def figures(self, new, config, average=np.mean):
        """
        Return (RMSE of the set on ``new``, its limit) [N], or None (not judged).

        The limit: ``max_shift_ratio`` times the set's RMS error on its own data in the same
        cells, plus ``error_floor_percent`` of its robust force range.  Samples in cells the set
        was not fitted on are not judged; fewer than :data:`MIN_CHECK_SAMPLES` judged samples:
        None.  ``average``: of the squares (``np.median``: a robust figure, which a few spikes,
        the outlier screen's business, cannot move).
        """
        if new.n < MIN_CHECK_SAMPLES:
            return None
        codes = self.cell_codes(new, config.current_bin_a)
        cell_ms = self.cell_ms
        known = np.array([int(k) in cell_ms for k in codes], dtype=bool)
        if np.count_nonzero(known) < MIN_CHECK_SAMPLES:
            return None
        part = new.select(known)
        r = part.f - model_force(self.parameters, part, config.i_ref_a)
        expected = np.array([cell_ms[int(k)] for k in codes[known]])
        e_new = float(np.sqrt(average(r * r)))
        limit = (config.max_shift_ratio * float(np.sqrt(average(expected)))
                 + 0.01 * config.error_floor_percent * self.scale)
        return e_new, limit

    def judge_batch(self, t, x, v, f, i, config):
        """
        Judge a measurement batch against the set, as it arrives.

        Judged as :meth:`figures` on the batch's finite samples within the sensor ranges, with
        medians of the squared errors (a spike or two in a batch is left to the outlier screen,
        which keeps the rest of the batch), only against a reference of the stream's recent
        past (its window ended at most one window length before the batch's first stamp: as
        the window gate judges no sample against a set fitted longer before it, not one left
        behind by a fitter that lags a replay).

        Parameters
        ----------
        t, x, v, f, i : numpy.ndarray with shape (n,)
            The batch: stamps [s], displacement [m], velocity [m/s], force [N], current [A].
        config : LiveConfig
            Ranges, ``current_bin_a``, ``i_ref_a``, ``max_shift_ratio``,
            ``error_floor_percent``, ``window_s``.

        Returns
        -------
        bool or None
            True if inconsistent, False if consistent, None if not judged.

        """
        if t.shape[0] < MIN_CHECK_SAMPLES:
            return None
        with np.errstate(invalid='ignore'):
            ok = (np.isfinite(t) & np.isfinite(x) & np.isfinite(v) & np.isfinite(f)
                  & np.isfinite(i) & (np.abs(f) <= config.force_limit_n)
                  & (np.abs(v) <= config.velocity_limit_m_s)
                  & (np.abs(x) <= config.displacement_limit_m)
                  & (i >= config.current_limit_min_a) & (i <= config.current_limit_max_a))
        if np.count_nonzero(ok) < MIN_CHECK_SAMPLES:
            return None
        if not (float(np.min(t[ok])) - self.window_end_s <= config.window_s):
            return None
        figures = self.figures(DamperData(t[ok], x[ok], v[ok], f[ok], i[ok], source='batch'),
                               config, np.median)
        return None if figures is None else figures[0] > figures[1]

    def consistent_blocks(self, new, config):
        """
        Mask of the samples of an inconsistent part before the onset of the inconsistency.

        The part is cut into blocks of :data:`BLOCK_SAMPLES` consecutive samples (the last one
        takes the remainder), each judged on its own (enough samples in known cells); when
        consistent blocks are followed only by inconsistent ones, a fault (or change) began
        inside the part and the blocks before it are kept, less an exactly constant run that
        goes on into the first inconsistent block (a stuck load cell's first samples).  Any
        other pattern keeps nothing.
        """
        keep = np.zeros(new.n, dtype=bool)
        n_blocks = new.n // BLOCK_SAMPLES
        if n_blocks < 2:
            return keep
        good = np.zeros(n_blocks, dtype=bool)
        for b in range(n_blocks):
            lo = b * BLOCK_SAMPLES
            hi = new.n if b == n_blocks - 1 else lo + BLOCK_SAMPLES
            figures = self.figures(new.select(slice(lo, hi)), config)
            good[b] = figures is not None and figures[0] <= figures[1]
        # one step, from consistent blocks to inconsistent ones (an onset); any other pattern
        # (a persistent fault that some blocks happen to match) counts whole
        if not good[0] or np.count_nonzero(good[1:] != good[:-1]) != 1:
            return keep
        keep[:] = np.repeat(good, np.diff(np.r_[np.arange(n_blocks) * BLOCK_SAMPLES, new.n]))
        # a constant run that goes on into the first inconsistent block is that fault's start
        # (a stuck load cell stays close to the true force for a while): cut before it
        j = int(np.argmin(keep))
        while j > 0 and new.f[j - 1] == new.f[j]:
            j -= 1
        keep[j:] = False
        return keep

    def rmse_on(self, fit, f_new, i_ref_a, bin_a):
        """
        Return (RMSE of a new set, RMSE of this set) [N] on ``fit``'s samples it covers, or None.

        ``f_new``: the new set's force on ``fit`` [N]; None with fewer than
        :data:`MIN_CHECK_SAMPLES` covered samples.
        """
        cov = self.covered(fit, bin_a)
        if np.count_nonzero(cov) < MIN_CHECK_SAMPLES:
            return None
        e_new = float(np.sqrt(np.mean((fit.f[cov] - f_new[cov]) ** 2)))
        f_prev = model_force(self.parameters, fit.select(cov), i_ref_a)
        return e_new, float(np.sqrt(np.mean((fit.f[cov] - f_prev) ** 2)))
