"""
The costs and solvers behind :func:`~mr_damper_model.identification.identify.identify`.

Separable least squares, the chunked residuals of long records, the polish.
"""
import math

import numpy as np
from scipy.optimize import least_squares

from mr_damper_model.identification.lsq import box_qp, gram, sum_squares
from mr_damper_model.models import HysteresisModel, Signals


#: Samples per chunk of a memoryless model's polish and final linear solve on all samples: their
#: normal equations (``J^T J``, ``J^T r``, the Gram matrix) are summed chunk by chunk, so the
#: (n, n_params) Jacobian and the regressors are never formed whole (memory of a fit of a
#: 3-million-sample record: ``bench/bench_csv_memory.py``).
CHUNK_SAMPLES = 262144


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
