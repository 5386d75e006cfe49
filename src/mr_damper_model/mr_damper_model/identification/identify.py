"""
Identification of damper model parameters from measured motion, force and coil current.

Two methods, both minimising the RMSE of the force (thesis eq. 4.3):

``separable`` (default)
    The particle swarm (:func:`~mr_damper_model.identification.pso.pso`) searches only the
    parameters that enter
    the force nonlinearly (Kwok: beta, delta; kwok-current: beta0, beta1, delta; Bouc-Wen:
    delta, beta, gamma, n); for every particle the parameters that enter linearly are the exact
    box-bounded least-squares solution (:mod:`~mr_damper_model.identification.lsq`). The regressor
    columns that
    do not depend on the nonlinear parameters (v, x, 1, ...) are detected once per record and
    their Gram products precomputed; columns of the form h(nonlinear) * w (the current weights
    of kwok-current) are reduced to two matrix products per swarm. Models with no nonlinear
    parameter (Bingham) are solved directly. Models with an ``identification`` policy (Spencer)
    follow it: the swarm searches the parameters that act on the states, on a contiguous
    stretch from the start of the record and with coarser sub-steps, the ones that do not
    (``spring_names``) fitted per particle by the model's ``spring_fit``; then a bounded
    least-squares polish on all samples (see :func:`_policy_swarm`).
``full``
    The swarm searches all parameters, as in the thesis.

Records joined from several tests (``DamperData.starts``, e.g. from ``DamperData.concatenate``)
are fitted with one parameter set; the stateful models (Bouc-Wen, Spencer) restart from rest at
every segment start, in the swarm's cost, the linear solve and the reported metrics alike.

Rest periods at the start and end of a record (x, v and F near zero, as in the shared Quiroz
files) are fitted as they are: every model gives F = f0 + (for Kwok) alpha*tanh(delta*sign(x))
there, close to the small measured force, so they cost little and need no trimming.
"""
from dataclasses import dataclass, field
import math
import time

import numpy as np
from scipy.optimize import least_squares

from mr_damper_model.io.data import DamperData
from mr_damper_model.identification.lsq import box_qp, gram, sum_squares
from mr_damper_model.identification.metrics import fit_metrics
from mr_damper_model.models import HysteresisModel, get_model, Signals
from mr_damper_model.identification.pso import as_bounds, pso

__all__ = ['IdentificationResult', 'identify', 'identify_per_current', 'compare_models',
           'current_groups', 'current_group_levels', 'METHODS', 'DEFAULT_BUDGETS',
           'MIN_LEVEL_SAMPLES']

METHODS = ('separable', 'full')

#: Default swarm budgets per method: maxiter, stagnation tolerance and patience.
#: (separable without the polish, i.e. stateful models: maxiter 60, patience 20)
DEFAULT_BUDGETS = {
    'separable': {'maxiter': 15, 'tol': 1e-6, 'patience': 15},
    'full': {'maxiter': 400, 'tol': 1e-7, 'patience': 60},
}
#: Separable swarm works on at most this many samples (every k-th) before the polish on all.
SWARM_SAMPLES = 500
#: Samples per chunk of a memoryless model's polish and final linear solve on all samples: their
#: normal equations (``J^T J``, ``J^T r``, the Gram matrix) are summed chunk by chunk, so the
#: (n, n_params) Jacobian and the regressors are never formed whole (memory of a fit of a
#: 3-million-sample record: ``bench/bench_csv_memory.py``).
CHUNK_SAMPLES = 262144
#: A current level needs at least this many samples to be fitted on its own; fewer are the coil
#: transients between the levels of a step test (a few samples per step), left out of
#: per-current fits.
MIN_LEVEL_SAMPLES = 50
#: Units of the tanh slope parameters, searched on a log scale.
_LOG_UNITS = ('s/m',)


class _Space:
    """
    Search coordinates of the swarm: log scale for positive parameters spanning decades.

    Log scale where lo > 0 and hi >= 100 lo, or lo == 0 and the parameter is a tanh slope
    [s/m] or hi >= 1e4 (the wide physical boxes of c, k and alpha), with an offset of
    1e-4 hi so that 0 stays reachable.
    """

    def __init__(self, lo, hi, units):
        lo = np.asarray(lo, dtype=float)
        hi = np.asarray(hi, dtype=float)
        wide = np.isfinite(hi) & (
            ((lo > 0) & (hi >= 100.0 * np.where(lo > 0, lo, 1.0)))
            | ((lo == 0) & ((np.isin(units, _LOG_UNITS) & (hi > 0)) | (hi >= 1e4))))
        self.log = np.flatnonzero(wide)
        self.offset = np.where(lo > 0, 0.0, 1e-4 * np.where(np.isfinite(hi), hi, 1.0))
        self.lo, self.hi = lo, hi

    def to_u(self, p):
        u = np.array(p, dtype=float, copy=True)
        k = self.log
        u[..., k] = np.log(u[..., k] + self.offset[k])
        return u

    def to_p(self, u):
        p = np.array(u, dtype=float, copy=True)
        k = self.log
        p[..., k] = np.exp(p[..., k]) - self.offset[k]
        return np.clip(p, self.lo, self.hi)

    def bounds(self):
        return self.to_u(self.lo), self.to_u(self.hi)


@dataclass
class IdentificationResult:
    """
    Outcome of one identification.

    Attributes
    ----------
    model : str
        Model name (``get_model`` key).
    parameters : dict
        Parameter name -> value, SI units (see the model's ``param_units``).
    x : ndarray
        Parameter vector in the model's ``param_names`` order.
    metrics : dict
        :func:`~mr_damper_model.identification.metrics.fit_metrics` of the identified model on the
        data.
    seconds : float
        Identification wall time [s].
    seed : int or None
        Seed of the swarm (drawn and recorded when none was given).
    method : str
        ``'separable'``, ``'full'`` or ``'linear'`` (direct least squares).
    success, message, nit, nfev
        Termination of the swarm (see :func:`~mr_damper_model.identification.pso.pso`).
    current_min_a, current_max_a : float
        Coil-current range of the data [A].
    model_options : dict
        Model constants (e.g. ``{'i_ref_a': 2.0}``).
    source : str
        Data source (file name) if known.
    current_a : float
        Current level [A] of a per-current fit (NaN otherwise).

    """

    model: str
    parameters: dict
    x: np.ndarray
    metrics: dict
    seconds: float
    seed: object
    method: str
    success: bool
    message: str
    nit: int
    nfev: int
    current_min_a: float
    current_max_a: float
    model_options: dict = field(default_factory=dict)
    source: str = ''
    current_a: float = math.nan

    def to_json_dict(self):
        """Return a JSON-ready dictionary (the parameter-file fields plus run details)."""
        return {
            'model': self.model,
            'parameters': {k: float(v) for k, v in self.parameters.items()},
            'model_options': dict(self.model_options),
            'current_min_a': float(self.current_min_a),
            'current_max_a': float(self.current_max_a),
            'metrics': {k: float(v) for k, v in self.metrics.items()},
            'seconds': float(self.seconds),
            'seed': self.seed,
            'method': self.method,
            'success': bool(self.success),
            'message': self.message,
            'nit': int(self.nit),
            'nfev': int(self.nfev),
            'source': self.source,
        }


def _as_data(data):
    if not isinstance(data, DamperData):
        raise TypeError('`data` must be a DamperData (see data.read_csv).')
    if data.n < 2:
        raise ValueError('`data` has fewer than 2 samples.')
    return data


def _param_vector(model, x0, name='x0'):
    if x0 is None:
        return None
    if isinstance(x0, dict):
        return np.asarray(model.from_dict(x0), dtype=float)
    x0 = np.atleast_1d(np.asarray(x0, dtype=float))
    if x0.shape != (len(model.param_names),) or not np.all(np.isfinite(x0)):
        raise ValueError(f'`{name}` must be a finite vector of {len(model.param_names)} '
                         f'parameters {model.param_names} or a dict.')
    return x0


class SeparableCost:
    """
    RMSE of the force as a function of the nonlinear parameters only (batched).

    The linear parameters of each particle are the box-bounded least-squares solution. Build
    once per record; call with an array of nonlinear parameter sets.

    Everything that does not depend on the nonlinear parameters is computed here, once: the
    model's :meth:`~mr_damper_model.models.HysteresisModel.separable_parts` split the
    regressors into fixed columns S (v, x, 1, ...) and columns ``h(nonlinear) * W`` (W: per-sample
    weights, e.g. the current polynomials of kwok-current), so that with the products
    ``S^T S``, ``S^T y`` and the per-sample outer products of W with W, S and y, a batch of
    particles costs only ``h`` (p, n) and two matrix products, ``(h*h) @ WW`` and
    ``h @ [WS, Wy]``. Models without that structure fall back to probing ``regressors``
    at two points to find the fixed columns.

    Parameters
    ----------
    model : HysteresisModel
    data : DamperData
    lin_lo, lin_hi : ndarray with shape (n_linear,)
        Bounds of the linear parameters (may be infinite).
    probe : ndarray with shape (2, n_nonlinear)
        Two different nonlinear parameter sets used to detect the columns that do not depend
        on the nonlinear parameters (only for models without ``separable_parts``).

    """

    def __init__(self, model, data, lin_lo, lin_hi, probe):
        self.model = model
        # validated once; stateful models restart at every segment start of the record
        self.args = model._signals(data.x, data.v, data.i, data.t, data.starts)
        self.y = np.ascontiguousarray(data.f, dtype=float)
        self.n = self.y.size
        self.yy = float(self.y @ self.y)
        self.m = m = len(model.linear_names)
        parts = model._eval_separable_parts(self.args) if m else None
        self.general = None
        if parts is not None:
            static = np.asarray(parts.fixed_index, dtype=int)
            dyn = np.asarray(parts.factor_index, dtype=int)
            S = np.asarray(parts.fixed, dtype=float)
            W = np.asarray(parts.weights, dtype=float)
            self._h = self._model_factor
        else:
            static, dyn, S, W = self._probe(probe)
        self.static, self.dyn, self.S = static, dyn, S
        ms, kd = static.size, dyn.size
        self.ms, self.kd = ms, kd
        # internal order: fixed columns first, then the factor columns
        self.order = np.concatenate([static, dyn])
        self.lo_p = np.asarray(lin_lo, dtype=float)[self.order]
        self.hi_p = np.asarray(lin_hi, dtype=float)[self.order]
        self.lin_lo, self.lin_hi = lin_lo, lin_hi
        self.SS = S.T @ S
        self.Sy = S.T @ self.y
        if kd and self.general is None:
            WW = (W[:, :, None] * W[:, None, :]).reshape(self.n, kd * kd)
            WS = (W[:, :, None] * S[:, None, :]).reshape(self.n, kd * ms)
            self.WW = np.ascontiguousarray(WW)
            self.WSy = np.ascontiguousarray(np.hstack([WS, W * self.y[:, None]]))

    def _model_factor(self, nonlinear):
        return self.model._eval_nonlinear_factor(nonlinear, self.args)

    def _probe(self, probe):
        """Find the fixed / nonlinear-dependent columns by evaluating the regressors twice."""
        phi = np.asarray(self.model._eval_regressors(np.asarray(probe, dtype=float), self.args),
                         dtype=float)
        scale = np.max(np.abs(phi), axis=(0, 1)) + 1e-300
        same = np.all(np.abs(phi[0] - phi[1]) <= 1e-12 * scale, axis=0)
        static, dyn = np.flatnonzero(same), np.flatnonzero(~same)
        S = phi[0][:, static]
        W = np.zeros((self.n, dyn.size))
        if dyn.size:
            D = phi[:, :, dyn]
            h = D[:, :, 0]
            big = np.abs(h[0]) > 1e-9 * (np.max(np.abs(h[0])) + 1e-300)
            W[big] = D[0][big] / h[0][big, None]
            dscale = np.max(np.abs(D), axis=(0, 1)) + 1e-300
            if np.all(np.abs(D - h[:, :, None] * W[None]) <= 1e-9 * dscale):
                col = dyn[0]
                self._h = lambda nl: self.model._eval_regressors(
                    np.atleast_2d(np.asarray(nl, dtype=float)), self.args)[:, :, col]
            else:
                self.general = True
        return static, dyn, S, W

    def _gram_internal(self, nonlinear):
        """G, b in the internal column order (fixed first), and the finite mask."""
        nonlinear = np.atleast_2d(np.asarray(nonlinear, dtype=float))
        p = nonlinear.shape[0]
        m, ms, kd = self.m, self.ms, self.kd
        G = np.empty((p, m, m))
        b = np.empty((p, m))
        G[:, :ms, :ms] = self.SS
        b[:, :ms] = self.Sy
        if kd:
            if self.general:
                D = self.model._eval_regressors(nonlinear, self.args)[:, :, self.dyn]
                Dt = np.swapaxes(D, 1, 2)
                Gdd = Dt @ D
                Gds = Dt @ self.S
                bd = Dt @ self.y
            else:
                h = self._h(nonlinear)
                Gdd = ((h * h) @ self.WW).reshape(p, kd, kd)
                prod = h @ self.WSy
                Gds = prod[:, :kd * ms].reshape(p, kd, ms)
                bd = prod[:, kd * ms:]
            G[:, ms:, ms:] = Gdd
            G[:, ms:, :ms] = Gds
            G[:, :ms, ms:] = np.swapaxes(Gds, 1, 2)
            b[:, ms:] = bd
            finite = np.isfinite(G.reshape(p, -1).sum(axis=1) + b.sum(axis=1))
            if not finite.all():
                G[~finite] = np.eye(m)
                b[~finite] = 0.0
        else:
            finite = np.ones(p, dtype=bool)
        return G, b, finite

    def gram(self, nonlinear):
        """
        Gram matrices and right-hand sides for a batch of nonlinear parameter sets.

        Returns
        -------
        G : ndarray with shape (p, m, m)
        b : ndarray with shape (p, m)
            Columns in ``linear_names`` order.
        finite : ndarray of bool with shape (p,)

        """
        G, b, finite = self._gram_internal(nonlinear)
        inv = np.argsort(self.order)
        return G[:, inv[:, None], inv[None, :]], b[:, inv], finite

    def solve(self, nonlinear):
        """
        Linear parameters and RMSE [N] for a batch of nonlinear parameter sets.

        Returns
        -------
        theta : ndarray with shape (p, n_linear)
        rmse : ndarray with shape (p,)  (inf where the model is not finite)

        """
        G, b, finite = self._gram_internal(nonlinear)
        theta_p = box_qp(G, b, self.lo_p, self.hi_p)
        rss = sum_squares(G, b, self.yy, theta_p)
        rmse = np.sqrt(rss / self.n)
        theta = np.empty_like(theta_p)
        theta[:, self.order] = theta_p
        return theta, np.where(finite, rmse, np.inf)

    def __call__(self, nonlinear):
        """RMSE [N] for a batch of nonlinear parameter sets, shape (p,)."""
        with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
            return self.solve(nonlinear)[1]


def _projected_lm(resid, jac, x, r, lo, hi, *, max_iter=30, ftol=1e-10):
    """
    Box-bounded Levenberg-Marquardt of a residual and its Jacobian; returns (x, r, evaluations).

    :func:`_projected_lm_normal` on the normal equations of ``resid`` and ``jac`` (the residual
    of the accepted point is reused for the next Jacobian).
    """
    ls = _Residual(resid, jac)
    ls.rss(x, r)
    x, _, evals = _projected_lm_normal(ls.normal, ls.rss, x, float(r @ r), lo, hi,
                                       max_iter=max_iter, ftol=ftol)
    return x, ls.residual(x), evals


class _Residual:
    """
    Sum of squares and normal equations of one residual function and its Jacobian.

    The residual of the last point whose sum of squares was asked is kept: the next Jacobian at
    that point (the accepted step of :func:`_projected_lm_normal`) reuses it.
    """

    def __init__(self, resid, jac):
        self.resid, self.jac = resid, jac
        self._p = self._r = None

    def residual(self, p):
        """Return the residual at ``p`` (kept from the last :meth:`rss` if at the same point)."""
        if self._p is None or not np.array_equal(self._p, p):
            self._p, self._r = np.array(p, dtype=float), self.resid(p)
        return self._r

    def rss(self, p, r=None):
        """Return the sum of squares at ``p`` (inf if not finite); ``r``: known residual."""
        if r is not None:
            self._p, self._r = np.array(p, dtype=float), r
        r = self.residual(p)
        return float(r @ r) if np.all(np.isfinite(r)) else math.inf

    def normal(self, p):
        """Return ``(J^T J, J^T r)`` at ``p``, or None if the Jacobian is not finite."""
        J = self.jac(p)
        if not np.all(np.isfinite(J)):
            return None
        r = self.residual(p)
        return J.T @ J, J.T @ r


class _ChunkedResidual:
    """
    The force residual ``model(p) - f`` of a long record, evaluated chunk by chunk.

    Sums of squares and normal equations are accumulated over ``chunk`` (default
    :data:`CHUNK_SAMPLES`) samples at a time: memory is bounded by the chunk, whatever the
    record's length (the whole (n, d) Jacobian, about 8 d bytes per sample, is never formed).
    Same sums as on the whole record, up to the order of the floating-point additions.
    Memoryless models are cut into independent chunks and use their analytic Jacobian; a
    stateful model with a chunked evaluation (``_eval_chunks``: the lag models, whose state
    runs on from chunk to chunk) gets forward differences (``_fd_batch``: the base set and the
    perturbed ones in one evaluation per chunk). The residual of the last point whose sum of
    squares was asked is kept (one float per sample), so the next Jacobian at that point (the
    accepted step) does not evaluate the force again (memoryless models).
    """

    def __init__(self, model, sig, y, chunk=None):
        chunk = CHUNK_SAMPLES if chunk is None else int(chunk)
        self.model, self.y, self.sig, self.chunk = model, y, sig, chunk
        self.stateful = model.stateful
        if not self.stateful:
            x, v, i, t, _ = sig
            one = np.zeros(1, dtype=sig.starts.dtype)
            self.parts = [(Signals(x[a:b], v[a:b], None if i is None else i[a:b],
                                   None if t is None else t[a:b], one), a, b)
                          for a in range(0, y.size, chunk) for b in [min(a + chunk, y.size)]]
        self._r = np.empty(y.size)
        self._p = None

    def _forces(self, P):
        """
        Yield ``(a, b, force of the rows P on samples a:b)`` over the record.

        A stateful model's chunks hold ``chunk / len(P)`` samples (``len(P)`` x chunk floats
        per intermediate array whatever the batch).
        """
        with np.errstate(over='ignore', invalid='ignore'):
            if self.stateful:
                yield from self.model._eval_chunks(self.model._force, (P,), self.sig,
                                                   max(1, self.chunk // len(P)))
            else:
                for sig, a, b in self.parts:
                    yield a, b, self.model._eval_force(P, sig)

    def rss(self, p):
        """Return the sum of squares at ``p`` (inf if not finite)."""
        total = 0.0
        self._p = None
        for a, b, F in self._forces(np.asarray(p, dtype=float)[None]):
            r = self._r[a:b]
            np.subtract(F[0], self.y[a:b], out=r)
            if not np.all(np.isfinite(r)):
                return math.inf
            total += float(r @ r)
        self._p = np.array(p, dtype=float)
        return total

    def normal(self, p):
        """Return ``(J^T J, J^T r)`` at ``p``, or None if the Jacobian is not finite."""
        A = g = 0.0
        if self.stateful:
            P, h = self.model._fd_batch(np.asarray(p, dtype=float))
            for a, b, F in self._forces(P):
                r = F[0] - self.y[a:b]
                J = F[1:]
                J -= F[0]
                J /= h[:, None]                 # (d, chunk): the transposed Jacobian
                if not np.all(np.isfinite(J)):
                    return None
                A = A + J @ J.T
                g = g + J @ r
            return A, g
        known = self._p is not None and np.array_equal(self._p, p)
        for sig, a, b in self.parts:
            with np.errstate(over='ignore', invalid='ignore'):
                J = self.model._eval_jacobian(p, sig)
            if not np.all(np.isfinite(J)):
                return None
            if known:
                r = self._r[a:b]
            else:
                with np.errstate(over='ignore', invalid='ignore'):
                    r = self.model._eval_force(p[None], sig)[0] - self.y[a:b]
            A = A + J.T @ J
            g = g + J.T @ r
        return A, g


def _projected_lm_normal(normal, rss, x, cost, lo, hi, *, max_iter=30, ftol=1e-10):
    """
    Box-bounded Levenberg-Marquardt on the normal equations; returns (x, RSS, evaluations).

    For a few parameters and many samples: per iteration the d x d products ``J^T J``,
    ``J^T r`` (``normal(x)``, None when the Jacobian is not finite) and a d x d solve (no
    factorisation of the n x d Jacobian). A parameter at a bound whose gradient points out of
    the box is held; the step of the others (Marquardt's diagonal damping, lambda divided by
    10 after a success, multiplied by 10 after a failure) is clipped to the box and accepted
    only if it lowers the sum of squares (``rss(x)``, inf when not finite). Stops when the
    relative decrease falls below ``ftol``, no step helps, or after ``max_iter`` iterations.
    """
    lam = 1e-3
    evals = 0
    for _ in range(max_iter):
        ne = normal(x)
        evals += 1
        if ne is None:
            break
        A, g = ne
        diag = np.diag(A).copy()
        edge = 1e-12 * (1.0 + np.abs(x))
        held = ((x <= lo + edge) & (g > 0)) | ((x >= hi - edge) & (g < 0)) | (diag <= 0)
        free = ~held
        if not free.any():
            break
        Af = A[np.ix_(free, free)]
        gf = g[free]
        df = diag[free]
        accepted = False
        for _ in range(12):
            try:
                step = np.linalg.solve(Af + lam * np.diag(df), -gf)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            xn = x.copy()
            xn[free] += step
            np.clip(xn, lo, hi, out=xn)
            cn = rss(xn)
            evals += 1
            if cn < cost:
                accepted = True
                break
            lam *= 10.0
        if not accepted:
            break
        small = cost - cn <= ftol * cost
        x, cost = xn, cn
        lam = max(0.1 * lam, 1e-12)
        if small:
            break
    return x, cost, evals


def _polish(model, data, x, lo, hi, max_nfev=50, chunk=None):
    """
    Bounded least-squares refinement of all parameters; returns (x, evaluations, RSS).

    Models with their own Jacobian (the algebraic ones: analytic; Spencer: one batch of
    forward differences): box-bounded Levenberg-Marquardt on the normal equations
    (:func:`_projected_lm_normal`, one evaluation per Jacobian; memoryless models sum them
    over chunks of ``chunk`` (default :data:`CHUNK_SAMPLES`) samples on a record longer than
    :data:`CHUNK_SAMPLES`). The lag models (kwok-current-lag, -amp) on such a record: the same,
    with forward-difference Jacobians summed chunk by chunk (their state runs on through the
    chunks). Others, and the lag models on shorter records: trust-region reflective
    Gauss-Newton (scipy ``least_squares``) with forward-difference Jacobians. The signals are
    validated once, not per evaluation.
    """
    y = np.asarray(data.f, dtype=float)
    sig = model._signals(data.x, data.v, data.i, data.t, data.starts)
    analytic = type(model)._jacobian is not HysteresisModel._jacobian
    big = y.size > CHUNK_SAMPLES
    chunked_state = big and model.stateful and hasattr(model, '_eval_chunks')
    d = x.size

    def resid(p):
        with np.errstate(over='ignore', invalid='ignore'):
            return model._eval_force(p[None], sig)[0] - y

    def jac(p):
        with np.errstate(over='ignore', invalid='ignore'):
            return model._eval_jacobian(p, sig)

    start = np.clip(x, lo, hi)
    if analytic or chunked_state:
        # long records chunk by chunk (bounded memory); other stateful models: all at once
        ls = (_ChunkedResidual(model, sig, y, chunk)
              if big and (not model.stateful or chunked_state) else _Residual(resid, jac))
        rss0 = ls.rss(start)
        if not math.isfinite(rss0):
            return x, 1, math.inf
        xn, rss, evals = _projected_lm_normal(ls.normal, ls.rss, start, rss0, lo, hi,
                                              max_iter=max_nfev)
        return (xn, 1 + evals, rss) if rss < rss0 else (x, 1 + evals, rss0)
    r0 = resid(start)
    if not np.all(np.isfinite(r0)):
        return x, 1, math.inf
    rss0 = float(r0 @ r0)
    try:
        res = least_squares(resid, start, jac=jac, bounds=(lo, hi), method='trf',
                            x_scale='jac', max_nfev=max_nfev, ftol=1e-10, xtol=1e-10)
    except (ValueError, np.linalg.LinAlgError):
        return x, 1, rss0
    evals = 1 + res.nfev + res.njev * (d + 1)
    if np.all(np.isfinite(res.fun)) and res.fun @ res.fun < rss0:
        return res.x, evals, float(res.fun @ res.fun)
    return x, evals, rss0


def _gram_all(model, nonlinear, data, chunk=None):
    """
    Gram matrices and right-hand sides of the regressors of ``nonlinear`` on all samples.

    Summed over chunks of ``chunk`` samples (the (p, n, m) regressors are never formed whole;
    default :data:`CHUNK_SAMPLES`): a memoryless model's chunks are independent, a lag
    model's state runs on through them (``_eval_chunks``); other stateful models' are
    evaluated on the whole record.
    """
    chunk = CHUNK_SAMPLES if chunk is None else int(chunk)
    chunked_state = model.stateful and hasattr(model, '_eval_chunks')
    if (model.stateful and not chunked_state) or data.n <= chunk:
        return gram(model.regressors(nonlinear, data.x, data.v, i=data.i, t=data.t,
                                     starts=data.starts), data.f)
    G = b = 0.0
    if chunked_state:
        N = np.atleast_2d(np.asarray(nonlinear, dtype=float))
        sig = model._signals(data.x, data.v, data.i, data.t, data.starts)
        for a, b_, phi in model._eval_chunks(model._regressors, (N,), sig, chunk):
            Gc, bc = gram(phi, data.f[a:b_])
            G, b = G + Gc, b + bc
        return (G, b) if np.ndim(nonlinear) > 1 else (G[0], b[0])
    for a in range(0, data.n, chunk):
        part = slice(a, a + chunk)
        Gc, bc = gram(model.regressors(nonlinear, data.x[part], data.v[part],
                                       i=None if data.i is None else data.i[part],
                                       t=data.t[part]), data.f[part])
        G, b = G + Gc, b + bc
    return G, b


def _starts(res, n):
    """Swarm best plus up to n - 1 other personal bests from distinct places, best first."""
    pop, cost = res.population, res.population_fun
    span = np.ptp(pop, axis=0) + 1e-300
    out = [np.asarray(res.x, dtype=float)]
    for k in np.argsort(cost):
        if len(out) >= n or not np.isfinite(cost[k]):
            break
        if all(np.max(np.abs(pop[k] - o) / span) > 0.2 for o in out):
            out.append(pop[k])
    return np.array(out)


def _full_cost(model, data):
    """
    RMSE [N] of full parameter sets (p, n_params) -> (p,), for the full PSO.

    For models with :meth:`~mr_damper_model.models.HysteresisModel.separable_parts` the
    residual sum of squares is evaluated in Gram form,
    ``theta^T G(nl) theta - 2 b(nl)^T theta + y^T y``, from the per-record products of
    :class:`SeparableCost`: per particle only the nonlinear factor (one tanh per sample) and two
    small matrix products. Other models evaluate the force.
    """
    y = np.asarray(data.f, dtype=float)
    names = tuple(model.param_names)
    parts = model.separable_parts(data.x, data.v, i=data.i, t=data.t) \
        if model.linear_names and not model.stateful else None
    if parts is not None:
        lin = np.array([names.index(n) for n in model.linear_names], dtype=int)
        nl = np.array([names.index(n) for n in model.nonlinear_names], dtype=int)
        m = lin.size
        sc = SeparableCost(model, data, np.full(m, -np.inf), np.full(m, np.inf), None)
        lin_ordered = lin[sc.order]

        def cost(params):
            with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
                G, b, finite = sc._gram_internal(params[:, nl])
                rss = sum_squares(G, b, sc.yy, params[:, lin_ordered])
                r = np.sqrt(rss / sc.n)
            return np.where(finite & np.isfinite(r), r, np.inf)
        return cost

    def cost(params):
        with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
            f = model.force(params, data.x, data.v, i=data.i, t=data.t, starts=data.starts)
            r = np.sqrt(np.mean((f - y) ** 2, axis=1))
        return np.where(np.isfinite(r), r, np.inf)
    return cost


def _policy_swarm(mdl, data, lo, hi, units, policy, x0v, common):
    """
    Swarm of a model with an ``identification`` policy (Spencer); returns (result, candidate).

    The swarm searches the parameters that act on the states (log-scaled as in the other
    fits) on a contiguous stretch from the start of the record (a stateful model cannot skip
    samples), up to ``swarm_span_s`` after the motion begins (speed above 5 % of its peak),
    with sub-steps of ``swarm_max_substep_s``; per particle the others
    (``spring_names``) come from ``spring_fit`` of the force computed with them at zero. The
    best particle is completed by ``spring_fit`` on all samples with the polish sub-step.
    """
    names = tuple(mdl.param_names)
    spring = np.array([names.index(n) for n in mdl.spring_names], dtype=int)
    dyn = np.array([j for j in range(len(names)) if j not in spring], dtype=int)
    dt = np.diff(data.t)
    dt = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    speed = np.abs(data.v)
    moving = int(np.argmax(speed > 0.05 * np.max(speed)))     # a rest at the start is kept
    n_span = max(2, moving + int(math.ceil(policy['swarm_span_s'] / dt)) + 1)
    part = data if n_span >= data.n else data.select(slice(0, n_span))
    swarm_mdl = mdl.for_identification(policy['swarm_max_substep_s'])
    sig = swarm_mdl._signals(part.x, part.v, part.i, part.t, part.starts)
    space = _Space(lo[dyn], hi[dyn], units[dyn])

    def full_sets(u):
        P = np.zeros((len(u), len(names)))
        P[:, dyn] = space.to_p(u)
        return P

    def cost(u):
        with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
            g = swarm_mdl._eval_force(full_sets(u), sig)
            _, rss = mdl.spring_fit(g, part.x, part.f, lo[spring], hi[spring])
            r = np.sqrt(np.maximum(rss, 0.0) / part.n)
        return np.where(np.isfinite(r), r, np.inf)

    u0 = None if x0v is None else space.to_u(np.clip(x0v[dyn], lo[dyn], hi[dyn]))
    res = pso(cost, space.bounds(), x0=u0, **common)
    best = full_sets(np.atleast_2d(res.x))
    fit_mdl = mdl.for_identification(policy['max_substep_s'])
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
        g = fit_mdl.force(best, data.x, data.v, i=data.i, t=data.t, starts=data.starts)
        theta, _ = mdl.spring_fit(g, data.x, data.f, lo[spring], hi[spring])
    best[:, spring] = theta
    return res, best[0]


def identify(data, model='kwok-current', *, method='separable', unbounded=False, bounds=None,
             seed=None, x0=None, swarm_size=25, maxiter=None, tol=None, budget_s=None,
             callback=None, model_options=None, patience=None, polish=None, n_starts=None):
    """
    Identify the parameters of a damper model from a record.

    Parameters
    ----------
    data : DamperData
        Measured t [s], x [m], v [m/s], f [N], i [A] (validate it first: ``data.validate``).
    model : str or HysteresisModel
        Model name (``'kwok'``, ``'kwok-current'``, ``'bingham'``, ``'bouc-wen'``,
        ``'spencer'``) or model object.
    method : {'separable', 'full'}
        See the module docstring.
    unbounded : bool
        Use the model's wide thesis-comparison bounds (c, k, alpha, f0 of either sign).
    bounds : tuple (lo, hi) of array_like with shape (n_params,), optional
        Overrides the model's default bounds (``param_names`` order).
    seed : int, optional
        Swarm seed; drawn at random and recorded in the result if None.
    x0 : dict or array_like with shape (n_params,), optional
        Warm start (e.g. the previous window's solution).
    swarm_size : int
        Particles.
    maxiter, tol, patience : optional
        Swarm iteration limit, stagnation tolerance and patience; defaults in
        :data:`DEFAULT_BUDGETS` per method.
    budget_s : float, optional
        Wall-time budget [s] of the swarm.
    callback : callable, optional
        ``callback(intermediate_result)`` after each swarm iteration; True stops.
    model_options : dict, optional
        Passed to ``get_model`` (e.g. ``{'i_ref_a': 2.0}``).
    n_starts : int, optional
        Polish the swarm best and up to ``n_starts - 1`` personal bests from other places of
        the search box, keep the best (default 1; 5 with ``unbounded``, whose sign-free box has
        mirror-image local minima, e.g. negative alpha and delta).
    polish : bool, optional
        Refine the swarm's best with a bounded least-squares run (Levenberg-Marquardt with the
        analytic Jacobian; trust-region reflective for models without one) on all parameters
        and all samples. Default: on for ``separable`` with
        an algebraic model (the swarm then works on at most :data:`SWARM_SAMPLES` samples, every
        k-th) and the stateful models whose ``polish_by_default`` says so (kwok-current-lag,
        kwok-current-amp; Spencer, with the swarm and polish of its ``identification``
        policy), off for ``full`` (the thesis method) and the other stateful models.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    ValueError
        Unknown model or method, malformed bounds or x0.

    """
    t_start = time.perf_counter()
    data = _as_data(data)
    if method not in METHODS:
        raise ValueError(f'`method` must be one of {METHODS}, got {method!r}.')
    mdl = get_model(model, **(model_options or {})) if isinstance(model, str) else model
    if seed is None:
        seed = int(np.random.SeedSequence().entropy % (2 ** 31))
    names = tuple(mdl.param_names)
    if bounds is None:
        lo, hi = mdl.default_bounds(unbounded=unbounded)
    else:
        lo, hi = bounds
    lo, hi = as_bounds((lo, hi), name='bounds', require_finite=False)
    if lo.size != len(names):
        raise ValueError(f'`bounds` must have {len(names)} entries {names}.')
    x0v = _param_vector(mdl, x0)
    budget = dict(DEFAULT_BUDGETS[method])
    policy = mdl.identification if method == 'separable' else None
    if polish is None:
        polish = method == 'separable' and (
            not mdl.stateful if mdl.polish_by_default is None else bool(mdl.polish_by_default))
    if method == 'separable' and not polish:
        budget.update(maxiter=60, patience=20)      # no local polish: the swarm must converge
        policy = None
    polish_mdl, polish_nfev = mdl, 50
    if policy is not None:
        budget.update(maxiter=policy['maxiter'], patience=policy['patience'])
        polish_mdl = mdl.for_identification(policy['max_substep_s'])
        polish_nfev = policy['polish_iterations']
    if maxiter is not None:
        budget['maxiter'] = int(maxiter)
    if tol is not None:
        budget['tol'] = float(tol)
    if patience is not None:
        budget['patience'] = int(patience)
    lin_idx = np.array([names.index(n) for n in mdl.linear_names], dtype=int)
    nl_idx = np.array([names.index(n) for n in mdl.nonlinear_names], dtype=int)
    used = method
    units = np.array([mdl.param_units.get(n, '') for n in names])
    if n_starts is None:
        n_starts = 5 if unbounded else 1
    if nl_idx.size == 0 and lin_idx.size:
        cost = SeparableCost(mdl, data, lo[lin_idx], hi[lin_idx], np.zeros((2, 0)))
        with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
            theta, _ = cost.solve(np.zeros((1, 0)))
        x = np.empty(len(names))
        x[lin_idx] = theta[0]
        res_info = dict(success=True, nit=0, nfev=1,
                        message='All parameters linear: solved by bounded least squares.')
        used = 'linear'
        polish = False
    else:
        if method == 'separable' and lin_idx.size == 0 and policy is None:
            used = 'full'
        common = dict(swarm_size=swarm_size, rng=seed, callback=callback, budget_s=budget_s,
                      **budget)
        swarm_data = data
        if polish and policy is None and data.n > 2 * SWARM_SAMPLES:
            swarm_data = data.select(slice(None, None, int(math.ceil(data.n / SWARM_SAMPLES))))
        if policy is None:
            idx = nl_idx if used == 'separable' else np.arange(len(names))
            space = _Space(lo[idx], hi[idx], units[idx])
            u0 = None if x0v is None else space.to_u(np.clip(x0v[idx], lo[idx], hi[idx]))
        if policy is not None:
            res, best = _policy_swarm(mdl, data, lo, hi, units, policy, x0v, common)
            cands = best[None]
        elif used == 'separable':
            nlo, nhi = lo[nl_idx], hi[nl_idx]
            probe = np.stack([nlo + 0.37 * (nhi - nlo), nlo + 0.71 * (nhi - nlo)])
            cost = SeparableCost(mdl, swarm_data, lo[lin_idx], hi[lin_idx], probe)
            res = pso(lambda u: cost(space.to_p(u)), space.bounds(), x0=u0, **common)
            starts = _starts(res, n_starts if polish else 1)
            nl = space.to_p(starts)
            with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
                if swarm_data is data:
                    theta, _ = cost.solve(nl)
                else:       # a few candidates on all samples: direct regressors
                    G, b = _gram_all(mdl, nl, data)
                    theta = box_qp(G, b, lo[lin_idx], hi[lin_idx])
            cands = np.empty((len(nl), len(names)))
            cands[:, nl_idx] = nl
            cands[:, lin_idx] = theta
        else:
            full = _full_cost(mdl, swarm_data)
            res = pso(lambda u: full(space.to_p(u)), space.bounds(), x0=u0, **common)
            cands = space.to_p(_starts(res, n_starts if polish else 1))
        x = cands[0]
        res_info = dict(success=bool(res.success), nit=int(res.nit), nfev=int(res.nfev),
                        message=res.message)
    if polish:
        best = math.inf
        for cand in cands:
            xc, extra, rss = _polish(polish_mdl, data, cand, lo, hi, max_nfev=polish_nfev)
            res_info['nfev'] += extra
            if rss < best:
                x, best = xc, rss
    f_sim = np.asarray(mdl.force(x, data.x, data.v, i=data.i, t=data.t, starts=data.starts),
                       dtype=float)
    if np.all(np.isfinite(f_sim)):
        metrics = fit_metrics(data.f, f_sim)
    else:
        metrics = dict.fromkeys(('mean_abs_error_n', 'rmse_n', 'mean_percent_error',
                                 'max_percent_error', 'nrmse_percent'), math.nan)
    return IdentificationResult(
        model=mdl.name, parameters={n: float(v) for n, v in zip(names, x)}, x=x,
        metrics=metrics, seconds=time.perf_counter() - t_start, seed=seed, method=used,
        current_min_a=float(np.min(data.i)), current_max_a=float(np.max(data.i)),
        model_options=dict(getattr(mdl, 'options', {}) or {}), source=data.source, **res_info)


def current_groups(data, *, tol_a=0.05, min_samples=MIN_LEVEL_SAMPLES):
    """
    Split a record into its coil-current levels, without the transients between them.

    Parameters
    ----------
    data : DamperData
        Record to split.
    tol_a : float
        Currents closer than this [A] form one level.
    min_samples : int
        Levels with fewer samples (coil transients of a current step) are left out.

    Returns
    -------
    list of (float, DamperData)
        ``(level_a, record)`` sorted by level.

    """
    data = _as_data(data)
    return [(lv, data.select(mask, split_gaps=True))
            for lv, mask in _level_masks(data, tol_a, min_samples)]


def current_group_levels(data, *, tol_a=0.05, min_samples=MIN_LEVEL_SAMPLES):
    """
    Return the levels [A] of :func:`current_groups`, without copying the record into groups.

    Parameters and rule as :func:`current_groups`.
    """
    return [lv for lv, _ in _level_masks(_as_data(data), tol_a, min_samples)]


def _level_masks(data, tol_a, min_samples):
    """``(level_a, mask)`` of the levels with at least ``min_samples`` samples."""
    return [(lv, mask) for lv, mask in data._clusters(tol_a)
            if int(np.count_nonzero(mask)) >= min_samples]


def identify_per_current(data, model='kwok', *, tol_a=0.05, min_samples=MIN_LEVEL_SAMPLES,
                         **kw):
    """
    Fit one parameter set per coil-current level (the thesis Table 4.3 layout).

    Parameters
    ----------
    data : DamperData
        Record with several current levels.
    model : str
        Model name (default Kwok, as in the thesis).
    tol_a : float
        Currents closer than this [A] form one level.
    min_samples : int
        Levels with fewer samples are coil transients and are not fitted
        (see :func:`current_groups`).
    **kw
        Passed to :func:`identify`. A ``callback`` is shared by the groups.

    Returns
    -------
    list of IdentificationResult
        Sorted by current level; ``current_a`` holds the level [A].

    Raises
    ------
    ValueError
        No current level with at least ``min_samples`` samples.

    """
    groups = current_groups(data, tol_a=tol_a, min_samples=min_samples)
    if not groups:
        raise ValueError(f'no current level with at least {min_samples} samples')
    out = []
    for level, part in groups:
        r = identify(part, model, **kw)
        r.current_a = float(level)
        out.append(r)
    return out


def compare_models(data, models=('bingham', 'bouc-wen', 'kwok'), **kw):
    """
    Identify several models on the same data (thesis Table 4.1 / Figure 4.14).

    Parameters
    ----------
    data : DamperData
        Record to fit.
    models : sequence of str
        Model names (default Bingham, Bouc-Wen and Kwok).
    **kw
        Passed to :func:`identify` (same seed for every model).

    Returns
    -------
    dict
        Model name -> IdentificationResult, in the order given.

    """
    data = _as_data(data)
    if kw.get('seed') is None:
        kw['seed'] = int(np.random.SeedSequence().entropy % (2 ** 31))
    return {name: identify(data, name, **kw) for name in models}
