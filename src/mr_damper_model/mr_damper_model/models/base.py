"""
Hysteresis model base class and registry.

Every model maps a batch of parameter sets (one row per PSO particle) and a measured motion
(displacement ``x`` [m], velocity ``v`` [m/s], coil current ``i`` [A], time ``t`` [s]) to the
damper force [N]. A single parameter set of shape ``(n_params,)`` gives a force of shape
``(n,)``; a batch of shape ``(p, n_params)`` gives ``(p, n)``. No model loops over particles in
Python; the stateful ones (Bouc-Wen, Spencer) loop over time only, in compiled code
(:mod:`mr_damper_model.models.compiled`).

Segments. A record may join several independent tests (``DamperData.starts``): every public
method takes ``starts``, the sorted sample indices where a test begins (0 is always one). A
stateful model restarts from rest at each start (its internal state at its initial value, as at
sample 0) and needs ``t`` strictly increasing only within a segment; it is evaluated segment by
segment, so the force of a joined record equals, sample for sample, the forces of its parts
computed alone. Memoryless models ignore ``starts``.

Slightly over the project's ~600 lines: the base class holds the one implementation of what
every model shares (signal checks, segment starts, batched evaluation, finite differences),
which the model modules must not copy.
"""
from dataclasses import dataclass
import importlib
from typing import NamedTuple

import numpy as np

MODEL_NAMES = ('kwok', 'kwok-current', 'bingham', 'bouc-wen', 'spencer', 'kwok-current-lag',
               'kwok-current-amp')

_REGISTRY = {
    'kwok': ('mr_damper_model.models.kwok', 'Kwok'),
    'kwok-current': ('mr_damper_model.models.kwok_current', 'KwokCurrent'),
    'bingham': ('mr_damper_model.models.bingham', 'Bingham'),
    'bouc-wen': ('mr_damper_model.models.bouc_wen', 'BoucWen'),
    'spencer': ('mr_damper_model.models.spencer', 'Spencer'),
    'kwok-current-lag': ('mr_damper_model.models.kwok_current_lag', 'KwokCurrentLag'),
    'kwok-current-amp': ('mr_damper_model.models.kwok_current_amp', 'KwokCurrentAmp'),
}


class ModelError(ValueError):
    """Invalid model name, parameters or signals."""


@dataclass(frozen=True)
class SeparableParts:
    """
    Structure of a model's regressors for the separable identification.

    ``regressors(N)[:, :, fixed_index] == fixed`` for every N (columns that do not depend on
    the nonlinear parameters) and ``regressors(N)[:, :, factor_index] ==
    h[:, :, None] * weights[None]`` with ``h = nonlinear_factor(N)`` of shape (p, n).

    Attributes
    ----------
    fixed_index : numpy.ndarray of int with shape (m_fixed,)
        Positions (in ``linear_names``) of the fixed columns.
    fixed : numpy.ndarray with shape (n, m_fixed)
        The fixed columns.
    factor_index : numpy.ndarray of int with shape (m_factor,)
        Positions of the columns that depend on the nonlinear parameters.
    weights : numpy.ndarray with shape (n, m_factor)
        Per-sample weights of ``h`` in those columns (e.g. the current polynomials).

    """

    fixed_index: np.ndarray
    fixed: np.ndarray
    factor_index: np.ndarray
    weights: np.ndarray


class Signals(NamedTuple):
    """Validated signals of one evaluation: arrays of shape (n,) and the segment starts."""

    x: np.ndarray
    v: np.ndarray
    i: object
    t: object
    starts: np.ndarray


def cvkz_regressors(p, x, v, z):
    """
    Regressors of ``F = c*v + k*x + alpha*z + f0`` (Kwok, Bouc-Wen).

    Parameters
    ----------
    p : int
        Number of nonlinear parameter sets.
    x, v : numpy.ndarray with shape (n,)
        Displacement [m] and velocity [m/s].
    z : numpy.ndarray with shape (p, n)
        Hysteretic variable at each parameter set [-].

    Returns
    -------
    numpy.ndarray with shape (p, n, 4)
        Columns for ``c, k, alpha, f0``.

    """
    phi = np.empty((p, x.size, 4))
    phi[:, :, 0] = v
    phi[:, :, 1] = x
    phi[:, :, 2] = z
    phi[:, :, 3] = 1.0
    return phi


def cvkz_separable_parts(x, v):
    """
    Separable structure of ``F = c*v + k*x + alpha*z + f0``: z is the nonlinear factor.

    Parameters
    ----------
    x, v : numpy.ndarray with shape (n,)
        Displacement [m] and velocity [m/s].

    Returns
    -------
    SeparableParts
        Fixed columns ``c, k, f0``; ``alpha`` multiplies ``nonlinear_factor`` with unit weight.

    """
    n = x.size
    return SeparableParts(fixed_index=np.array([0, 1, 3]),
                          fixed=np.column_stack([v, x, np.ones(n)]),
                          factor_index=np.array([2]), weights=np.ones((n, 1)))


def get_model(name, **options):
    """
    Return a model instance by name.

    Parameters
    ----------
    name : str
        One of ``MODEL_NAMES``.
    **options
        Model constants, e.g. ``i_ref_a=2.0`` for ``'kwok-current'``.

    Returns
    -------
    HysteresisModel

    Raises
    ------
    ModelError
        Unknown name.

    """
    if name not in _REGISTRY:
        raise ModelError(f'unknown model {name!r}; expected one of {", ".join(MODEL_NAMES)}')
    module, cls = _REGISTRY[name]
    return getattr(importlib.import_module(module), cls)(**options)


def _signal(a, name, n=None):
    """
    Coerce a signal to a finite 1-D float array.

    Parameters
    ----------
    a : array_like
        Signal (scalar or 1-D).
    name : str
        Argument name used in error messages.
    n : int or None
        Required length (scalars are broadcast to it).

    Returns
    -------
    numpy.ndarray with shape (n,)

    """
    arr = np.atleast_1d(np.asarray(a, dtype=float))
    if arr.ndim != 1:
        raise ModelError(f'`{name}` must be 1-D, got shape {arr.shape}')
    if n is not None and arr.size == 1 and n != 1:
        arr = np.full(n, arr[0])
    if n is not None and arr.size != n:
        raise ModelError(f'`{name}` has {arr.size} samples, expected {n}')
    if not np.all(np.isfinite(arr)):
        raise ModelError(f'`{name}` contains NaN or inf')
    return arr


def segment_starts(starts, n):
    """
    Coerce segment starts to a sorted int array that begins with 0.

    Parameters
    ----------
    starts : array_like of int or None
        Sample indices where an independent segment begins (None: one segment).
    n : int
        Number of samples.

    Returns
    -------
    numpy.ndarray of int with shape (n_segments,)

    """
    if starts is None:
        return np.zeros(1, dtype=np.int64)
    arr = np.atleast_1d(np.asarray(starts))
    if arr.ndim != 1 or (arr.size and arr.dtype.kind not in 'iuf') \
            or (arr.dtype.kind == 'f' and not np.all(arr == np.round(arr))):
        raise ModelError(f'`starts` must be a 1-D array of sample indices, got {starts!r}')
    arr = arr.astype(np.int64)
    if arr.size == 0 or arr[0] != 0:
        arr = np.concatenate([[0], arr])
    if np.any(np.diff(arr) <= 0) or arr[-1] >= max(n, 1):
        raise ModelError(f'`starts` must be strictly increasing sample indices in [0, {n}), '
                         f'got {np.asarray(starts).tolist()}')
    return arr


class HysteresisModel:
    """
    Base class of the damper force models.

    Attributes
    ----------
    name : str
        Registry name.
    param_names : tuple of str
        Parameter order of a parameter vector.
    param_units : dict
        Unit of each parameter.
    linear_names : tuple of str
        Parameters entering the force linearly (``regressors`` columns, in this order).
    nonlinear_names : tuple of str
        The other parameters, in ``param_names`` order.
    stateful : bool
        True if the model integrates an internal state (needs ``t``).
    needs_current : bool
        True if ``force`` needs the coil current ``i``.
    polish_by_default : bool or None
        Whether ``identify``'s separable method polishes by default (the swarm on every k-th
        sample, then bounded least squares on all samples). None: for the algebraic models
        only; True for a stateful model whose state washes out on every k-th sample
        (``kwok-current-lag``) or whose swarm works on a stretch of the record (Spencer's
        ``identification`` policy).
    identification : dict or None
        A model's own policy for ``identify``'s separable method (swarm stretch, sub-steps,
        budgets; see ``Spencer.identification``), None for the generic one.
    options : dict
        Model constants.

    """

    name = ''
    param_names = ()
    param_units = {}
    linear_names = ()
    stateful = False
    needs_current = False
    polish_by_default = None
    identification = None

    def __init__(self, **options):
        if options:
            raise ModelError(f'model {self.name!r} takes no options, got {sorted(options)}')
        self.options = {}

    # -- helpers -------------------------------------------------------------------------
    @property
    def nonlinear_names(self):
        """Parameters that enter the force nonlinearly, in ``param_names`` order."""
        return tuple(p for p in self.param_names if p not in self.linear_names)

    @property
    def n_params(self):
        """Number of parameters."""
        return len(self.param_names)

    def _params(self, params):
        """Coerce ``params`` to (p, n_params); return it and whether the input was 1-D."""
        arr = np.asarray(params, dtype=float)
        single = arr.ndim == 1
        arr = np.atleast_2d(arr)
        if arr.ndim != 2 or arr.shape[1] != self.n_params:
            raise ModelError(
                f'`params` must have shape (n_params,) or (p, n_params) with n_params='
                f'{self.n_params} ({", ".join(self.param_names)}), got {np.shape(params)}')
        if not np.all(np.isfinite(arr)):
            raise ModelError('`params` contains NaN or inf')
        return arr, single

    def _nonlinear(self, nonlinear):
        arr = np.asarray(nonlinear, dtype=float)
        single = arr.ndim == 1
        arr = np.atleast_2d(arr)
        k = len(self.nonlinear_names)
        if k == 0 and arr.size == 0:
            arr = np.zeros((max(1, arr.shape[0]) if arr.ndim == 2 else 1, 0))
        if arr.ndim != 2 or arr.shape[1] != k:
            raise ModelError(f'`nonlinear` must have shape (p, {k}) '
                             f'({", ".join(self.nonlinear_names)}), got {np.shape(nonlinear)}')
        if not np.all(np.isfinite(arr)):
            raise ModelError('`nonlinear` contains NaN or inf')
        return arr, single

    def _signals(self, x, v, i=None, t=None, starts=None):
        """Validate the signals once; return :class:`Signals`."""
        x = _signal(x, 'x')
        n = x.size
        v = _signal(v, 'v', n)
        if self.needs_current:
            if i is None:
                raise ModelError(f'model {self.name!r} needs the coil current `i`')
            i = _signal(i, 'i', n)
        elif i is not None:
            i = _signal(i, 'i', n)
        starts = segment_starts(starts, n)
        if self.stateful:
            if t is None:
                raise ModelError(f'model {self.name!r} is stateful and needs the time `t`')
            t = _signal(t, 't', n)
            step_ok = np.diff(t) > 0
            step_ok[starts[1:] - 1] = True      # t may jump back where a segment starts
            if not np.all(step_ok):
                raise ModelError('`t` must be strictly increasing (within each segment)')
        elif t is not None:
            t = _signal(t, 't', n)
        return Signals(x, v, i, t, starts)

    def _per_segment(self, method, lead, sig, axis):
        """
        Evaluate ``method(*lead, x, v, i, t)`` per segment and join along ``axis``.

        Memoryless models and single-segment records are evaluated in one call.
        """
        x, v, i, t, starts = sig
        if not self.stateful or starts.size == 1:
            return method(*lead, x, v, i, t)
        edges = np.append(starts, x.size)
        parts = [method(*lead, x[a:b], v[a:b], None if i is None else i[a:b],
                        None if t is None else t[a:b]) for a, b in zip(edges[:-1], edges[1:])]
        return np.concatenate(parts, axis=axis)

    def _eval_force(self, P, sig):
        """Force (p, n) of parameter rows ``P`` on validated signals ``sig``."""
        return self._per_segment(self._force, (P,), sig, 1)

    def _eval_regressors(self, N, sig):
        """Regressors (p, n, n_linear) on validated signals."""
        return self._per_segment(self._regressors, (N,), sig, 1)

    def _eval_nonlinear_factor(self, N, sig):
        """Nonlinear factor (p, n) on validated signals."""
        return self._per_segment(self._nonlinear_factor, (N,), sig, 1)

    def _eval_jacobian(self, p, sig):
        """Jacobian (n, n_params) on validated signals."""
        return self._per_segment(self._jacobian, (p,), sig, 0)

    def _eval_separable_parts(self, sig):
        """:class:`SeparableParts` (or None) on validated signals."""
        x, v, i, t, starts = sig
        if not self.stateful or starts.size == 1:
            return self._separable_parts(x, v, i, t)
        edges = np.append(starts, x.size)
        parts = [self._separable_parts(x[a:b], v[a:b], None if i is None else i[a:b],
                                       None if t is None else t[a:b])
                 for a, b in zip(edges[:-1], edges[1:])]
        if parts[0] is None:
            return None
        return SeparableParts(fixed_index=parts[0].fixed_index,
                              fixed=np.concatenate([q.fixed for q in parts]),
                              factor_index=parts[0].factor_index,
                              weights=np.concatenate([q.weights for q in parts]))

    # -- public API ----------------------------------------------------------------------
    def default_bounds(self, *, unbounded=False):
        """
        Return box bounds ``(lower, upper)``, each of shape (n_params,).

        Parameters
        ----------
        unbounded : bool
            False: physically meaningful ranges; True: the wide thesis-comparison ranges.

        Returns
        -------
        tuple of numpy.ndarray

        """
        table = self._bounds_unbounded if unbounded else self._bounds
        lo = np.array([table[p][0] for p in self.param_names], dtype=float)
        hi = np.array([table[p][1] for p in self.param_names], dtype=float)
        return lo, hi

    def force(self, params, x, v, i=None, t=None, starts=None):
        """
        Damper force [N].

        Parameters
        ----------
        params : array_like with shape (n_params,) or (p, n_params)
            Parameter set(s), order ``param_names``.
        x : array_like with shape (n,)
            Piston displacement [m].
        v : array_like with shape (n,)
            Piston velocity [m/s].
        i : array_like with shape (n,), optional
            Coil current [A] (current-dependent models).
        t : array_like with shape (n,), optional
            Time [s], strictly increasing within each segment (stateful models).
        starts : array_like of int, optional
            Sample indices where an independent segment (test) begins, sorted; 0 is always one
            (``DamperData.starts``). Stateful models restart from rest at each; memoryless
            models ignore them. Default: one segment.

        Returns
        -------
        numpy.ndarray with shape (n,) or (p, n)

        """
        P, single = self._params(params)
        sig = self._signals(x, v, i, t, starts)
        f = self._eval_force(P, sig)
        return f[0] if single else f

    def regressors(self, nonlinear, x, v, i=None, t=None, starts=None):
        """
        Linear regressors at given nonlinear parameters.

        Parameters
        ----------
        nonlinear : array_like with shape (p, n_nonlinear) or (n_nonlinear,)
            Values of ``nonlinear_names``.
        x, v, i, t, starts : array_like
            As in ``force``.

        Returns
        -------
        numpy.ndarray with shape (p, n, n_linear) (or (n, n_linear) for 1-D input)
            ``force(full) == Phi @ theta_linear`` with columns in ``linear_names`` order.

        """
        if not self.linear_names:
            raise ModelError(f'model {self.name!r} has no linear parameters')
        N, single = self._nonlinear(nonlinear)
        phi = self._eval_regressors(N, self._signals(x, v, i, t, starts))
        return phi[0] if single else phi

    def separable_parts(self, x, v, i=None, t=None, starts=None):
        """
        Split the regressors into fixed columns and columns ``h(nonlinear) * weights``.

        Lets the separable identification precompute, once per record, everything that does not
        depend on the nonlinear parameters; per particle only :meth:`nonlinear_factor` is
        evaluated.

        Parameters
        ----------
        x, v, i, t, starts : array_like
            As in ``force``.

        Returns
        -------
        SeparableParts or None
            None if the model has no such structure (or no linear parameters).

        """
        if not self.linear_names:
            return None
        return self._eval_separable_parts(self._signals(x, v, i, t, starts))

    def nonlinear_factor(self, nonlinear, x, v, i=None, t=None, starts=None):
        """
        Evaluate the regressor factor ``h`` that depends on the nonlinear parameters.

        Parameters
        ----------
        nonlinear : array_like with shape (p, n_nonlinear) or (n_nonlinear,)
            Values of ``nonlinear_names``.
        x, v, i, t, starts : array_like
            As in ``force``.

        Returns
        -------
        numpy.ndarray with shape (p, n) (or (n,) for 1-D input)
            Kwok models: ``tanh(beta*v + delta*sign(x))``; Bouc-Wen: ``z``.

        Raises
        ------
        ModelError
            If the model has no :meth:`separable_parts` structure.

        """
        N, single = self._nonlinear(nonlinear)
        sig = self._signals(x, v, i, t, starts)
        try:
            h = self._eval_nonlinear_factor(N, sig)
        except NotImplementedError:
            raise ModelError(f'model {self.name!r} has no separable structure') from None
        return h[0] if single else h

    def jacobian(self, params, x, v, i=None, t=None, starts=None):
        """
        Differentiate the force with respect to the parameters at one parameter set.

        Analytic for the algebraic models (Kwok, kwok-current, Bingham); forward differences
        otherwise.

        Parameters
        ----------
        params : array_like with shape (n_params,)
            Parameter values in ``param_names`` order.
        x, v, i, t, starts : array_like
            As in ``force``.

        Returns
        -------
        numpy.ndarray with shape (n, n_params)
            dF/dparam [N per parameter unit], columns in ``param_names`` order.

        """
        P, single = self._params(params)
        if not single:
            raise ModelError('`params` must be a single parameter set for jacobian')
        return self._eval_jacobian(P[0], self._signals(x, v, i, t, starts))

    def to_dict(self, params):
        """
        Map a parameter vector to ``{name: value}``.

        Parameters
        ----------
        params : array_like with shape (n_params,)
            Parameter values in ``param_names`` order.

        Returns
        -------
        dict of str to float

        """
        P, single = self._params(params)
        if not single and P.shape[0] != 1:
            raise ModelError('`params` must be a single parameter set for to_dict')
        return {p: float(val) for p, val in zip(self.param_names, P[0])}

    def from_dict(self, d):
        """
        Build a parameter vector from a mapping.

        Parameters
        ----------
        d : mapping of str to float
            Must contain every name of ``param_names`` (extra keys are ignored).

        Returns
        -------
        numpy.ndarray with shape (n_params,)

        Raises
        ------
        ModelError
            Missing or non-finite values (the names are given).

        """
        missing = [p for p in self.param_names if p not in d]
        if missing:
            raise ModelError(f'{self.name} parameters missing: {", ".join(missing)}')
        vals = []
        bad = []
        for p in self.param_names:
            try:
                val = float(d[p])
            except (TypeError, ValueError):
                val = float('nan')
            if not np.isfinite(val):
                bad.append(p)
            vals.append(val)
        if bad:
            raise ModelError(f'{self.name} parameters not finite: {", ".join(bad)}')
        return np.array(vals)

    # subclasses implement
    def _force(self, P, x, v, i, t):
        raise NotImplementedError

    def _regressors(self, N, x, v, i, t):
        raise NotImplementedError

    def _separable_parts(self, x, v, i, t):
        return None

    def _nonlinear_factor(self, N, x, v, i, t):
        raise NotImplementedError

    def _jacobian(self, p, x, v, i, t):
        """Forward differences (models with an analytic form override this)."""
        return self._fd_jacobian(p, x, v, i, t)

    def _fd_jacobian(self, p, x, v, i, t, cols=None):
        """
        Forward differences of the force in the parameters ``cols`` (default all), one batch.

        The base set and the perturbed ones are one ``_force`` call; the other columns are 0.
        """
        cols = np.arange(p.size) if cols is None else np.asarray(cols, dtype=int)
        P, h = self._fd_batch(p, cols)
        F = self._force(P, x, v, i, t)
        J = np.zeros((x.size, p.size))
        J[:, cols] = ((F[1:] - F[0]) / h[:, None]).T
        return J

    def _fd_batch(self, p, cols=None):
        """
        Parameter rows of a forward-difference Jacobian: ``(P, h)``.

        ``P[0]`` is ``p``, ``P[1 + k]`` is ``p`` with ``cols[k]`` (default all) raised by
        ``h[k]`` (1e-7 of the value, at least 1e-10 of the wide bounds' span).
        """
        cols = np.arange(p.size) if cols is None else np.asarray(cols, dtype=int)
        lo, hi = self.default_bounds(unbounded=True)
        span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
        h = 1e-7 * np.maximum(np.abs(p[cols]), 1e-3 * span[cols])
        P = np.repeat(p[None], cols.size + 1, axis=0)
        P[1 + np.arange(cols.size), cols] += h
        return P, h

    def _split(self, P):
        """Columns of P as (p, 1) arrays keyed by name."""
        return {name: P[:, [j]] for j, name in enumerate(self.param_names)}

    def __repr__(self):
        opts = ', '.join(f'{k}={v!r}' for k, v in self.options.items())
        return f'{type(self).__name__}({opts})'
