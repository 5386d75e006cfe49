"""
The consistency reference of the live identifier: the set in use and its error by state (no ROS).

The last valid set of a stream is kept with its mean square error on the data it was fitted on,
per state cell (current level x displacement cell x velocity cell over the fit data's range):
the model error of a Kwok fit depends on the phase of the cycle (e.g. larger on one stroke of a
real damper), so new samples are compared with the error the set made at the same current and
state (:func:`consistency_figures`).  The window's new samples are judged with it
(``LiveIdentifier._consistency``), and so is each measurement batch as it arrives
(:func:`batch_consistency`): a batch whose force the set in use cannot explain is refused
before its stamps can carry the stream ahead.
"""
import math

import numpy as np

from mr_damper_model.io.data import DamperData
from mr_damper_model.models.kwok_current import kwok_current_force

#: Fewest screened samples on which the last valid set's consistency is judged.
MIN_CHECK_SAMPLES = 20
#: Cells per axis of the (displacement, velocity) grid of the consistency reference.
STATE_CELLS = 8
#: Fewest fitted samples in a reference cell for its error to count as known.
MIN_CELL_SAMPLES = 10


def model_force(params, data, i_ref_a):
    """Kwok-current force [N] of a parameter dict on ``data`` (reference current ``i_ref_a``)."""
    return kwok_current_force(dict(params, i_ref_a=i_ref_a), data.x, data.v, data.i)


def cell_codes(ref, data, bin_a):
    """Return the cell codes (current, x, v cell) of samples in ``ref``; -1 off its grid."""
    xe, ve = ref['x_edges'], ref['v_edges']
    ix = np.searchsorted(xe, data.x, side='right') - 1
    iv = np.searchsorted(ve, data.v, side='right') - 1
    ix[data.x == xe[-1]] = STATE_CELLS - 1
    iv[data.v == ve[-1]] = STATE_CELLS - 1
    inside = (ix >= 0) & (ix < STATE_CELLS) & (iv >= 0) & (iv < STATE_CELLS)
    keys = np.round(data.i / bin_a).astype(np.int64)
    code = (keys * STATE_CELLS + ix) * STATE_CELLS + iv
    return np.where(inside, code, -1)


def make_reference(est, fit, f_new, scale, bin_a):
    """
    Return a valid set as a consistency reference: its mean square error per state cell.

    Parameters
    ----------
    est : LiveEstimate
        The valid set (parameters, covered current range, window end).
    fit : DamperData
        The samples it was fitted on.
    f_new : numpy.ndarray
        Its force on ``fit`` [N].
    scale : float
        Robust force range of ``fit`` [N] (the error floor is a fraction of it).
    bin_a : float
        Current bin width [A].

    Returns
    -------
    dict
        ``parameters``, ``current_min_a``, ``current_max_a``, ``window_end_s``, ``x_edges``,
        ``v_edges``, ``scale``, ``cell_ms`` (cell code -> mean square error [N^2], cells with
        at least :data:`MIN_CELL_SAMPLES` samples).

    """
    x_edges = np.linspace(float(fit.x.min()), float(fit.x.max()), STATE_CELLS + 1)
    v_edges = np.linspace(float(fit.v.min()), float(fit.v.max()), STATE_CELLS + 1)
    ref = {'parameters': dict(est.parameters), 'current_min_a': est.current_min_a,
           'current_max_a': est.current_max_a, 'window_end_s': float(est.window_end_s),
           'x_edges': x_edges, 'v_edges': v_edges, 'scale': scale, 'cell_ms': {}}
    codes = cell_codes(ref, fit, bin_a)
    sq = (fit.f - f_new) ** 2
    ok = codes >= 0
    uniq, inverse, counts = np.unique(codes[ok], return_inverse=True, return_counts=True)
    sums = np.bincount(inverse, weights=sq[ok], minlength=uniq.size)
    ref['cell_ms'] = {int(u): float(m) for u, m, n in zip(uniq, sums / counts, counts)
                      if n >= MIN_CELL_SAMPLES}
    return ref


def consistency_figures(ref, new, config, average=np.mean):
    """
    Return (RMSE of the reference set on ``new``, its limit) [N], or None (not judged).

    The limit: ``max_shift_ratio`` times the set's RMS error on its own data in the same
    cells, plus ``error_floor_percent`` of its robust force range.  Samples in cells the set
    was not fitted on are not judged; fewer than :data:`MIN_CHECK_SAMPLES` judged samples (or
    no reference): None.  ``average``: of the squares (``np.median``: a robust figure, which a
    few spikes, the outlier screen's business, cannot move).
    """
    if ref is None or new.n < MIN_CHECK_SAMPLES:
        return None
    codes = cell_codes(ref, new, config.current_bin_a)
    cell_ms = ref['cell_ms']
    known = np.array([int(k) in cell_ms for k in codes], dtype=bool)
    if np.count_nonzero(known) < MIN_CHECK_SAMPLES:
        return None
    part = new.select(known)
    r = part.f - model_force(ref['parameters'], part, config.i_ref_a)
    expected = np.array([cell_ms[int(k)] for k in codes[known]])
    e_new = float(np.sqrt(average(r * r)))
    limit = (config.max_shift_ratio * float(np.sqrt(average(expected)))
             + 0.01 * config.error_floor_percent * ref['scale'])
    return e_new, limit


def batch_consistency(ref, t, x, v, f, i, config):
    """
    Judge a measurement batch against the set in use, as it arrives.

    Judged as :func:`consistency_figures` on the batch's finite samples within the sensor
    ranges, with medians of the squared errors (a spike or two in a batch is left to the
    outlier screen, which keeps the rest of the batch), only against a reference of the
    stream's recent past (its window ended at most one window length before the batch's first
    stamp: as the window gate judges no sample against a set fitted longer before it, not one
    left behind by a fitter that lags a replay).

    Parameters
    ----------
    ref : dict or None
        :func:`make_reference` of the set in use.
    t, x, v, f, i : numpy.ndarray with shape (n,)
        The batch: stamps [s], displacement [m], velocity [m/s], force [N], current [A].
    config : LiveConfig
        Ranges, ``current_bin_a``, ``i_ref_a``, ``max_shift_ratio``, ``error_floor_percent``,
        ``window_s``.

    Returns
    -------
    bool or None
        True if inconsistent, False if consistent, None if not judged.

    """
    if ref is None or t.shape[0] < MIN_CHECK_SAMPLES:
        return None
    with np.errstate(invalid='ignore'):
        ok = (np.isfinite(t) & np.isfinite(x) & np.isfinite(v) & np.isfinite(f)
              & np.isfinite(i) & (np.abs(f) <= config.force_limit_n)
              & (np.abs(v) <= config.velocity_limit_m_s)
              & (np.abs(x) <= config.displacement_limit_m)
              & (i >= config.current_limit_min_a) & (i <= config.current_limit_max_a))
    if np.count_nonzero(ok) < MIN_CHECK_SAMPLES:
        return None
    first = float(np.min(t[ok]))
    end = ref.get('window_end_s', math.nan)
    if not (first - end <= config.window_s):
        return None
    figures = consistency_figures(ref, DamperData(t[ok], x[ok], v[ok], f[ok], i[ok],
                                                  source='batch'), config, np.median)
    return None if figures is None else figures[0] > figures[1]
