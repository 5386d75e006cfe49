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

The costs and solvers (separable least squares, chunked residuals of long records, the
polish) are in :mod:`mr_damper_model.identification.separable`.
"""
from dataclasses import dataclass, field
import math
import time

import numpy as np

from mr_damper_model.identification.lsq import box_qp
from mr_damper_model.identification.metrics import fit_metrics
from mr_damper_model.identification.pso import as_bounds, pso
from mr_damper_model.identification.separable import (_full_cost, _gram_all, _param_vector,
                                                      _polish, _Space, _starts, SeparableCost)
from mr_damper_model.io.data import DamperData
from mr_damper_model.models import get_model

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


#: A current level needs at least this many samples to be fitted on its own; fewer are the coil
#: transients between the levels of a step test (a few samples per step), left out of
#: per-current fits.
MIN_LEVEL_SAMPLES = 50


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
