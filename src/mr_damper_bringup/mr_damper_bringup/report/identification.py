"""Identification figures of a run: fit errors on the record, the offline yardstick, delays."""
from array import array
import math

import numpy as np

from mr_damper_bringup.report import recording
from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_common.recording.columnlog import open_log
from mr_damper_model.models.kwok_current import kwok_current_force


def fit_error(f_meas, f_model):
    """Return ``(rmse_n, nrmse_percent)``; NRMSE normalised by the measured force range."""
    f_meas = np.asarray(f_meas, dtype=float)
    err = np.asarray(f_model, dtype=float) - f_meas
    if f_meas.size == 0:
        return math.nan, math.nan
    rmse = float(np.sqrt(np.mean(err ** 2)))
    span = float(np.ptp(f_meas))
    return rmse, (100.0 * rmse / span if span > 0 else math.nan)


def record_error(meas, params):
    """
    ``(rmse_n, nrmse_percent)`` of kwok-current ``params`` on every sample of ``meas``, streamed.

    Same figures as :func:`fit_error` on the whole arrays (NRMSE by the measured force range).
    """
    meas = open_log(meas)
    if not _finite_set(params):
        return math.nan, math.nan
    n, se, fmin, fmax = 0, 0.0, math.inf, -math.inf
    for c in meas.chunks(recording.CHUNK_ROWS, ('x', 'v', 'f', 'i')):
        c = _finite_rows(c)
        if not c['f'].size:
            continue
        with np.errstate(over='ignore', invalid='ignore'):
            e = kwok_current_force(params, c['x'], c['v'], c['i']) - c['f']
        se += float(e @ e)
        n += e.size
        fmin, fmax = min(fmin, float(c['f'].min())), max(fmax, float(c['f'].max()))
    if n == 0:
        return math.nan, math.nan
    rmse = math.sqrt(se / n)
    span = fmax - fmin
    return rmse, (100.0 * rmse / span if span > 0 else math.nan)


def _finite_set(params):
    """Tell whether the ten kwok-current parameters of ``params`` are finite numbers."""
    return all(isinstance(params.get(n), (int, float)) and math.isfinite(params[n])
               for n in KWOK_CURRENT_NAMES)


def _finite_rows(cols):
    """Return the columns of ``cols`` (dict of equal-length arrays) at their all-finite rows."""
    cols = {k: np.asarray(v, dtype=float) for k, v in cols.items() if k != 'stride'}
    ok = np.all(np.isfinite(np.vstack(list(cols.values()))), axis=0)
    return cols if ok.all() else {k: v[ok] for k, v in cols.items()}


def offline_best_fit(meas, *, budget_s=5.0, max_samples=8000, seed=1):
    """
    Fit kwok-current offline to the whole record: a yardstick.

    The fit is ``mr_damper_model.identification.identify``.

    When the true damper is not a kwok-current model (the Spencer plant), no parameter can be
    compared with a truth; the best kwok-current fit of everything recorded says how close the
    live estimate is to the best this model can do. The fit uses at most ``max_samples`` evenly
    spaced samples; its error is then measured on every sample.

    Returns
    -------
    dict or None
        ``parameters``, ``rmse_n``, ``nrmse_percent`` (on the whole record), ``seconds``; None
        if the record covers fewer than two current levels or the fit fails.

    """
    from mr_damper_model.io.data import DamperData
    from mr_damper_model.identification.identify import identify
    meas = open_log(meas)
    sub = _finite_rows(meas.strided(max_samples, ('t', 'x', 'v', 'f', 'i')))
    t, x, v, f, i = (sub[k] for k in ('t', 'x', 'v', 'f', 'i'))
    if np.unique(np.round(i / 0.05)).size < 2:
        return None
    try:
        res = identify(DamperData(t, x, v, f, i, source='suite'), 'kwok-current', seed=seed,
                       budget_s=budget_s)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):
        return None
    p = dict(res.parameters, i_ref_a=float((res.model_options or {}).get('i_ref_a', 2.0)))
    rmse, nrmse = record_error(meas, p)
    return {'parameters': res.parameters, 'rmse_n': rmse, 'nrmse_percent': nrmse,
            'seconds': res.seconds}


def identification_summary(meas, params_log, truth=None, *, max_history=80,
                           offline_budget_s=5.0):
    """
    Identification figures of a run.

    Parameters
    ----------
    meas : column log, reader or dict
        Columns ``t, x, v, f, i`` of the recorded measurements
        (``mr_damper_common.recording.columnlog.open_log``); read in streamed passes.
    params_log : iterable of (float, dict)
        Wall receipt time [s] and decoded ``/mr_damper/kwok_parameters`` message; iterated a
        few times (a list, or :class:`ParamsLog` that reads its file on each pass).
    truth : dict, optional
        True kwok-current parameters (when the plant is kwok-current).
    max_history : int
        At most this many history entries are evaluated on the record.
    offline_budget_s : float
        Compute budget [s] of :func:`offline_best_fit` (run when there is no kwok-current
        truth; 0 = skip).

    Returns
    -------
    dict

    """
    meas = open_log(meas)
    n_upd, n_valid, first_valid, final = 0, 0, None, None
    for t, p in params_log:
        n_upd += 1
        if p.get('valid') == 1.0 and _finite_set(p):
            n_valid += 1
            final = p
            if first_valid is None:
                first_valid = t
    out = {'updates': n_upd, 'valid_updates': n_valid, 'first_valid_s': first_valid,
           'rmse_n': math.nan, 'nrmse_percent': math.nan, 'parameters': None, 'truth': None,
           'reported_rmse_n': math.nan, 'reported_nrmse_percent': math.nan, 'history': []}
    have = meas.rows > 0
    if final is not None:
        out['parameters'] = {n: final[n] for n in KWOK_CURRENT_NAMES if n in final}
        out['parameters']['i_ref_a'] = final.get('i_ref_a', 2.0)
        out['reported_rmse_n'] = final.get('rmse_n', math.nan)
        out['reported_nrmse_percent'] = final.get('nrmse_percent', math.nan)
        out['current_range_a'] = [final.get('current_min_a'), final.get('current_max_a')]
        if have:
            out['rmse_n'], out['nrmse_percent'] = record_error(meas, final)
    if truth:
        tp = {n: truth[n] for n in KWOK_CURRENT_NAMES if n in truth}
        if len(tp) == len(KWOK_CURRENT_NAMES):
            tp['i_ref_a'] = truth.get('i_ref_a', 2.0)
            out['truth'] = tp
            if out['parameters']:
                out['parameter_error_percent'] = {
                    n: (100.0 * (out['parameters'][n] - tp[n]) / abs(tp[n]) if tp[n] else math.nan)
                    for n in KWOK_CURRENT_NAMES}
            if have:
                out['truth_rmse_n'], out['truth_nrmse_percent'] = record_error(meas, tp)
    if have and not out['truth'] and offline_budget_s > 0:
        out['offline_best_fit'] = offline_best_fit(meas, budget_s=offline_budget_s)
    step = max(1, int(math.ceil(n_upd / max_history)))
    picks = set(range(0, n_upd, step)) | ({n_upd - 1} if n_upd else set())
    dec = _finite_rows(meas.strided(20000, ('x', 'v', 'f', 'i')))   # <= ~20k samples each
    x, v, f, i = (dec[k] for k in 'xvfi')
    for k, (t, p) in enumerate(params_log):
        if k not in picks:
            continue
        entry = {'t_s': t, 'valid': p.get('valid') == 1.0, 'rmse_n': p.get('rmse_n'),
                 'nrmse_percent': p.get('nrmse_percent'),
                 'parameters': {n: p.get(n) for n in KWOK_CURRENT_NAMES}}
        if f.size and _finite_set(p):
            with np.errstate(over='ignore', invalid='ignore'):
                fm = kwok_current_force(p, x, v, i)
            if np.all(np.isfinite(fm)):
                entry['record_rmse_n'], entry['record_nrmse_percent'] = fit_error(f, fm)
        out['history'].append(entry)
    return out


def measurement_to_parameters(meas, params_log):
    """
    Delays [s] from the newest measurement of each identified window to its parameters.

    Each window counts once, at its first arrival: a set the identifier publishes again (it
    refused a newer window and keeps the set in use) is not a new identification.

    The newest sample's arrival (``mr-damper-record`` receives the measurement stream as the
    identifier does) is found from its stamp ``window_end_s``; the delay runs to the arrival of
    the parameter message at the recorder (the quarter car subscribes to it the same way and
    uses it from its next 1 ms step on). Windows older than the record are ignored. The record
    is read in one streamed pass.

    Returns
    -------
    numpy.ndarray
        One delay per parameter message [s].

    """
    meas = open_log(meas)
    if meas.rows < 2 or 'recv_epoch_s' not in meas.columns:
        return np.zeros(0)
    ends, gots = array('d'), array('d')
    for _, p in params_log:
        end, got = p.get('window_end_s', math.nan), p.get('recv_epoch_s', math.nan)
        if end is not None and got is not None and math.isfinite(end) and math.isfinite(got):
            ends.append(end)
            gots.append(got)
    if not ends:
        return np.zeros(0)
    ends, gots = np.frombuffer(ends, dtype=float), np.frombuffer(gots, dtype=float)
    order = np.argsort(ends, kind='stable')
    ends, gots = ends[order], gots[order]
    # a set re-published (a refused window keeps the set in use, with its window) is not a new
    # identification: each window counts once, from its first arrival
    ends, first = np.unique(ends, return_index=True)
    gots = np.minimum.reduceat(gots, first)
    delays = np.full(ends.size, np.nan)
    k = None
    for c in meas.chunks(recording.CHUNK_ROWS, ('t', 'recv_epoch_s'), overlap=1):
        t, recv = c['t'], c['recv_epoch_s']
        if k is None:           # windows ending before the record are ignored
            k = int(np.searchsorted(ends, t[0], side='left'))
        stop = int(np.searchsorted(ends, t[-1], side='right'))
        if stop > k:
            delays[k:stop] = gots[k:stop] - np.interp(ends[k:stop], t, recv)
            k = stop
    return delays[np.isfinite(delays)]
