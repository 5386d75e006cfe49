"""Conversions of parameter sets: plain Kwok and current-dependent Kwok, a file to an estimate."""
import math

import numpy as np

from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_model.live.fitting import parameter_reason
from mr_damper_model.live.window import LiveEstimate
from mr_damper_model.models.kwok_current import kwok_current_coefficients


def kwok_to_kwok_current(p):
    """
    Write Kwok parameters as a current-independent kwok-current set.

    Parameters
    ----------
    p : dict
        Kwok parameters (c, k, alpha, beta, delta, f0).

    Returns
    -------
    dict
        kwok-current parameters with c1 = alpha1 = alpha2 = beta1 = 0.

    """
    return {'c0': p['c'], 'c1': 0.0, 'k': p['k'], 'alpha0': p['alpha'], 'alpha1': 0.0,
            'alpha2': 0.0, 'beta0': p['beta'], 'beta1': 0.0, 'delta': p['delta'], 'f0': p['f0']}


def kwok_current_at(p, current_a, i_ref_a=2.0):
    """
    Evaluate kwok-current parameters at one current as a Kwok set.

    Parameters
    ----------
    p : dict
        kwok-current parameters.
    current_a : float
        Coil current [A].
    i_ref_a : float
        Reference current [A].

    Returns
    -------
    dict
        Kwok parameters c(i), k, alpha(i), beta(i), delta, f0.

    """
    row = np.array([[p[n] for n in KWOK_CURRENT_NAMES]], dtype=float)
    c, alpha, beta = kwok_current_coefficients(row, np.array([current_a / i_ref_a]))
    return {'c': float(c[0, 0]), 'k': p['k'], 'alpha': float(alpha[0, 0]),
            'beta': float(beta[0, 0]), 'delta': p['delta'], 'f0': p['f0']}


def initial_estimate(initial, config):
    """
    Return the identifier's first estimate from an initial set (a parameter file's content).

    Parameters
    ----------
    initial : dict or ParamsFile
        A kwok-current or kwok set (``model``, ``parameters``, optional ``model_options``,
        ``metrics``, ``valid``, current range).
    config : LiveConfig
        ``i_ref_a``, ``unbounded``, ``max_nrmse_percent``.

    Returns
    -------
    LiveEstimate
        ``model_fitted`` ``'file'``; not valid (with the reason) when stored as not valid, at
        another reference current, out of bounds or above the NRMSE threshold.

    Raises
    ------
    ValueError
        Another model than kwok or kwok-current.

    """
    d = initial.to_json_dict() if hasattr(initial, 'to_json_dict') else dict(initial)
    model = d.get('model', 'kwok-current')
    params = dict(d['parameters'])
    i_ref = float((d.get('model_options') or {}).get('i_ref_a', config.i_ref_a))
    if model == 'kwok':
        params = kwok_to_kwok_current(params)
    elif model != 'kwok-current':
        raise ValueError(f'`initial`: model {model!r} is not kwok or kwok-current')
    params = {n: float(params[n]) for n in KWOK_CURRENT_NAMES}
    metrics = d.get('metrics') or {}
    nrmse = float(metrics.get('nrmse_percent', math.nan) if metrics.get(
        'nrmse_percent') is not None else math.nan)
    rmse = float(metrics.get('rmse_n') if metrics.get('rmse_n') is not None else math.nan)
    reason = '' if d.get('valid', True) else 'stored_invalid'
    if not reason and i_ref != config.i_ref_a:
        reason = 'i_ref_mismatch'
    if not reason:
        reason = parameter_reason('kwok-current', params, config.unbounded, i_ref)
    if not reason and not (nrmse <= config.max_nrmse_percent):
        reason = 'nrmse_above_threshold'
    return LiveEstimate(parameters=params, valid=not reason, reason=reason,
                        model_fitted='file', i_ref_a=i_ref, window_end_s=0.0,
                        window_start_s=0.0,
                        current_min_a=float(d.get('current_min_a', math.nan)),
                        current_max_a=float(d.get('current_max_a', math.nan)),
                        rmse_n=rmse, nrmse_percent=nrmse)


def warm_start(solutions, model, levels, i_ref_a):
    """
    Return the warm start of a fit of ``model`` from the last solutions, or None.

    Parameters
    ----------
    solutions : dict
        Model name (``'kwok'``, ``'kwok-current'``) -> last parameter dict.
    model : str
        The model to fit.
    levels : list of float
        Current levels of the fit data [A] (a kwok fit starts from the kwok-current set at
        the first one).
    i_ref_a : float
        Reference current of the kwok-current model [A].

    """
    if model in solutions:
        return dict(solutions[model])
    if model == 'kwok' and 'kwok-current' in solutions:
        return kwok_current_at(solutions['kwok-current'], levels[0], i_ref_a)
    if model == 'kwok-current' and 'kwok' in solutions:
        return kwok_to_kwok_current(solutions['kwok'])
    return None
