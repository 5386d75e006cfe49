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
   multipliers (gradients), until the set repeats (a repeated set satisfies the KKT
   conditions: free values within their bounds, outward gradients at the active bounds);
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
    """
    Primal-dual active-set iteration on unit-scaled problems (all rows violate a bound).

    All rows are iterated together (a settled row reproduces itself, so re-solving it is
    harmless and cheaper than gathering the unsettled ones). A row whose active set repeats
    satisfies the KKT conditions: its free variables lie within their bounds and the gradient
    at each active bound points outwards.
    """
    m = bs.shape[1]
    diag = np.arange(m)
    at_lo = u < los
    at_hi = u > his
    settled = np.zeros(bs.shape[0], dtype=bool)
    for _ in range(max_iter):
        fixed = at_lo | at_hi
        free = ~fixed
        val = np.where(at_lo, los, np.where(at_hi, his, 0.0))
        A = Gs * (free[:, :, None] & free[:, None, :])
        A[:, diag, diag] += fixed
        rhs = np.where(fixed, val, bs - (Gs @ val[..., None])[..., 0])
        u = np.linalg.solve(A, rhs[..., None])[..., 0]
        grad = (Gs @ u[..., None])[..., 0] - bs
        new_lo = (free & (u < los)) | (at_lo & (grad > 0))
        new_hi = (free & (u > his)) | (at_hi & (grad < 0))
        settled = ~np.any((new_lo != at_lo) | (new_hi != at_hi), axis=1)
        at_lo, at_hi = new_lo, new_hi
        if settled.all():
            return u
    for j in np.flatnonzero(~settled):
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
    Compute the residual sum of squares ``||Phi theta - y||^2`` from the Gram form, clipped at 0.

    Parameters
    ----------
    G : ndarray with shape (p, m, m)
        Gram matrices ``Phi^T Phi``.
    b : ndarray with shape (p, m)
        ``Phi^T y``.
    yy : float
        ``y^T y``.
    theta : ndarray with shape (p, m)
        Linear parameter vectors, one per row.

    Returns
    -------
    ndarray with shape (p,)

    """
    quad = np.einsum('pi,pij,pj->p', theta, G, theta)
    return np.maximum(yy - 2.0 * np.einsum('pi,pi->p', b, theta) + quad, 0.0)
