"""
Current-dependent Kwok model with a lag and a velocity-amplitude-dependent knee.

``kwok-current-amp``: ``kwok-current-lag`` (see :mod:`~mr_damper_model.models.kwok_current_lag`)
with the tanh slope divided by ``1 + kappa*V``::

    tau(i)*du/dt = v - u                                (u = v at the first sample)
    V[n] = max over m <= n of |v[m]|*exp(-(t[n] - t[m])/tau_a)
    F = c(i)*v + k*x + alpha(i)*tanh(beta(i)*u/(1 + kappa*V) + delta*sign(x)) + f0

V is a causal estimate of the piston-velocity amplitude [m/s]: a peak hold of |v| that decays
with the time constant ``tau_a`` (model option, default 5 s: longer than the half period of
the slowest shared test, 0.1 Hz, so it holds the amplitude over a cycle; short enough to follow
a road signal's changing amplitude within seconds). It needs no knowledge of a test frequency
and starts from ``V = |v|`` at each record's first sample.

Why: the knee of the force-velocity curve is wider, in velocity, the faster the piston moves.
Per-file Kwok fits of the shared Quiroz tests give beta about 240 s/m at 25 mm / 0.25 Hz
(peak velocity 0.04 m/s) and about 150 s/m at 25 mm / 0.5 Hz (0.08 m/s) at 0 and 0.25 A; the
authors' filtered series (force and displacement averaged over a tenth of the period) carry a
knee smeared over a velocity range proportional to their amplitude (beta*V about 3 to 4.5).
A single beta(i) cannot follow either; ``beta(i)/(1 + kappa*V)`` can, and on the
cross-validation of docs/cross-validation.md it predicts held-out series markedly better than
``kwok-current-lag`` (median ratio 1.45 -> 1.26, worst 4.0 -> 2.6; most of it on the filtered
series). ``kappa = 0`` gives ``kwok-current-lag`` exactly.

Stateful like the lag model (needs ``t``; records joined with ``DamperData.concatenate``
restart the lag and the peak hold at each record's first sample). The linear parameters and
the separable structure are those of ``kwok-current``; the swarm searches beta0, beta1,
delta, tau0, tau1 and kappa; ``identify`` polishes it by default as ``kwok-current-lag``.
"""
import numpy as np

from mr_damper_model.models.kwok_current_lag import KwokCurrentLag
from mr_damper_model.models import ModelError


def velocity_amplitude(v, t, tau_a, carry=None):
    """
    Causal amplitude of a velocity signal: a peak hold of ``|v|`` decaying with ``tau_a``.

    ``V[n] = max(|v[m]| * exp(-(t[n] - t[m]) / tau_a) for m <= n)``, evaluated without a loop
    (a running maximum in the log domain); exact for any sample spacing.

    Parameters
    ----------
    v : numpy.ndarray with shape (n,)
        Velocity [m/s].
    t : numpy.ndarray with shape (n,)
        Strictly increasing time [s].
    tau_a : float
        Decay time constant of the peak hold [s], > 0.
    carry : optional
        Chunked evaluation (``KwokCurrentLag._eval_chunks``): the hold runs on from the
        previous chunk's (``carry.g``, updated) on the segment's time origin ``carry.t_ref``.

    Returns
    -------
    numpy.ndarray with shape (n,)
        Amplitude estimate [m/s] (``|v[0]|`` at the first sample).

    """
    if not (np.isfinite(tau_a) and tau_a > 0):
        raise ModelError(f'`tau_a` must be a positive time constant [s], got {tau_a}')
    if v.size == 0:
        return np.zeros(0)
    r = (t - (t[0] if carry is None else carry.t_ref)) / tau_a
    g = np.log(np.maximum(np.abs(v), 1e-300)) + r
    if carry is not None and carry.g is not None:
        g[0] = max(g[0], carry.g)
    np.maximum.accumulate(g, out=g)
    if carry is not None:
        carry.g = float(g[-1])
    g -= r
    return np.exp(g, out=g)


class KwokCurrentAmp(KwokCurrentLag):
    """
    Current-dependent Kwok model with a lag and a knee widening with the velocity amplitude.

    Parameters and units: those of ``KwokCurrentLag`` and kappa [s/m] (the knee widens by
    ``1 + kappa*V`` at velocity amplitude V). Options ``i_ref_a`` as for ``KwokCurrent``
    (default 2.0 A) and ``tau_a``, the decay time constant of the amplitude estimate
    (:func:`velocity_amplitude`, default 5.0 s).

    Bounds of kappa: [0, 1000] s/m (physical: up to a knee 90 times wider at 0.09 m/s);
    [0, 1e4] s/m unbounded (negative values are rejected: 1 + kappa*V could reach zero).
    """

    name = 'kwok-current-amp'
    param_names = KwokCurrentLag.param_names + ('kappa',)
    param_units = dict(KwokCurrentLag.param_units, kappa='s/m')
    linear_names = KwokCurrentLag.linear_names
    _bounds = dict(KwokCurrentLag._bounds, kappa=(0.0, 1000.0))
    _bounds_unbounded = dict(KwokCurrentLag._bounds_unbounded, kappa=(0.0, 1e4))

    def __init__(self, i_ref_a=2.0, tau_a=5.0):
        super().__init__(i_ref_a=i_ref_a)
        tau_a = float(tau_a)
        if not (np.isfinite(tau_a) and tau_a > 0):
            raise ModelError(f'`tau_a` must be a positive time constant [s], got {tau_a}')
        self.options['tau_a'] = tau_a

    def _scale_slope(self, a, extra, x, v, t, carry=None):
        """Divide the slope term ``a`` (p, n) by ``1 + kappa*V`` (kappa: ``extra[:, 0]``)."""
        kappa = extra[:, [0]]
        if np.any(kappa < 0):
            raise ModelError('knee widening `kappa` must be >= 0')
        a /= 1.0 + kappa * velocity_amplitude(v, t, self.options['tau_a'], carry)
