"""
Bingham visco-plastic damper model (thesis eq. 2.33).

``F = fc*sign(v) + c0*v + f0``
"""
import numpy as np

from mr_damper_model.models import HysteresisModel


class Bingham(HysteresisModel):
    """
    Bingham model: Coulomb friction in parallel with a viscous dashpot.

    Parameters and units: ``fc`` friction (yield) force [N], ``c0`` viscous coefficient
    [N s/m], ``f0`` offset [N]; all enter linearly (no nonlinear parameters).

    Default bounds: fc in [0, 3000] N, c0 in [0, 5000] N s/m, f0 in [-200, 200] N.
    Unbounded: fc, c0 in [-1e4, 1e4], f0 in [-1000, 1000].
    """

    name = 'bingham'
    param_names = ('fc', 'c0', 'f0')
    param_units = {'fc': 'N', 'c0': 'N s/m', 'f0': 'N'}
    linear_names = ('fc', 'c0', 'f0')
    _bounds = {'fc': (0.0, 3000.0), 'c0': (0.0, 5000.0), 'f0': (-200.0, 200.0)}
    _bounds_unbounded = {'fc': (-1e4, 1e4), 'c0': (-1e4, 1e4), 'f0': (-1000.0, 1000.0)}

    def _force(self, P, x, v, i, t):
        q = self._split(P)
        return q['fc'] * np.sign(v) + q['c0'] * v + q['f0']

    def _regressors(self, N, x, v, i, t):
        p = N.shape[0]
        phi = np.empty((p, x.size, 3))
        phi[:, :, 0] = np.sign(v)
        phi[:, :, 1] = v
        phi[:, :, 2] = 1.0
        return phi
