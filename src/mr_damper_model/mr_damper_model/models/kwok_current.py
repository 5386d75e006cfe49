"""
Current-dependent Kwok model ("kwok-current"), one parameter set for the whole current range.

With ``s = i / i_ref_a``::

    c(i)     = c0 + c1*s
    alpha(i) = alpha0 + alpha1*s*(2 - s) + alpha2*s**2
    beta(i)  = beta0*exp(beta1*s)
    F = c(i)*v + k*x + alpha(i)*tanh(beta(i)*v + delta*sign(x)) + f0

Why this form: with non-negative c0, c1, alpha0, alpha1, alpha2 (the default box bounds) c(i)
and alpha(i) are non-decreasing on [0, i_ref_a]: s*(2 - s) and s**2 are the Bernstein basis of
the quadratics that are monotone on [0, 1], so the box spans exactly the monotone quadratics;
alpha1 > alpha2 gives saturating growth (magnetic saturation of the MR fluid), alpha2 > alpha1
convex growth. beta(i) stays positive for every beta1. All of c0..alpha2, k and f0 enter the
force linearly, so the separable PSO searches only beta0, beta1 and delta.
"""
import math

import numpy as np

from mr_damper_common.contract import KWOK_CURRENT_NAMES
from mr_damper_model.models.base import HysteresisModel, ModelError, SeparableParts


def kwok_current_coefficients(P, s):
    """
    Evaluate c(i), alpha(i), beta(i) for parameter rows P and normalised currents s.

    Parameters
    ----------
    P : numpy.ndarray with shape (p, 10)
        Parameter rows in ``KwokCurrent.param_names`` order.
    s : numpy.ndarray with shape (n,)
        Normalised current i / i_ref_a [-].

    Returns
    -------
    tuple of numpy.ndarray, each (p, n)
        c [N s/m], alpha [N], beta [s/m].

    """
    c = P[:, [0]] + P[:, [1]] * s
    alpha = P[:, [3]] + P[:, [4]] * s * (2.0 - s) + P[:, [5]] * s * s
    beta = P[:, [6]] * np.exp(np.clip(P[:, [7]] * s, -50.0, 50.0))
    return c, alpha, beta


def kwok_current_force_scalar(p, s, x, v):
    """
    Kwok-current force [N] for one sample, in plain floats (1 kHz loops: plant, inverse).

    Parameters
    ----------
    p : sequence of float
        The ten parameters in ``KwokCurrent.param_names`` order.
    s : float
        Normalised current i / i_ref_a [-].
    x : float
        Displacement [m].
    v : float
        Velocity [m/s].

    Returns
    -------
    float

    """
    c, alpha, beta, _ = _coefficients(p, s)
    sx = 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)
    return c * v + p[2] * x + alpha * math.tanh(beta * v + p[8] * sx) + p[9]


def kwok_current_force(params, x, v, i):
    """
    Kwok-current force [N] of a named parameter set on arrays of samples.

    Parameters
    ----------
    params : dict
        The ten parameters by name, and ``i_ref_a`` [A] (default 2.0); other keys (e.g. a
        decoded parameters message's fit figures) are ignored.
    x, v, i : numpy.ndarray with shape (n,)
        Displacement [m], velocity [m/s], coil current [A].

    Returns
    -------
    numpy.ndarray with shape (n,)

    """
    model = KwokCurrent(i_ref_a=float(params.get('i_ref_a', 2.0)))
    return model.force(model.from_dict(params), x, v, i=i)


def _coefficients(p, s):
    """Return ``c(s)``, ``alpha(s)``, ``beta(s)`` and beta's exponent ``b1 s`` (one home)."""
    c0, c1, k, a0, a1, a2, b0, b1, delta, f0 = p
    bs = b1 * s
    return (c0 + c1 * s, a0 + a1 * s * (2.0 - s) + a2 * s * s,
            b0 * math.exp(max(-50.0, min(50.0, bs))), bs)


def kwok_current_terms_scalar(p, s):
    """
    Evaluate the current-dependent terms of the kwok-current force at one normalised current.

    Parameters
    ----------
    p : sequence of float
        The ten parameters in ``KwokCurrent.param_names`` order.
    s : float
        Normalised current i / i_ref_a [-].

    Returns
    -------
    tuple of float
        ``c(i)`` [N s/m], ``alpha(i)`` [N], ``beta(i)`` [s/m], and their slopes over s
        ``d alpha/ds`` [N] and ``d beta/ds`` [s/m] (0 where beta's exponent is clipped at
        +-50); ``dc/ds`` is ``c1``.

    """
    c, alpha, beta, bs = _coefficients(p, s)
    a1, a2, b1 = p[4], p[5], p[7]
    return (c, alpha, beta, 2.0 * (a1 * (1.0 - s) + a2 * s),
            b1 * beta if -50.0 < bs < 50.0 else 0.0)


def kwok_current_force_slope_at(terms, p, x, v):
    """
    Kwok-current force [N] and its slope dF/ds [N] from the terms at one current.

    The force is :func:`kwok_current_force_scalar`'s at that current (the same operations, so
    the same float); the slope ``dF/ds = c1 v + alpha'(s) z + alpha(s) (1 - z**2) beta'(s) v``
    with ``z = tanh(beta v + delta sign(x))`` tells the scalar inverse whether F(i) has an
    interior extremum. With the terms of a fixed current (the ends of a current range) computed
    once, one sample costs one ``tanh``.

    Parameters
    ----------
    terms : tuple of float
        :func:`kwok_current_terms_scalar` at the current.
    p : sequence of float
        The ten parameters in ``KwokCurrent.param_names`` order.
    x : float
        Displacement [m].
    v : float
        Velocity [m/s].

    Returns
    -------
    force, slope : float

    """
    c, alpha, beta, dalpha, dbeta = terms
    sx = 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)
    z = math.tanh(beta * v + p[8] * sx)
    return (c * v + p[2] * x + alpha * z + p[9],
            p[1] * v + dalpha * z + alpha * (1.0 - z * z) * dbeta * v)


class KwokCurrent(HysteresisModel):
    """
    Current-dependent Kwok model.

    Parameters and units: c0, c1 [N s/m]; k [N/m]; alpha0, alpha1, alpha2 [N]; beta0 [s/m];
    beta1 [-] (log-slope of beta over 0..i_ref_a); delta [-]; f0 [N]. Option ``i_ref_a``
    (reference current [A], default 2.0, the top of the thesis range).

    Default bounds (physical, wide enough for dampers of a few kN; see ``Kwok``): c0, c1 in
    [0, 1e5] N s/m; k in [0, 5e5] N/m; alpha0..2 in [0, 1e4] N; beta0 in [0.1, 1000] s/m;
    beta1 in [-3, 3] (beta changes at most by e**3 over the range); delta in [0, 3];
    f0 in [-500, 500] N. Unbounded: c0, c1 in [-1e5, 1e5]; k in [-1e6, 1e6];
    alpha0..2 in [-1e4, 1e4]; beta0 in [0, 1000] s/m; beta1 in [-5, 5]; delta in [-5, 5];
    f0 in [-1000, 1000] N.
    """

    name = 'kwok-current'
    param_names = KWOK_CURRENT_NAMES
    param_units = {'c0': 'N s/m', 'c1': 'N s/m', 'k': 'N/m', 'alpha0': 'N', 'alpha1': 'N',
                   'alpha2': 'N', 'beta0': 's/m', 'beta1': '-', 'delta': '-', 'f0': 'N'}
    linear_names = ('c0', 'c1', 'k', 'alpha0', 'alpha1', 'alpha2', 'f0')
    needs_current = True
    _bounds = {'c0': (0.0, 1e5), 'c1': (0.0, 1e5), 'k': (0.0, 5e5),
               'alpha0': (0.0, 1e4), 'alpha1': (0.0, 1e4), 'alpha2': (0.0, 1e4),
               'beta0': (0.1, 1000.0), 'beta1': (-3.0, 3.0), 'delta': (0.0, 3.0),
               'f0': (-500.0, 500.0)}
    _bounds_unbounded = {'c0': (-1e5, 1e5), 'c1': (-1e5, 1e5), 'k': (-1e6, 1e6),
                         'alpha0': (-1e4, 1e4), 'alpha1': (-1e4, 1e4), 'alpha2': (-1e4, 1e4),
                         'beta0': (0.0, 1000.0), 'beta1': (-5.0, 5.0), 'delta': (-5.0, 5.0),
                         'f0': (-1000.0, 1000.0)}

    def __init__(self, i_ref_a=2.0):
        i_ref_a = float(i_ref_a)
        if not np.isfinite(i_ref_a) or i_ref_a <= 0:
            raise ModelError(f'`i_ref_a` must be a positive current [A], got {i_ref_a}')
        self.options = {'i_ref_a': i_ref_a}

    def _force(self, P, x, v, i, t):
        s = i / self.options['i_ref_a']
        c, alpha, beta = kwok_current_coefficients(P, s)
        z = np.tanh(beta * v + P[:, [8]] * np.sign(x))
        return c * v + P[:, [2]] * x + alpha * z + P[:, [9]]

    def _regressors(self, N, x, v, i, t):
        s = i / self.options['i_ref_a']
        beta = N[:, [0]] * np.exp(np.clip(N[:, [1]] * s, -50.0, 50.0))
        z = np.tanh(beta * v + N[:, [2]] * np.sign(x))
        p = N.shape[0]
        phi = np.empty((p, x.size, 7))
        phi[:, :, 0] = v
        phi[:, :, 1] = s * v
        phi[:, :, 2] = x
        phi[:, :, 3] = z
        phi[:, :, 4] = s * (2.0 - s) * z
        phi[:, :, 5] = s * s * z
        phi[:, :, 6] = 1.0
        return phi

    def _separable_parts(self, x, v, i, t):
        s = i / self.options['i_ref_a']
        n = x.size
        return SeparableParts(fixed_index=np.array([0, 1, 2, 6]),
                              fixed=np.column_stack([v, s * v, x, np.ones(n)]),
                              factor_index=np.array([3, 4, 5]),
                              weights=np.column_stack([np.ones(n), s * (2.0 - s), s * s]))

    def _nonlinear_factor(self, N, x, v, i, t):
        s = i / self.options['i_ref_a']
        a = N[:, [1]] * s                   # in place from here: one (p, n) buffer
        np.clip(a, -50.0, 50.0, out=a)
        np.exp(a, out=a)
        a *= N[:, [0]]
        a *= v
        a += N[:, [2]] * np.sign(x)
        return np.tanh(a, out=a)

    def _jacobian(self, p, x, v, i, t):
        s = i / self.options['i_ref_a']
        sx = np.sign(x)
        ebs = np.exp(np.clip(p[7] * s, -50.0, 50.0))
        z = np.tanh(p[6] * ebs * v + p[8] * sx)
        w1, w2 = s * (2.0 - s), s * s
        alpha = p[3] + p[4] * w1 + p[5] * w2
        dz = alpha * (1.0 - z * z)
        inside = np.abs(p[7] * s) < 50.0
        dbeta1 = np.where(inside, dz * p[6] * ebs * s * v, 0.0)
        return np.column_stack([v, s * v, x, z, w1 * z, w2 * z, dz * ebs * v, dbeta1,
                                dz * sx, np.ones(x.size)])
