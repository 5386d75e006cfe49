"""
Current-dependent Kwok model with a first-order fluid lag ("kwok-current-lag").

``kwok-current`` (see :mod:`~mr_damper_model.models.kwok_current`) with the velocity inside the
tanh replaced by the lagged velocity ``u``::

    tau(i)*du/dt = v - u                                (u = v at the first sample)
    tau(i) = tau0 + tau1*s                              (s = max(i, 0)/i_ref_a)
    F = c(i)*v + k*x + alpha(i)*tanh(beta(i)*u + delta*sign(x)) + f0

with c(i), alpha(i), beta(i) of ``kwok-current``. Why: on the shared Quiroz tests the
force-velocity loop of the MR damper is wider, in velocity, the larger the piston acceleration
(2 mm at 5 Hz and 5 mm at 3 Hz: about +-0.015 m/s at 1 A; 25 mm at 0.25 Hz: a few mm/s),
which a lag of the yield force behind the velocity (fluid compressibility, the flow through
the valve building up) makes: the shift is ``tau*dv/dt``. The loops widen with the current
too (the lag grows as the field builds the fluid's structure): tau grows linearly with it.
Kwok's constant shift ``delta*sign(x)`` stays for the rate-independent part.
``tau0 = tau1 = 0`` gives ``kwok-current`` exactly.

The lag is a state carried from sample to sample: the model is stateful (needs ``t``) and a
record is filtered as one time series per segment (``starts``: records joined with
``DamperData.concatenate`` restart the lag at ``u = v`` at each record's first sample).
Discretisation: exact for a velocity held at its new value over each sample interval,
``u[n] = a*u[n-1] + (1 - a)*v[n]``, ``a = exp(-dt/tau)``; stretches of equal sample interval
(within 1 %) and current (within 1 % of i_ref_a, at the time constant of their mean current)
are filtered in one ``scipy.signal.lfilter`` call per parameter set: fast for test records at
a few current levels, slow (a call per sample) for a current that changes at every sample.
A long record is evaluated chunk by chunk with the lag carried from one chunk to the next
(``_eval_chunks``, the record's stretches: the same result up to rounding), so ``identify``
fits it in bounded memory (``bench/bench_csv_memory.py --multi``).

``identify`` polishes it by default (``polish_by_default``): the swarm works on every k-th
sample (where the lag is washed out: it settles the other parameters) and the bounded
least-squares polish finds tau0 and tau1 on all samples; see docs/cross-validation.md.

The linear parameters (c0, c1, k, alpha0..2, f0) and the separable structure are those of
``kwok-current``; the swarm searches beta0, beta1, delta, tau0 and tau1.
"""
import numpy as np
from scipy.signal import lfilter

from mr_damper_model.models.kwok_current import KwokCurrent, kwok_current_coefficients
from mr_damper_model.models import HysteresisModel, ModelError

#: Sample intervals within this relative spread are filtered as one uniform stretch.
DT_SPREAD = 0.01
#: Normalised currents within this spread share one lag time constant (their mean's).
S_SPREAD = 0.01


def _stretches(t, s):
    """
    Split a record into stretches of (nearly) equal sample interval and current.

    Parameters
    ----------
    t : numpy.ndarray with shape (n,)
        Strictly increasing time [s].
    s : numpy.ndarray with shape (n,)
        Normalised current [-].

    Returns
    -------
    list of (int, int, float, float)
        ``(start, stop, dt, s_mean)``: samples ``start:stop`` with interval ``dt`` [s] before
        each (the first sample of the record gets the interval of the second) and mean
        normalised current ``s_mean``.

    """
    n = t.size
    if n < 2:
        return [(0, n, 1.0, float(np.mean(s)) if n else 0.0)]
    dt = np.diff(t)
    dt = np.concatenate([dt[:1], dt])
    out = []
    start = 0
    while start < n:
        off = np.flatnonzero((np.abs(dt[start:] - dt[start]) > DT_SPREAD * dt[start])
                             | (np.abs(s[start:] - s[start]) > S_SPREAD))
        stop = start + (int(off[0]) if off.size else n - start)
        out.append((start, stop, float(np.mean(dt[start:stop])),
                    float(np.mean(s[start:stop]))))
        start = stop
    return out


def first_order_lag(v, t, tau0, tau1=0.0, s=None, *, stretches=None, u0=None):
    """
    Lag a signal through ``tau*du/dt = v - u`` with ``tau = tau0 + tau1*s``.

    Parameters
    ----------
    v : numpy.ndarray with shape (n,)
        Input signal (here the piston velocity [m/s]).
    t : numpy.ndarray with shape (n,)
        Strictly increasing time [s].
    tau0, tau1 : array_like with shape (p,) or scalar
        Time constant at s = 0 and its slope [s]; ``tau0 + tau1*s`` must be >= 0 (0: no lag,
        ``u = v``).
    s : numpy.ndarray with shape (n,), optional
        Normalised coil current [-] (zero if omitted). Stretches whose current stays within
        :data:`S_SPREAD` use the time constant of their mean current.
    stretches : list of (int, int, float, float), optional
        The stretches of these samples (default: ``_stretches(t, s)``); a chunk of a longer
        record passes its share of the record's stretches (the record's intervals and means).
    u0 : numpy.ndarray with shape (p,), optional
        Lagged signal at the sample before the first (the end of the previous chunk); default
        none: the signal starts at ``u[0] = v[0]``.

    Returns
    -------
    numpy.ndarray with shape (p, n)
        Lagged signals, starting at ``u[0] = v[0]``.

    """
    tau0, tau1 = np.broadcast_arrays(np.atleast_1d(np.asarray(tau0, dtype=float)),
                                     np.atleast_1d(np.asarray(tau1, dtype=float)))
    if not (np.all(np.isfinite(tau0)) and np.all(np.isfinite(tau1))):
        raise ModelError('`tau0` and `tau1` must be finite')
    s = np.zeros(v.size) if s is None else s
    out = np.empty((tau0.size, v.size))
    if v.size == 0:
        return out
    stretches = _stretches(t, s) if stretches is None else stretches
    for j in range(tau0.size):
        prev = v[0] if u0 is None else u0[j]
        for start, stop, dt, s_mean in stretches:
            tau = tau0[j] + tau1[j] * s_mean
            if tau < 0:
                raise ModelError(f'lag time constant `tau0 + tau1*s` must be >= 0, got {tau}')
            if tau == 0.0:
                out[j, start:stop] = v[start:stop]
            else:
                a = float(np.exp(-dt / tau))
                out[j, start:stop], _ = lfilter([1.0 - a], [1.0, -a], v[start:stop],
                                                zi=[a * prev])
            prev = out[j, stop - 1]
    return out


class _Carry:
    """
    State carried from one chunk of a segment to the next (chunked evaluation of a long record).

    ``stretches`` and ``t_ref`` are those of the whole segment, so every chunk is filtered with
    the record's coefficients; ``u`` is the lagged velocity at the end of the previous chunk
    (per parameter row), ``g`` the log-domain peak hold of ``kwok-current-amp``.
    """

    def __init__(self, stretches, t_ref):
        self.stretches, self.t_ref = stretches, t_ref
        self.offset = 0
        self.u = self.g = None

    def local(self, n):
        """Return the stretches of the chunk of ``n`` samples at ``offset``, chunk-relative."""
        a, b = self.offset, self.offset + n
        return [(max(s0, a) - a, min(s1, b) - a, dt, sm)
                for s0, s1, dt, sm in self.stretches if s0 < b and s1 > a]


class KwokCurrentLag(KwokCurrent):
    """
    Current-dependent Kwok model with a first-order lag of the velocity in the tanh.

    Parameters and units: those of ``KwokCurrent`` (c0, c1 [N s/m]; k [N/m]; alpha0..2 [N];
    beta0 [s/m]; beta1 [-]; delta [-]; f0 [N]), tau0 [s] (lag time constant at zero current)
    and tau1 [s] (its growth over 0..i_ref_a). Option ``i_ref_a`` as for ``KwokCurrent``
    (default 2.0 A).

    Bounds of tau0 and tau1: [0, 0.05] s (physical), [0, 0.1] s (unbounded; negative values
    are rejected); the others as ``KwokCurrent``.
    """

    name = 'kwok-current-lag'
    param_names = KwokCurrent.param_names + ('tau0', 'tau1')
    param_units = dict(KwokCurrent.param_units, tau0='s', tau1='s')
    linear_names = KwokCurrent.linear_names
    stateful = True
    polish_by_default = True
    _bounds = dict(KwokCurrent._bounds, tau0=(0.0, 0.05), tau1=(0.0, 0.05))
    _bounds_unbounded = dict(KwokCurrent._bounds_unbounded, tau0=(0.0, 0.1),
                             tau1=(0.0, 0.1))

    #: no analytic Jacobian: forward differences (the tau column is a filter of its own)
    _jacobian = HysteresisModel._jacobian

    def _lagged(self, tau0, tau1, v, i, t, carry=None):
        if np.any(tau0 < 0) or np.any(tau1 < 0):
            raise ModelError('lag time constants `tau0`, `tau1` must be >= 0')
        s = np.maximum(i, 0.0) / self.options['i_ref_a']
        if carry is None:
            return first_order_lag(v, t, tau0, tau1, s)
        u = first_order_lag(v, t, tau0, tau1, s, stretches=carry.local(v.size), u0=carry.u)
        carry.u = u[:, -1].copy()
        return u

    def _scale_slope(self, a, extra, x, v, t, carry=None):
        """Scale the tanh argument's slope term ``a`` in place (subclasses; here none)."""

    def _force(self, P, x, v, i, t, carry=None):
        s = i / self.options['i_ref_a']
        c, alpha, beta = kwok_current_coefficients(P, s)
        u = self._lagged(P[:, 10], P[:, 11], v, i, t, carry)
        u *= beta
        self._scale_slope(u, P[:, 12:], x, v, t, carry)
        z = np.tanh(u + P[:, [8]] * np.sign(x))
        return c * v + P[:, [2]] * x + alpha * z + P[:, [9]]

    def _nonlinear_factor(self, N, x, v, i, t, carry=None):
        s = i / self.options['i_ref_a']
        beta = N[:, [0]] * np.exp(np.clip(N[:, [1]] * s, -50.0, 50.0))
        a = self._lagged(N[:, 3], N[:, 4], v, i, t, carry)
        a *= beta
        self._scale_slope(a, N[:, 5:], x, v, t, carry)
        a += N[:, [2]] * np.sign(x)
        return np.tanh(a, out=a)

    def _eval_chunks(self, method, lead, sig, chunk):
        """
        Evaluate ``method(*lead, x, v, i, t, carry)`` chunk by chunk; yield ``(a, b, out)``.

        ``out`` is the result on samples ``a:b`` (at most ``chunk`` of them, within one
        segment). The lag (and the amplitude's peak hold) runs on from the end of the previous
        chunk of the segment with the segment's stretches, so the joined results equal the
        evaluation on the whole record up to rounding, while only one chunk is in memory
        (bounded memory of a fit of a long record: ``identify``).
        """
        x, v, i, t, starts = sig
        edges = np.append(starts, x.size)
        for s0, s1 in zip(edges[:-1], edges[1:]):
            s = np.maximum(i[s0:s1], 0.0) / self.options['i_ref_a']
            carry = _Carry(_stretches(t[s0:s1], s), float(t[s0]))
            del s
            for a in range(s0, s1, chunk):
                b = min(a + chunk, s1)
                carry.offset = a - s0
                yield a, b, method(*lead, x[a:b], v[a:b], i[a:b], t[a:b], carry)

    def _regressors(self, N, x, v, i, t, carry=None):
        parts = self._separable_parts(x, v, i, t)
        h = self._nonlinear_factor(N, x, v, i, t, carry)
        phi = np.empty((N.shape[0], x.size, len(self.linear_names)))
        phi[:, :, parts.fixed_index] = parts.fixed
        phi[:, :, parts.factor_index] = h[:, :, None] * parts.weights
        return phi
