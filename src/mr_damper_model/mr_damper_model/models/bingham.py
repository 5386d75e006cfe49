"""
Bingham visco-plastic damper model (thesis eq. 2.33).

``F = fc*sign(v) + c0*v + f0``
"""
import numpy as np

from mr_damper_model.models import HysteresisModel, SeparableParts


class Bingham(HysteresisModel):
    """
    Bingham model: Coulomb friction in parallel with a viscous dashpot.

    Parameters and units: ``fc`` friction (yield) force [N], ``c0`` viscous coefficient
    [N s/m], ``f0`` offset [N]; all enter linearly (no nonlinear parameters).

    Default bounds (physical, wide enough for dampers of a few kN; the Quiroz damper reached
    the former c0 <= 5000 N s/m on most files): fc in [0, 1e4] N, c0 in [0, 1e5] N s/m,
    f0 in [-500, 500] N. Unbounded: fc in [-1e4, 1e4], c0 in [-1e5, 1e5], f0 in [-1000, 1000].
    """

    name = 'bingham'
    param_names = ('fc', 'c0', 'f0')
    param_units = {'fc': 'N', 'c0': 'N s/m', 'f0': 'N'}
    linear_names = ('fc', 'c0', 'f0')
    _bounds = {'fc': (0.0, 1e4), 'c0': (0.0, 1e5), 'f0': (-500.0, 500.0)}
    _bounds_unbounded = {'fc': (-1e4, 1e4), 'c0': (-1e5, 1e5), 'f0': (-1000.0, 1000.0)}

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

    def _separable_parts(self, x, v, i, t):
        n = x.size
        return SeparableParts(fixed_index=np.arange(3),
                              fixed=np.column_stack([np.sign(v), v, np.ones(n)]),
                              factor_index=np.zeros(0, dtype=int), weights=np.zeros((n, 0)))

    def _nonlinear_factor(self, N, x, v, i, t):
        return np.zeros((N.shape[0], x.size))

    def _jacobian(self, p, x, v, i, t):
        return np.column_stack([np.sign(v), v, np.ones(x.size)])
