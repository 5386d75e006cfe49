"""
Classic Bouc-Wen damper model, thesis eq. 2.30-2.31 as written.

::

    F    = c*v + k*x + alpha*z + f0
    zdot = delta*v - beta*v*|z|**n - gamma*z*|v|*|z|**(n - 1),     z(t[0]) = 0

Note the thesis form swaps the roles of beta and gamma against the usual notation: here
``gamma`` multiplies ``|v|`` (the dissipative term) and ``beta`` multiplies ``v``.

Integration on the sample grid: between samples the velocity is linear in time; each interval is
split into ``m`` equal sub-steps (``m`` from the stiffness of the batch, see ``_substeps``) and
z is advanced in the displacement increment ``du = v*h`` by a semi-implicit step, implicit in the
dissipative gamma term::

    z1 = (z0 + du*(delta - beta*|z0|**n)) / (1 + gamma*|du|*|z0|**(n - 1))

which has the exact saturation value ``|z| = (delta/(beta + gamma))**(1/n)`` as its fixed point
and never diverges for gamma >= 0. z is clipped to that saturation value (the exact solution from
z = 0 never exceeds it when beta + gamma > 0 and gamma >= 0), or to +-1e6 otherwise (unstable
parameter sets in the unbounded mode), so no overflow occurs.
"""
import math

import numpy as np

from mr_damper_model.models import compiled
from mr_damper_model.models import (cvkz_regressors, cvkz_separable_parts, HysteresisModel,
                                    ModelError)

_Z_CAP = 1e6
_MAX_SUBSTEPS = 200


def _saturation(delta, beta, gamma, n):
    """Saturation |z| = (|delta| / (beta + gamma))**(1/n), or the cap when not bounded."""
    b = beta + gamma
    ok = (b > 0) & (gamma >= 0)
    ratio = np.abs(delta) / np.where(ok, b, 1.0)
    zs = np.where(ok, ratio ** (1.0 / n), _Z_CAP)
    return np.minimum(zs, _Z_CAP)


def _substep_count(delta, beta, gamma, n, zs, v, t, max_du_rate):
    """Sub-steps per sample interval: (linearised stiffness in z) * |du| <= max_du_rate."""
    rate = n * np.abs(np.abs(beta) + np.abs(gamma)) * np.minimum(zs, 1e3) ** (n - 1.0)
    du_max = float(np.max(np.abs(v)) * np.max(np.diff(t)))
    return int(np.clip(np.ceil(np.max(rate) * du_max / max_du_rate), 1, _MAX_SUBSTEPS))


def _z_loop(delta, beta, gamma, n, zs, v, t, m, out):
    """
    Time loop of :func:`bouc_wen_z` over scalars.

    Compiled by :mod:`mr_damper_model.models.compiled`.

    Time outer, sub-steps, then the whole swarm innermost (independent particles in a row keep
    the processor busy while each one's division and power complete). The same semi-implicit
    step as :func:`bouc_wen_z_numpy`, with ``|z|**n`` formed as ``|z|**(n - 1) * |z|`` and the
    power as ``exp((n - 1) * log|z|)`` (agreement to round-off; n = 1 takes no power at all and
    is bit for bit the numpy result). Writes z into ``out`` (p, N), whose column 0 must hold
    zeros.
    """
    p = delta.shape[0]
    z = np.zeros(p)
    nm1 = n - 1.0
    for k in range(1, v.shape[0]):
        h = (t[k] - t[k - 1]) / m
        v0 = v[k - 1]
        dv = v[k] - v0
        for j in range(m):
            du = h * (v0 + ((j + 0.5) / m) * dv)
            adu = abs(du)
            for q in range(p):
                zq = z[q]
                az = abs(zq)
                pw = 1.0 if nm1[q] == 0.0 else math.exp(nm1[q] * math.log(az))
                zq = (zq + du * (delta[q] - beta[q] * (pw * az))) / (1.0 + gamma[q] * adu * pw)
                if zq > zs[q]:
                    zq = zs[q]
                elif zq < -zs[q]:
                    zq = -zs[q]
                z[q] = zq
        for q in range(p):
            out[q, k] = z[q]
    return out


def _prepare(delta, beta, gamma, n, v, t):
    arrs = [np.ascontiguousarray(a, dtype=float) for a in (delta, beta, gamma, n, v, t)]
    return arrs + [_saturation(*arrs[:4])]


def bouc_wen_z(delta, beta, gamma, n, v, t, *, max_du_rate=0.2):
    """
    Integrate the hysteretic variable z for a batch of parameter sets (compiled loop).

    Same scheme and sub-steps as :func:`bouc_wen_z_numpy` (the reference), equal to it within
    round-off; the loop over time is compiled by numba (:mod:`mr_damper_model.models.compiled`).

    Parameters
    ----------
    delta, beta, gamma, n : numpy.ndarray with shape (p,)
        delta [1/m], beta and gamma [1/m] (for z dimensionless), n [-] (>= 1).
    v : numpy.ndarray with shape (N,)
        Velocity [m/s].
    t : numpy.ndarray with shape (N,)
        Time [s], increasing.
    max_du_rate : float
        Sub-steps are chosen so that (linearised stiffness in z) * |du| <= max_du_rate.

    Returns
    -------
    numpy.ndarray with shape (p, N)

    """
    delta, beta, gamma, n, v, t, zs = _prepare(delta, beta, gamma, n, v, t)
    out = np.zeros((delta.shape[0], v.size))
    if v.size < 2:
        return out
    m = _substep_count(delta, beta, gamma, n, zs, v, t, max_du_rate)
    return compiled.kernel(_z_loop)(delta, beta, gamma, n, zs, v, t, m, out)


def bouc_wen_z_numpy(delta, beta, gamma, n, v, t, *, max_du_rate=0.2):
    """
    Integrate z with numpy, vectorised over the parameter sets (reference of :func:`bouc_wen_z`).

    Parameters and result as :func:`bouc_wen_z`.
    """
    delta, beta, gamma, n, v, t, zs = _prepare(delta, beta, gamma, n, v, t)
    p = delta.shape[0]
    N = v.size
    z = np.zeros(p)
    out = np.zeros((p, N))
    if N < 2:
        return out
    nm1 = n - 1.0
    dt = np.diff(t)
    m = _substep_count(delta, beta, gamma, n, zs, v, t, max_du_rate)
    fr = (np.arange(m) + 0.5) / m
    for k in range(1, N):
        h = dt[k - 1] / m
        v0 = v[k - 1]
        dv = v[k] - v0
        for j in range(m):
            du = h * (v0 + fr[j] * dv)
            az = np.abs(z)
            num = z + du * (delta - beta * az ** n)
            den = 1.0 + gamma * abs(du) * az ** nm1
            z = np.clip(num / den, -zs, zs)
        out[:, k] = z
    return out


class BoucWen(HysteresisModel):
    """
    Classic Bouc-Wen model (thesis eq. 2.30-2.31), stateful: needs ``t``.

    Parameters and units (z dimensionless): c [N s/m], k [N/m], alpha [N], f0 [N] (linear);
    delta [1/m], beta [1/m], gamma [1/m], n [-] (nonlinear). Strictly beta, gamma are in
    m**-1 with |z|**n dimensionless.

    Default bounds: c in [0, 1e5] N s/m, k in [0, 5e5] N/m, alpha in [0, 1e4] N,
    f0 in [-500, 500] N (as ``Kwok``); delta in [0, 2000] 1/m (a yield displacement of 0.5 mm
    or more), beta and gamma in [0, 2000] 1/m (gamma >= 0 and beta + gamma > 0 keep z
    bounded), n in [1, 3]. Unbounded: c in [-1e5, 1e5], k in [-1e6, 1e6], alpha in
    [-1e4, 1e4], f0 in [-1000, 1000], delta and beta in [-1e4, 1e4], gamma in [0, 1e4],
    n in [1, 4].
    """

    name = 'bouc-wen'
    param_names = ('c', 'k', 'alpha', 'f0', 'delta', 'beta', 'gamma', 'n')
    param_units = {'c': 'N s/m', 'k': 'N/m', 'alpha': 'N', 'f0': 'N', 'delta': '1/m',
                   'beta': '1/m', 'gamma': '1/m', 'n': '-'}
    linear_names = ('c', 'k', 'alpha', 'f0')
    stateful = True
    _bounds = {'c': (0.0, 1e5), 'k': (0.0, 5e5), 'alpha': (0.0, 1e4),
               'f0': (-500.0, 500.0), 'delta': (0.0, 2000.0), 'beta': (0.0, 2000.0),
               'gamma': (0.0, 2000.0), 'n': (1.0, 3.0)}
    _bounds_unbounded = {'c': (-1e5, 1e5), 'k': (-1e6, 1e6), 'alpha': (-1e4, 1e4),
                         'f0': (-1000.0, 1000.0), 'delta': (-1e4, 1e4), 'beta': (-1e4, 1e4),
                         'gamma': (0.0, 1e4), 'n': (1.0, 4.0)}

    def _z(self, N, v, t):
        if np.any(N[:, 2] < 0) or np.any(N[:, 3] < 1):
            raise ModelError('bouc-wen needs `gamma` >= 0 and `n` >= 1 (bounded z)')
        return bouc_wen_z(N[:, 0], N[:, 1], N[:, 2], N[:, 3], v, t)

    def _force(self, P, x, v, i, t):
        z = self._z(P[:, 4:8], v, t)
        q = self._split(P)
        return q['c'] * v + q['k'] * x + q['alpha'] * z + q['f0']

    def _regressors(self, N, x, v, i, t):
        z = self._z(N, v, t)
        return cvkz_regressors(N.shape[0], x, v, z)

    def _separable_parts(self, x, v, i, t):
        return cvkz_separable_parts(x, v)

    def _nonlinear_factor(self, N, x, v, i, t):
        return self._z(N, v, t)
