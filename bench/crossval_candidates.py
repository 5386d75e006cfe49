"""
Candidate models of docs/cross-validation.md that are not package models, on the same bench.

    .venv/bin/python bench/crossval_candidates.py --models kwok-current-amp-quad \
        kwok-current-cubic@i_ref_a=1 kwok-current-amp-cubic@i_ref_a=1 --polish --workers 1

Registers the prototypes below in the model registry (this process and the bench's worker
processes, which fork from it), then runs :func:`bench_crossval.main` with the same arguments:
same splits, seed, score and figures as the package models.

* ``kwok-current-amp-quad``: ``kwok-current-amp`` with the instantaneous sine amplitude
  ``V = sqrt(max(v**2 - x*dv/dt, 0))`` (exact for a centred sine, no hold time) instead of the
  decaying peak hold.
* ``kwok-current-cubic``, ``kwok-current-lag-cubic``, ``kwok-current-amp-cubic``,
  ``kwok-current-amp-quad-cubic``: an S-shaped alpha(i), one more linear parameter ``alpha3``
  multiplying ``s**2*(3 - 2*s)`` (smoothstep; with ``i_ref_a=1`` the four monotone terms of
  alpha(s) span every cubic on [0, 1 A]).
"""
import sys

import numpy as np

from mr_damper_model import models
from mr_damper_model.kwok_current import KwokCurrent
from mr_damper_model.kwok_current_amp import KwokCurrentAmp
from mr_damper_model.kwok_current_lag import KwokCurrentLag
from mr_damper_model.models import HysteresisModel, SeparableParts


def sine_amplitude(x, v, t):
    """Return ``sqrt(max(v**2 - x*a, 0))`` [m/s], ``a`` the backward difference of v."""
    a = np.zeros_like(v)
    if v.size > 1:
        a[1:] = np.diff(v) / np.diff(t)
        a[0] = a[1]
    return np.sqrt(np.maximum(v * v - x * a, 0.0))


class KwokCurrentAmpQuad(KwokCurrentAmp):
    name = 'kwok-current-amp-quad'

    def _force(self, P, x, v, i, t):
        self._x = x
        return super()._force(P, x, v, i, t)

    def _nonlinear_factor(self, N, x, v, i, t):
        self._x = x
        return super()._nonlinear_factor(N, x, v, i, t)

    def _scale_slope(self, a, extra, v, t):
        a /= 1.0 + extra[:, [0]] * sine_amplitude(self._x, v, t)


def _smoothstep(s):
    return s * s * (3.0 - 2.0 * s)


class _Cubic:
    """Adds ``alpha3*smoothstep(s)`` to alpha(s) (the last linear parameter)."""

    _jacobian = HysteresisModel._jacobian

    def _force(self, P, x, v, i, t):
        s = i / self.options['i_ref_a']
        N = P[:, [self.param_names.index(n) for n in self.nonlinear_names]]
        z = self._nonlinear_factor(N, x, v, i, t)
        return super()._force(P[:, :-1], x, v, i, t) + P[:, [-1]] * _smoothstep(s) * z

    def _regressors(self, N, x, v, i, t):
        phi = super()._regressors(N, x, v, i, t)
        if phi.shape[2] == len(self.linear_names):     # built from the separable parts
            return phi
        z = self._nonlinear_factor(N, x, v, i, t)
        s = i / self.options['i_ref_a']
        return np.concatenate([phi, (z * _smoothstep(s))[:, :, None]], axis=2)

    def _separable_parts(self, x, v, i, t):
        p = super()._separable_parts(x, v, i, t)
        s = i / self.options['i_ref_a']
        return SeparableParts(fixed_index=p.fixed_index, fixed=p.fixed,
                              factor_index=np.append(p.factor_index, len(self.linear_names) - 1),
                              weights=np.column_stack([p.weights, _smoothstep(s)]))


def _cubic(base, name):
    attrs = dict(name=name, param_names=base.param_names + ('alpha3',),
                 param_units=dict(base.param_units, alpha3='N'),
                 linear_names=base.linear_names + ('alpha3',),
                 _bounds=dict(base._bounds, alpha3=(0.0, 1e4)),
                 _bounds_unbounded=dict(base._bounds_unbounded, alpha3=(-1e4, 1e4)))
    if base is KwokCurrent:
        attrs['_nonlinear_factor'] = KwokCurrent._nonlinear_factor
    return type(name.title().replace('-', ''), (_Cubic, base), attrs)


CANDIDATES = [KwokCurrentAmpQuad] + [
    _cubic(base, name) for base, name in (
        (KwokCurrent, 'kwok-current-cubic'), (KwokCurrentLag, 'kwok-current-lag-cubic'),
        (KwokCurrentAmp, 'kwok-current-amp-cubic'),
        (KwokCurrentAmpQuad, 'kwok-current-amp-quad-cubic'))]
for _cls in CANDIDATES:
    globals()[_cls.__name__] = _cls
    models._REGISTRY[_cls.name] = (__name__, _cls.__name__)


if __name__ == '__main__':
    sys.modules.setdefault('crossval_candidates', sys.modules['__main__'])
    for _cls in CANDIDATES:
        models._REGISTRY[_cls.name] = ('crossval_candidates', _cls.__name__)
    import bench_crossval
    bench_crossval.main()
