"""
Kwok et al. (2006) hysteretic damper model (thesis eq. 2.34-2.35).

``F = c*v + k*x + alpha*tanh(beta*v + delta*sign(x)) + f0``
"""
import numpy as np

from mr_damper_model.models import HysteresisModel


class Kwok(HysteresisModel):
    """
    Kwok tanh hysteresis model.

    Parameters and units: ``c`` viscous coefficient [N s/m], ``k`` stiffness [N/m], ``alpha``
    hysteretic force scale [N], ``beta`` tanh slope [s/m], ``delta`` loop shift [-], ``f0`` force
    offset [N]. ``c, k, alpha, f0`` enter linearly; ``beta, delta`` nonlinearly.

    Default (physical) bounds: c in [0, 5000] N s/m (dissipative), k in [0, 2000] N/m (small
    gas-spring stiffness: at most 60 N over 30 mm), alpha in [0, 3000] N (yield force is
    non-negative), beta in [0.1, 300] s/m (positive slope, from nearly linear to nearly a sign
    function at 0.01 m/s), delta in [0, 3] (a positive shift makes the force lag the velocity,
    the loop direction of a real damper: at x > 0, v = 0 the force is still positive, as in thesis
    Table 4.3 where every delta is about +0.5), f0 in [-200, 200] N (accumulator / friction
    offset of either sign).

    ``default_bounds(unbounded=True)``: c, k, alpha in [-1e4, 1e4], f0 in [-1000, 1000],
    beta in [0, 1000] s/m, delta in [-5, 5] (contains every thesis Table 4.3 set).
    """

    name = 'kwok'
    param_names = ('c', 'k', 'alpha', 'beta', 'delta', 'f0')
    param_units = {'c': 'N s/m', 'k': 'N/m', 'alpha': 'N', 'beta': 's/m', 'delta': '-',
                   'f0': 'N'}
    linear_names = ('c', 'k', 'alpha', 'f0')
    _bounds = {'c': (0.0, 5000.0), 'k': (0.0, 2000.0), 'alpha': (0.0, 3000.0),
               'beta': (0.1, 300.0), 'delta': (0.0, 3.0), 'f0': (-200.0, 200.0)}
    _bounds_unbounded = {'c': (-1e4, 1e4), 'k': (-1e4, 1e4), 'alpha': (-1e4, 1e4),
                         'beta': (0.0, 1000.0), 'delta': (-5.0, 5.0), 'f0': (-1000.0, 1000.0)}

    def _force(self, P, x, v, i, t):
        q = self._split(P)
        z = np.tanh(q['beta'] * v + q['delta'] * np.sign(x))
        return q['c'] * v + q['k'] * x + q['alpha'] * z + q['f0']

    def _regressors(self, N, x, v, i, t):
        beta, delta = N[:, [0]], N[:, [1]]
        z = np.tanh(beta * v + delta * np.sign(x))
        p = N.shape[0]
        phi = np.empty((p, x.size, 4))
        phi[:, :, 0] = v
        phi[:, :, 1] = x
        phi[:, :, 2] = z
        phi[:, :, 3] = 1.0
        return phi
