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
* ``kwok-current-amp-level``: ``kwok-current-amp`` with the yield term ``alpha(i)*tanh(...)``
  scaled by ``exp(-eta*V)`` (one more swarm parameter, eta [s/m]): a force level that changes
  with the velocity amplitude (e.g. a fluid warmer in faster tests).
* ``kwok-table-amp``: ``kwok-current-amp`` with c(i) and alpha(i) tabulated at the tested
  currents 0, 0.25, 0.5, 0.75 and 1.0 A (ten linear parameters, interpolated linearly in i,
  held outside): the most flexible current dependence of c and alpha.
"""
import sys

import numpy as np

from mr_damper_model.models import base as models
from mr_damper_model.models.kwok_current import KwokCurrent, kwok_current_coefficients
from mr_damper_model.models.kwok_current_amp import KwokCurrentAmp, velocity_amplitude
from mr_damper_model.models.kwok_current_lag import KwokCurrentLag
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

    def _scale_slope(self, a, extra, x, v, t):
        a /= 1.0 + extra[:, [0]] * sine_amplitude(x, v, t)


class KwokCurrentAmpLevel(KwokCurrentAmp):
    """``kwok-current-amp`` with the yield term scaled by ``exp(-eta*V)``."""

    name = 'kwok-current-amp-level'
    param_names = KwokCurrentAmp.param_names + ('eta',)
    param_units = dict(KwokCurrentAmp.param_units, eta='s/m')
    _bounds = dict(KwokCurrentAmp._bounds, eta=(-20.0, 20.0))
    _bounds_unbounded = dict(KwokCurrentAmp._bounds_unbounded, eta=(-50.0, 50.0))

    def _force(self, P, x, v, i, t):
        s = i / self.options['i_ref_a']
        c, alpha, _ = kwok_current_coefficients(P, s)
        N = P[:, [self.param_names.index(n) for n in self.nonlinear_names]]
        z = self._nonlinear_factor(N, x, v, i, t)
        return c * v + P[:, [2]] * x + alpha * z + P[:, [9]]

    def _nonlinear_factor(self, N, x, v, i, t):
        z = super()._nonlinear_factor(N[:, :-1], x, v, i, t)
        return z * np.exp(-N[:, [-1]] * velocity_amplitude(v, t, self.options['tau_a']))


KNOTS_A = (0.0, 0.25, 0.5, 0.75, 1.0)


def hat_weights(i, knots=KNOTS_A):
    """Return (n, m) linear interpolation weights of currents ``i`` [A] on ``knots``."""
    basis = np.eye(len(knots))
    return np.column_stack([np.interp(i, knots, b) for b in basis])


class KwokTableAmp(KwokCurrentAmp):
    """``kwok-current-amp`` with c(i), alpha(i) tabulated at the current knots."""

    name = 'kwok-table-amp'
    _nk = len(KNOTS_A)
    _c = tuple(f'c_{j}' for j in range(_nk))
    _a = tuple(f'alpha_{j}' for j in range(_nk))
    param_names = _c + ('k',) + _a + ('f0', 'beta0', 'beta1', 'delta', 'tau0', 'tau1', 'kappa')
    param_units = dict({n: 'N s/m' for n in _c}, **{n: 'N' for n in _a}, k='N/m', f0='N',
                       beta0='s/m', beta1='-', delta='-', tau0='s', tau1='s', kappa='s/m')
    linear_names = _c + ('k',) + _a + ('f0',)
    _bounds = dict({n: (0.0, 1e5) for n in _c}, **{n: (0.0, 1e4) for n in _a},
                   k=(0.0, 5e5), f0=(-500.0, 500.0), beta0=(0.1, 1000.0), beta1=(-3.0, 3.0),
                   delta=(0.0, 3.0), tau0=(0.0, 0.05), tau1=(0.0, 0.05), kappa=(0.0, 1000.0))
    _bounds_unbounded = _bounds

    def _force(self, P, x, v, i, t):
        W = hat_weights(i)
        nk = self._nk
        z = self._nonlinear_factor(P[:, 2 * nk + 2:], x, v, i, t)
        c = P[:, :nk] @ W.T
        alpha = P[:, nk + 1:2 * nk + 1] @ W.T
        return c * v + P[:, [nk]] * x + alpha * z + P[:, [2 * nk + 1]]

    def _separable_parts(self, x, v, i, t):
        W = hat_weights(i)
        nk = self._nk
        return SeparableParts(
            fixed_index=np.array(list(range(nk)) + [nk, 2 * nk + 1]),
            fixed=np.column_stack([W * v[:, None], x, np.ones(x.size)]),
            factor_index=np.arange(nk + 1, 2 * nk + 1), weights=W)


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


CANDIDATES = [KwokCurrentAmpQuad, KwokCurrentAmpLevel, KwokTableAmp] + [
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
