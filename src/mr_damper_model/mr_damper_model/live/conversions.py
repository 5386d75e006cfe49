"""Conversions between the plain Kwok and the current-dependent Kwok parameter sets (no ROS)."""
import numpy as np

from mr_damper_common.contract import KWOK_CURRENT_NAMES
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
