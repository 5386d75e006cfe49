"""
Particle swarm optimisation, vectorised over the swarm (thesis section 2.4, eq. 2.36-2.39).

The formulation is the one of the seed thesis: positions and velocities initialised at random in
the bounds, velocity update with an inertia weight decreasing linearly from 0.9 to 0.4, cognitive
and social constants c1 = c2 = 2.0, a velocity clamp of a fraction of each parameter range and a
global-best (star) topology. The time step of eq. 2.37-2.39 is 1 (one iteration).

Additions the thesis does not have: positions are kept in the bounds (clipped, and the velocity
component that left the box is zeroed), termination by stagnation, by a callback or by a time
budget, and a warm start that seeds part of the swarm around a previous solution.
"""
import time

import numpy as np
from scipy.optimize import Bounds, OptimizeResult

__all__ = ['pso', 'as_bounds', 'TERMINATION_MESSAGES']

TERMINATION_MESSAGES = {
    1: 'Best cost improved less than `tol` (relative) over `patience` iterations.',
    0: 'Maximum number of iterations `maxiter` reached.',
    -1: 'Callback requested stop.',
    -2: 'Time budget `budget_s` exhausted.',
}


def as_bounds(bounds, *, name='bounds', require_finite=True):
    """
    Convert bounds to two float arrays ``lo``, ``hi``.

    Parameters
    ----------
    bounds : tuple (lo, hi) of array_like with shape (d,), or scipy.optimize.Bounds
        Lower and upper bounds per dimension.
    name : str
        Argument name used in error messages.
    require_finite : bool
        Reject infinite bounds (the PSO needs a finite box).

    Returns
    -------
    lo, hi : ndarray with shape (d,)

    Raises
    ------
    ValueError
        If the bounds are malformed, empty, not finite (when required) or lo > hi.

    """
    if isinstance(bounds, Bounds):
        lo, hi = bounds.lb, bounds.ub
    else:
        try:
            lo, hi = bounds
        except (TypeError, ValueError):
            raise ValueError(f'`{name}` must be a pair (lo, hi) of arrays.') from None
    lo = np.atleast_1d(np.asarray(lo, dtype=float)).copy()
    hi = np.atleast_1d(np.asarray(hi, dtype=float)).copy()
    if lo.ndim != 1 or lo.shape != hi.shape or lo.size == 0:
        raise ValueError(f'`{name}`: lo and hi must be 1-D arrays of the same non-zero length.')
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)):
        raise ValueError(f'`{name}` contains NaN.')
    if require_finite and not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError(f'`{name}` must be finite for the particle swarm.')
    if np.any(lo > hi):
        raise ValueError(f'`{name}`: lower bound above upper bound.')
    return lo, hi


def pso(fun, bounds, *, swarm_size=25, maxiter=100, inertia=(0.9, 0.4), c1=2.0, c2=2.0,
        vmax_fraction=0.2, tol=1e-8, patience=20, x0=None, warm_fraction=0.5,
        warm_spread=0.05, rng=None, callback=None, budget_s=None):
    """
    Minimise ``fun`` over a box with a global-best particle swarm.

    Parameters
    ----------
    fun : callable
        ``fun(X) -> costs``, ``X`` with shape (p, d), costs with shape (p,). Non-finite costs
        are treated as +inf (the particle is never a best).
    bounds : tuple (lo, hi) of array_like with shape (d,), or scipy.optimize.Bounds
        Finite search box.
    swarm_size : int
        Number of particles p (thesis: 20-30).
    maxiter : int
        Maximum number of iterations (velocity updates) after the initial swarm.
    inertia : tuple (w_start, w_end)
        Inertia weight decreasing linearly from ``w_start`` at the first iteration to ``w_end``
        at iteration ``maxiter``. With a warm start (``x0``) the schedule starts half-way,
        at ``(w_start + w_end) / 2``.
    c1, c2 : float
        Cognitive (personal best) and social (global best) acceleration constants.
    vmax_fraction : float
        Velocity clamp as a fraction of each dimension's range.
    tol : float
        Stagnation tolerance: stop when the best cost improved by less than
        ``tol * |best|`` over the last ``patience`` iterations.
    patience : int
        Iterations over which stagnation is measured.
    x0 : array_like with shape (d,), optional
        Warm start. One particle is placed at ``x0`` (clipped to the box), and
        ``warm_fraction`` of the swarm in total around it with a Gaussian spread of
        ``warm_spread`` times the range, with initial velocities of that size; the rest is
        uniform in the box.
    warm_fraction : float
        Fraction of the swarm seeded around ``x0`` (0..1).
    warm_spread : float
        Standard deviation of the warm seeds, as a fraction of each range.
    rng : None, int or numpy.random.Generator
        Seed or generator. The same seed and the same ``fun`` give bitwise the same result
        (unless ``budget_s`` stops the run).
    callback : callable, optional
        ``callback(intermediate_result)`` after each iteration, with an OptimizeResult holding
        ``x``, ``fun``, ``nit``, ``nfev``. Returning True stops the run.
    budget_s : float, optional
        Wall-time budget [s]; the run stops after the iteration that exceeds it.

    Returns
    -------
    scipy.optimize.OptimizeResult
        ``x`` (d,), ``fun``, ``nit``, ``nfev``, ``status`` (1 stagnation, 0 maxiter, -1 callback,
        -2 time budget), ``success`` (``status > 0``), ``message``, ``history`` (best cost
        after the initial swarm and after each iteration, shape (nit + 1,)), ``population``
        (personal bests, (p, d)) and ``population_fun`` (their costs).

    Raises
    ------
    ValueError
        On malformed bounds, options, ``x0`` or a ``fun`` returning the wrong shape.

    """
    lo, hi = as_bounds(bounds)
    d = lo.size
    swarm_size = int(swarm_size)
    maxiter = int(maxiter)
    patience = int(patience)
    if swarm_size < 2:
        raise ValueError('`swarm_size` must be at least 2.')
    if maxiter < 0:
        raise ValueError('`maxiter` must be >= 0.')
    if patience < 1:
        raise ValueError('`patience` must be >= 1.')
    if not 0.0 < vmax_fraction:
        raise ValueError('`vmax_fraction` must be positive.')
    if not 0.0 <= warm_fraction <= 1.0:
        raise ValueError('`warm_fraction` must be within [0, 1].')
    if tol < 0:
        raise ValueError('`tol` must be >= 0.')
    w_start, w_end = (float(w) for w in inertia)
    if x0 is not None:
        # a warm-started swarm is already near a solution: skip the exploring half of the
        # inertia schedule (the cold part of the swarm still covers the box)
        w_start = 0.5 * (w_start + w_end)
    gen = np.random.default_rng(rng)
    span = hi - lo
    vmax = vmax_fraction * span
    t_start = time.perf_counter()

    def evaluate(pos):
        cost = np.asarray(fun(pos), dtype=float)
        if cost.shape != (pos.shape[0],):
            raise ValueError(f'`fun` must return shape ({pos.shape[0]},), got {cost.shape}.')
        return np.where(np.isfinite(cost), cost, np.inf)

    # eq. 2.36: positions uniform in the box
    pos = lo + gen.random((swarm_size, d)) * span
    if x0 is not None:
        x0 = np.atleast_1d(np.asarray(x0, dtype=float))
        if x0.shape != (d,) or not np.all(np.isfinite(x0)):
            raise ValueError(f'`x0` must be a finite array with shape ({d},).')
        n_warm = max(1, int(round(warm_fraction * swarm_size)))
        start = np.clip(x0, lo, hi)
        seeds = start + gen.standard_normal((n_warm, d)) * (warm_spread * span)
        seeds[0] = start
        pos[:n_warm] = np.clip(seeds, lo, hi)
    # eq. 2.37 with dt = 1, read as a displacement to another random point of the box (the
    # literal formula is a position, not a velocity); then the velocity clamp
    vel = np.clip(lo + gen.random((swarm_size, d)) * span - pos, -vmax, vmax)
    if x0 is not None:
        # warm particles start slow: a step of the size of their spread, not across the box
        vel[:n_warm] = np.clip(gen.standard_normal((n_warm, d)) * (warm_spread * span),
                               -vmax, vmax)

    cost = evaluate(pos)
    nfev = swarm_size
    pbest = pos.copy()
    pbest_cost = cost.copy()
    g = int(np.argmin(pbest_cost))
    gbest = pbest[g].copy()
    gbest_cost = pbest_cost[g]
    history = [gbest_cost]
    status = 0
    nit = 0
    for k in range(maxiter):
        w = w_start + (w_end - w_start) * (k / (maxiter - 1) if maxiter > 1 else 1.0)
        r1 = gen.random((swarm_size, d))
        r2 = gen.random((swarm_size, d))
        # eq. 2.38 (dt = 1) with the velocity clamp
        vel = w * vel + c1 * r1 * (pbest - pos) + c2 * r2 * (gbest - pos)
        np.clip(vel, -vmax, vmax, out=vel)
        # eq. 2.39, then keep the particles in the box
        pos = pos + vel
        out = (pos < lo) | (pos > hi)
        if out.any():
            np.clip(pos, lo, hi, out=pos)
            vel[out] = 0.0
        cost = evaluate(pos)
        nfev += swarm_size
        better = cost < pbest_cost
        pbest[better] = pos[better]
        pbest_cost[better] = cost[better]
        g = int(np.argmin(pbest_cost))
        if pbest_cost[g] < gbest_cost:
            gbest = pbest[g].copy()
            gbest_cost = pbest_cost[g]
        history.append(gbest_cost)
        nit = k + 1
        if callback is not None:
            inter = OptimizeResult(x=gbest.copy(), fun=float(gbest_cost), nit=nit, nfev=nfev)
            if callback(inter) is True:
                status = -1
                break
        if nit >= patience:
            old = history[-1 - patience]
            if np.isfinite(old) and old - gbest_cost <= tol * abs(old):
                status = 1
                break
        if budget_s is not None and time.perf_counter() - t_start > budget_s:
            status = -2
            break
    return OptimizeResult(x=gbest, fun=float(gbest_cost), nit=nit, nfev=nfev, status=status,
                          success=status > 0, message=TERMINATION_MESSAGES[status],
                          history=np.asarray(history), population=pbest,
                          population_fun=pbest_cost)
