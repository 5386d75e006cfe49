"""
Batched box-bounded linear least squares for the separable identification.

For p particles at once, solve ``min ||Phi_j theta - y||^2`` subject to ``lo <= theta <= hi``
with ``Phi_j`` of shape (n, m), m small (up to about 8). The work is done on the Gram matrices
``G = Phi^T Phi`` (p, m, m) and ``b = Phi^T y`` (p, m), so the cost per particle after the Gram
products is independent of n:

1. columns are scaled to unit norm (conditioning), a tiny ridge keeps collinear columns solvable;
2. the unconstrained solution is computed for every particle (batched ``numpy.linalg.solve``);
3. particles that violate a bound run a primal-dual active-set iteration (Hintermueller, Ito and
   Kunisch 2002), vectorised over the particles: each step solves the equality-constrained
   problem for the current active set and updates the set from the primal values and the
   multipliers (gradients), until the set repeats; the result is checked against the KKT
   conditions;
4. a particle that does not settle within a few iterations (rare) is solved exactly by
   bounded-variable least squares (``scipy.optimize.lsq_linear``, BVLS) on the Cholesky factor.

Infinite bounds (unbounded mode) are allowed.
"""
import numpy as np
from scipy.optimize import lsq_linear

__all__ = ['box_qp', 'gram', 'bounded_lstsq', 'sum_squares']

_RIDGE = 1e-11


def gram(phi, y):
    """
    Gram matrix and right-hand side of a batch of least-squares problems.

    Parameters
    ----------
    phi : array_like with shape (p, n, m) or (n, m)
        Regressor matrices.
    y : array_like with shape (n,)
        Target (measured force [N]).

    Returns
    -------
    G : ndarray with shape (p, m, m) (or (m, m))
    b : ndarray with shape (p, m) (or (m,))

    """
    phi = np.asarray(phi, dtype=float)
    y = np.asarray(y, dtype=float)
    phit = np.swapaxes(phi, -1, -2)
    return phit @ phi, phit @ y


def _kkt_ok(u, grad, at_lo, at_hi, lo, hi, scale):
    tol = 1e-9 * scale
    free = ~(at_lo | at_hi)
    feas = np.all(~free | ((u >= lo - 1e-9 * (1 + np.abs(lo))) & (u <= hi + 1e-9 * (1 + np.abs(hi)))),
                  axis=1)
    mult = np.all((~at_lo | (grad >= -tol)) & (~at_hi | (grad <= tol)), axis=1)
    return feas & mult


def box_qp(G, b, lo, hi, *, max_iter=None, ridge=_RIDGE):
    """
    Solve a batch of box-constrained least-squares problems given their Gram matrices.

    Minimises ``theta^T G theta - 2 b^T theta`` (equal to ``||Phi theta - y||^2 - y^T y``)
    subject to ``lo <= theta <= hi`` for each of the p problems.

    Parameters
    ----------
    G : array_like with shape (p, m, m)
        Symmetric positive semi-definite Gram matrices ``Phi^T Phi``.
    b : array_like with shape (p, m)
        ``Phi^T y``.
    lo, hi : array_like with shape (m,)
        Bounds, may be infinite; ``lo <= hi``.
    max_iter : int, optional
        Active-set iterations before the exact fallback; default ``2 m + 4``.
    ridge : float
        Relative ridge added to the unit-scaled Gram diagonal (keeps exactly collinear columns,
        e.g. a current-dependent term on single-current data, solvable: minimum-norm split).

    Returns
    -------
    theta : ndarray with shape (p, m)

    Raises
    ------
    ValueError
        On inconsistent shapes or bounds.

    """
    G = np.asarray(G, dtype=float)
    b = np.asarray(b, dtype=float)
    squeeze = G.ndim == 2
    if squeeze:
        G, b = G[None], b[None]
    if G.ndim != 3 or G.shape[1] != G.shape[2] or b.shape != G.shape[:2]:
        raise ValueError('`G` must have shape (p, m, m) and `b` shape (p, m).')
    p, m = b.shape
    lo = np.broadcast_to(np.asarray(lo, dtype=float), (m,))
    hi = np.broadcast_to(np.asarray(hi, dtype=float), (m,))
    if np.any(lo > hi):
        raise ValueError('`lo` above `hi`.')
    if max_iter is None:
        max_iter = 2 * m + 4
    diag = np.einsum('pii->pi', G)
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    Gs = G / (d[:, :, None] * d[:, None, :])
    Gs[:, np.arange(m), np.arange(m)] += ridge
    bs = b / d
    los = lo * d
    his = hi * d
    u = np.linalg.solve(Gs, bs[..., None])[..., 0]
    viol = np.any((u < los) | (u > his), axis=1)
    if viol.any():
        idx = np.flatnonzero(viol)
        u[idx] = _active_set(Gs[idx], bs[idx], los[idx], his[idx], u[idx], max_iter)
    theta = u / d
    return theta[0] if squeeze else theta


def _active_set(Gs, bs, los, his, u, max_iter):
    """Primal-dual active-set iteration on unit-scaled problems (all rows violate a bound)."""
    q, m = bs.shape
    at_lo = u < los
    at_hi = u > his
    done = np.zeros(q, dtype=bool)
    eye = np.eye(m, dtype=bool)
    scale = 1.0 + np.abs(bs)
    for _ in range(max_iter):
        act = np.flatnonzero(~done)
        if act.size == 0:
            break
        G_a, b_a, lo_a, hi_a = Gs[act], bs[act], los[act], his[act]
        al, ah = at_lo[act], at_hi[act]
        fixed = al | ah
        free = ~fixed
        val = np.where(al, lo_a, 0.0) + np.where(ah, hi_a, 0.0)
        A = np.where(free[:, :, None] & free[:, None, :], G_a, 0.0)
        A[:, eye] = np.where(fixed, 1.0, A[:, eye])
        rhs = np.where(fixed, val, b_a - np.einsum('pij,pj->pi', G_a, val))
        ua = np.linalg.solve(A, rhs[..., None])[..., 0]
        grad = np.einsum('pij,pj->pi', G_a, ua) - b_a
        new_lo = (free & (ua < lo_a)) | (al & (grad > 0))
        new_hi = (free & (ua > hi_a)) | (ah & (grad < 0))
        settled = np.all(new_lo == al, axis=1) & np.all(new_hi == ah, axis=1)
        u[act] = ua
        ok = settled & _kkt_ok(ua, grad, al, ah, lo_a, hi_a, scale[act, :].max(axis=1,
                                                                               keepdims=True))
        done[act[ok]] = True
        at_lo[act] = new_lo
        at_hi[act] = new_hi
    for j in np.flatnonzero(~done):
        u[j] = _exact_one(Gs[j], bs[j], los[j], his[j])
    return u


def _exact_one(Gs, bs, los, his):
    """Exact bounded least squares for one scaled problem (BVLS on the Cholesky factor)."""
    R = np.linalg.cholesky(Gs).T           # Gs = R^T R (ridge makes it positive definite)
    c = np.linalg.solve(R.T, bs)
    res = lsq_linear(R, c, bounds=(los, his), method='bvls', tol=1e-12)
    return res.x


def bounded_lstsq(phi, y, lo, hi, **kw):
    """
    Batched box-bounded linear least squares from the regressors.

    Parameters
    ----------
    phi : array_like with shape (p, n, m) or (n, m)
        Regressor matrices.
    y : array_like with shape (n,)
        Target.
    lo, hi : array_like with shape (m,)
        Bounds (may be infinite).
    **kw
        Passed to :func:`box_qp`.

    Returns
    -------
    theta : ndarray with shape (p, m) or (m,)

    """
    G, b = gram(phi, y)
    return box_qp(G, b, lo, hi, **kw)


def sum_squares(G, b, yy, theta):
    """
    Residual sum of squares ``||Phi theta - y||^2`` from the Gram form, clipped at 0.

    Parameters
    ----------
    G : ndarray with shape (p, m, m)
    b : ndarray with shape (p, m)
    yy : float
        ``y^T y``.
    theta : ndarray with shape (p, m)

    Returns
    -------
    ndarray with shape (p,)

    """
    quad = np.einsum('pi,pij,pj->p', theta, G, theta)
    return np.maximum(yy - 2.0 * np.einsum('pi,pi->p', b, theta) + quad, 0.0)
