"""
Offline optimal semi-active bound: the best ride any semi-active law could get from a damper.

Not a live law: it knows the whole road in advance (full preview) and optimises the damper force
sequence of the whole run at once. Method (docs/control-laws.md):

1. **Cost.** ``J = mean(a_wk^2) / A0 + rho * mean(F_t,dyn^2) / T0`` with ``a_wk`` the ISO 2631-1
   Wk-weighted body acceleration (:func:`quarter_car_sim.ride_metrics.wk_sos`), ``F_t,dyn`` the
   dynamic tyre load, ``A0`` and ``T0`` their mean squares with the damper at ``i_min`` (the
   softest passive setting); ``rho = 0`` is pure comfort.
2. **Prediction.** The car is linear while the tyre stays on the road, so with the force written
   ``F_k = -c_ref v_rel,k + w_k`` (a reference viscous part fed back at each sample, which only
   conditions the problem) every output is ``y = y_free + G w``: ``y_free`` from one run of the
   car with ``F = -c_ref v_rel``, ``G`` a convolution with the impulse response of the
   discretised car (:func:`quarter_car_sim.dynamics.discretise`, exact for a force held over
   each control period), applied with FFTs and its transpose for the gradient.
3. **Limits.** At each sample the force must lie in the damper's range at the present travel
   and piston velocity over the current range, ``F(x, v, i_min) .. F(x, v, i_max)`` of the
   damper model (on the body ``-F``); this is what makes the problem semi-active (dissipative,
   0 A floor, 2 A ceiling). The limits depend on the trajectory, so they are fixed along the
   present trajectory and the box-constrained QP in ``w`` is solved by projected accelerated
   gradient (FISTA with restart, step from the largest Hessian eigenvalue, exact gradient
   through the transposed convolutions; ``scipy.optimize.minimize`` L-BFGS-B gave the same
   cost, 0.7790 against 0.7790, in 4x the time); then the plan is **projected**: the
   car is run sample by sample, each force clipped to the limits at the state actually reached
   (so the final force sequence respects the limits at every step, by construction), the
   limits are taken again along that trajectory, and the QP is solved again (sequential convex
   programming). The best projected run (including the start, the ``i_min`` passive car) is
   kept, so the bound is never worse than the softest passive setting in ``J``. This outer
   loop (:func:`sequential_projection`) serves the full car's bound too
   (:mod:`quarter_car_sim.full_car.bound`).
4. **Honest evaluation.** The projected forces are turned into coil currents by the inverse
   model and that current sequence is replayed open loop through the real simulation
   (:func:`quarter_car_sim.simulate.simulate`, any plant, coil lag included).

The plan starts where the replay starts: the car at rest on the road's first height ``settle_s``
before the road (the settling every simulation runs, planned but not scored), and over the first
control period the car's initial damper force (no command reaches that period: a command acts
from the next period on, :class:`CurrentSchedule`). So the replay on a plant equal to the model
follows the plan to the inverse's tolerance, on any machine: a plan that chose a first force the
replay cannot make would start the replay off the plan, and the model's ``sign(travel)`` term
(a jump of the force at zero travel) then spreads that difference through the run by whichever
side of zero each round-off falls (issue 32).

Assumptions: the prediction knows the road exactly and uses the damper model's force map (for
the MR damper: the identified kwok-current model, a static map of travel, velocity and current,
no coil lag); the tyre stays on the road in the prediction (the projection run lets it lift);
the optimum is local (the limits make the problem non-convex), so it is the best found, a
bound in the engineering sense rather than a certificate.
"""
import dataclasses
import math

import numpy as np
from scipy import signal

from quarter_car_sim.dynamics import discretise, QuarterCar
from quarter_car_sim.ride_metrics import ride_metrics, wk_sos


class KwokForceModel:
    """
    Force map of the identified kwok-current damper model, for the bound.

    Parameters
    ----------
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse
        Identified model (its parameters, reference current and current range).

    """

    def __init__(self, inverse):
        from mr_damper_model.models.kwok_current import KwokCurrent, kwok_current_coefficients
        self.inverse = inverse
        self.i_min, self.i_max = inverse.i_min, inverse.i_max
        self._p = np.array([inverse.params[n] for n in KwokCurrent.param_names])
        # c, alpha, beta at the two ends of the current range (rows: i_min, i_max)
        c, alpha, beta = kwok_current_coefficients(
            self._p[None, :], np.array([self.i_min, self.i_max]) / inverse.i_ref_a)
        self._ends = np.column_stack([c[0], alpha[0], beta[0]])

    def body_force_range(self, travel, v_rel):
        """Reachable damper forces on the body ``(lo, hi)`` [N] at one state (floats)."""
        return self.inverse.body_force_range(travel, v_rel)

    def body_force_range_array(self, travel, v_rel):
        """Like :meth:`body_force_range`, vectorised over arrays of shape (n,)."""
        x = np.asarray(travel, dtype=float)
        v = np.asarray(v_rel, dtype=float)
        p = self._p
        static = p[2] * x + p[9]                      # k x + f0
        arg = p[8] * np.sign(x)                       # delta sign(x)
        a, b = (-(c * v + static + alpha * np.tanh(beta * v + arg))
                for c, alpha, beta in self._ends)     # the kwok-current force at each end
        return np.minimum(a, b), np.maximum(a, b)

    def currents(self, f_body, travel, v_rel):
        """Coil currents [A] giving the forces on the body ``f_body`` [N] (arrays (n,))."""
        from mr_damper_model.models.inverse import inverse_current
        inv = self.inverse
        res = inverse_current(-np.asarray(f_body, dtype=float), travel, v_rel, inv.params,
                              i_ref_a=inv.i_ref_a, i_min=inv.i_min, i_max=inv.i_max,
                              tol_a=1e-5)
        return res.current


class CurrentSchedule:
    """
    Replay of a precomputed coil-current sequence (``kind == 'current'``).

    The command issued at sample ``k`` sets the force from sample ``k + 1`` on (the plant makes
    its force at the end of each control period), so ``demand`` at sample ``k`` returns
    ``currents[k + 1]``; before the road starts (settling) it returns ``currents[0]``.

    Parameters
    ----------
    currents : array_like with shape (n,)
        Current for the force over control period k [A].
    t0 : float
        Time of sample 0 [s].
    dt : float
        Control period [s].
    name : str
        Controller name.

    """

    kind = 'current'

    def __init__(self, currents, t0, dt, name='bound'):
        self.currents = np.asarray(currents, dtype=float).tolist()
        if not self.currents or not all(map(math.isfinite, self.currents)):
            raise ValueError('`currents` must be a non-empty sequence of finite currents')
        self.t0, self.dt, self.name = float(t0), float(dt), name

    def reset(self):
        """No internal state."""

    def demand(self, state):
        """Return the current [A] to command at this sample."""
        k = int(round((state.t - self.t0) / self.dt)) + 1
        return self.currents[min(max(k, 0), len(self.currents) - 1)]


@dataclasses.dataclass
class BoundResult:
    """
    Result of :func:`semi_active_bound`.

    Attributes
    ----------
    force : ndarray (n,)
        Damper force on the body over each control period from ``t0`` [N] (the projected
        optimum).
    current : ndarray (n,)
        Coil currents giving those forces on the damper model [A].
    predicted : dict
        Time series of the recorded part of the projected run on the damper model (``t``,
        ``a_s``, ``travel``, ``v_rel``, ``tyre_force``, ``damper_force``, ``force_lo``,
        ``force_hi``, ``static_tyre_load``).
    predicted_metrics : dict
        :func:`quarter_car_sim.ride_metrics.ride_metrics` of the projected run.
    cost, cost_start : float
        ``J`` of the result and of the start (``i_min`` passive car).
    cost_history : list of float
        ``J`` of each projected run.
    replay : SimResult or None
        The current sequence replayed on the plant by :func:`simulate` (None without a plant).
    rho : float
        Tyre-load weight.
    nit : int
        Outer (projection) iterations done.
    t0 : float
        Time of the first planned sample [s] (the settling's start, before the road).

    """

    force: np.ndarray
    current: np.ndarray
    predicted: dict
    predicted_metrics: dict
    cost: float
    cost_start: float
    cost_history: list
    replay: object
    rho: float
    nit: int
    t0: float = 0.0

    def metrics(self):
        """Ride metrics of the replay on the plant (else of the prediction)."""
        return self.predicted_metrics if self.replay is None else self.replay.metrics()


def _impulse_responses(params, dt, c_ref, n):
    """Responses of ``[a_s, travel, v_rel, dynamic tyre load]`` to a unit ``w_0`` (n,) each."""
    d = discretise(params, dt, contact=True)
    phi, g = d[:, :4], d[:, 7]
    sel = np.array([0.0, 1.0, 0.0, -1.0])
    phi_cl = phi - c_ref * np.outer(g, sel)
    p = params
    C = np.array([
        [-p.k_s / p.m_s, -(p.c_s + c_ref) / p.m_s, p.k_s / p.m_s, (p.c_s + c_ref) / p.m_s],
        [1.0, 0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0, -1.0],
        [0.0, 0.0, -p.k_t, -p.c_t],
    ])
    D = np.array([1.0 / p.m_s, 0.0, 0.0, 0.0])
    h = np.empty((4, n))
    h[:, 0] = D
    x = g.copy()
    for k in range(1, n):
        h[:, k] = C @ x
        x = phi_cl @ x
    return h


class _Conv:
    """Causal convolution with a kernel (FFT) and its transpose, for sequences of length n."""

    def __init__(self, kernel, n):
        self.h, self.n = np.asarray(kernel, dtype=float), n

    def __call__(self, w):
        return signal.oaconvolve(w, self.h)[:self.n]

    def T(self, r):
        return signal.oaconvolve(r[::-1], self.h)[:self.n][::-1]


def _rollout(params, road, dt, n, t0, model, w, c_ref):
    """
    Run the car from rest at ``t0`` with ``F_k = clip(-c_ref v_rel,k + w_k, lo_k, hi_k)``.

    Over the first period the force is the car's initial one, whatever ``w_0`` (no command
    reaches it; its limits are that force).
    """
    car = QuarterCar(params, None, road, t0=t0)
    rng = model.body_force_range
    out = np.empty((8, n))
    wl = np.asarray(w, dtype=float).tolist()
    step = car.step_force
    s = car.state
    for k in range(n):
        lo, hi = rng(s.travel, s.v_rel) if k else (s.damper_force, s.damper_force)
        f = -c_ref * s.v_rel + wl[k]
        f = lo if f < lo else (hi if f > hi else f)
        out[:, k] = (s.t, s.z_s, s.z_u, s.travel, s.v_rel, s.tyre_force, lo, hi)
        wl[k] = f
        s = step(dt, f)
    p = params
    force = np.asarray(wl)
    t, _, _, tr, vr, ft, lo, hi = out
    a_s = (force - p.k_s * tr - p.c_s * vr) / p.m_s
    return {'t': t, 'a_s': a_s, 'travel': tr, 'v_rel': vr, 'tyre_force': ft,
            'damper_force': force, 'force_lo': lo, 'force_hi': hi,
            'static_tyre_load': p.static_tyre_load}


class Unlimited:
    """A force model without limits: the free response's (any force is reachable)."""

    @staticmethod
    def body_force_range(travel, v_rel):
        """Return ``(-inf, inf)``."""
        return -math.inf, math.inf


def _free_response(params, road, dt, n, t0, c_ref):
    """Run the car with ``F = -c_ref v_rel`` only (``w = 0``, no limits)."""
    return _rollout(params, road, dt, n, t0, Unlimited, np.zeros(n), c_ref)


def largest_eigenvalue(hess, n, iters=30):
    """Largest eigenvalue of a symmetric positive operator (power iteration, +5 % margin)."""
    v = np.random.default_rng(0).standard_normal(n)
    lam = 0.0
    for _ in range(iters):
        hv = hess(v)
        lam = float(np.linalg.norm(hv))
        v = hv / lam
    return 1.05 * lam


def fista_box(grad, lipschitz, w, lb, ub, maxiter):
    """Projected accelerated gradient (FISTA with gradient restart) on the box [lb, ub]."""
    y, t = w.copy(), 1.0
    step = 1.0 / lipschitz
    for _ in range(maxiter):
        w_new = np.clip(y - step * grad(y), lb, ub)
        t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
        if np.dot(y - w_new, w_new - w) > 0.0:
            t_new, y = 1.0, w_new
        else:
            y = w_new + ((t - 1.0) / t_new) * (w_new - w)
        w, t = w_new, t_new
    return w


def check_bound_options(rho, dt, outer, maxiter, settle_s=0.0):
    """Raise ValueError unless the options of a bound are in range."""
    if not (math.isfinite(rho) and rho >= 0.0):
        raise ValueError(f'`rho` must be >= 0, got {rho}')
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f'`dt` must be > 0, got {dt}')
    if not (math.isfinite(settle_s) and settle_s >= 0.0):
        raise ValueError(f'`settle_s` must be >= 0, got {settle_s}')
    if int(outer) < 0 or int(maxiter) < 1:
        raise ValueError('`outer` must be >= 0 and `maxiter` >= 1')


def sequential_projection(start, cost_of, box_along, rollout, grad, lipschitz, *, outer=6,
                          maxiter=100, callback=None):
    """
    Run the outer loop of the bounds (quarter car and full car): linearise, solve, project.

    From ``start`` (the projected run of the ``i_min`` passive car), each round takes the
    force limits along the linear prediction of the present run (``box_along``), solves the
    box-constrained QP by :func:`fista_box` from the present forces, and projects the plan on
    the nonlinear car (``rollout``). The best projected run, the start included, is kept.

    Parameters
    ----------
    start : dict
        Projected run to start from.
    cost_of : callable
        ``cost_of(run) -> J`` of a projected run.
    box_along : callable
        ``box_along(run) -> (w, lb, ub)``: the run's QP variables and the box of the QP
        around it (flat arrays of one length).
    rollout : callable
        ``rollout(w) -> run``: the plan ``w`` projected on the nonlinear car.
    grad : callable
        Gradient of the QP's cost in ``w``.
    lipschitz : float
        Upper bound of the QP's Hessian eigenvalues (:func:`largest_eigenvalue`).
    outer, maxiter : int
        Rounds; projected-gradient iterations per QP.
    callback : callable, optional
        ``callback(k, cost)`` after each projected run; returning True stops.

    Returns
    -------
    best : dict
        The best projected run.
    history : list of float
        ``J`` of the start and of each projected run (``min(history)`` is ``best``'s).

    """
    best, j_best = start, cost_of(start)
    history = [j_best]
    run = start
    for k in range(int(outer)):
        w, lb, ub = box_along(run)
        w = fista_box(grad, lipschitz, np.clip(w, lb, ub), lb, ub, int(maxiter))
        run = rollout(w)
        j = cost_of(run)
        history.append(j)
        if j < j_best:
            best, j_best = run, j
        if callback is not None and callback(k + 1, j):
            break
    return best, history


def semi_active_bound(params, road, force_model, plant=None, *, rho=0.0, dt=1e-3,
                      c_ref=1500.0, outer=6, maxiter=100, kernel_s=4.0, settle_s=0.5,
                      callback=None):
    """
    Offline optimal semi-active control of the quarter car on a known road (a bound).

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters.
    road : RoadProfile
        Road, known in full in advance.
    force_model : object
        Damper force map: ``body_force_range(travel, v_rel)`` (floats),
        ``body_force_range_array(travel, v_rel)`` (arrays) -> ``(lo, hi)`` forces on the body
        [N], and ``currents(f_body, travel, v_rel)`` -> currents [A]
        (e.g. :class:`KwokForceModel`).
    plant : DamperPlant, optional
        True damper for the honest replay of the current sequence (:func:`simulate`).
    rho : float
        Weight of the dynamic tyre load in the cost (0: comfort only).
    dt : float
        Control period [s].
    c_ref : float
        Reference viscous damping of the parametrisation [N s/m] (conditioning only; the
        result does not depend on it except through the local optimum found).
    outer : int
        Projection (outer) iterations.
    maxiter : int
        Projected-gradient (FISTA) iterations per QP.
    kernel_s : float
        Length of the impulse responses [s] (they decay with ``c_ref``).
    settle_s : float
        Time planned before the road starts, on its first height, and run by the replay's
        settling (as :func:`simulate`); not scored.
    callback : callable, optional
        ``callback(k, cost)`` after each projected run; returning True stops.

    Returns
    -------
    BoundResult
        ``force`` and ``current`` cover the planned samples from ``t0`` (the settling
        first); ``predicted`` the recorded part.

    """
    check_bound_options(rho, dt, outer, maxiter, settle_s)
    n_settle = int(round(settle_s / dt))
    t0 = float(road.t[0]) - n_settle * dt
    n = n_settle + int(round(road.duration / dt)) + 1
    mask = np.arange(n) >= n_settle
    n_rec = float(mask.sum())
    sos = wk_sos(1.0 / dt)
    nk = min(n, max(2, int(round(kernel_s / dt))))
    h = _impulse_responses(params, dt, c_ref, nk)
    conv_a = _Conv(signal.sosfilt(sos, h[0]), n)
    conv_tr, conv_vr, conv_t = _Conv(h[1], n), _Conv(h[2], n), _Conv(h[3], n)
    free = _free_response(params, road, dt, n, t0, c_ref)
    w_load = params.static_tyre_load
    a_free = signal.sosfilt(sos, free['a_s'])
    t_free = free['tyre_force'] - w_load

    def rollout(w, model=force_model, c=c_ref):
        return _rollout(params, road, dt, n, t0, model, w, c)

    start = rollout(np.zeros(n), c=0.0)
    a0 = np.sum(signal.sosfilt(sos, start['a_s'])[mask] ** 2) / n_rec
    t0_load = np.sum((start['tyre_force'] - w_load)[mask] ** 2) / n_rec

    def cost_of(run):
        return float(np.sum(signal.sosfilt(sos, run['a_s'])[mask] ** 2) / (n_rec * a0)
                     + rho * np.sum((run['tyre_force'] - w_load)[mask] ** 2) / (n_rec * t0_load))

    def grad(w):
        g = (2.0 / (n_rec * a0)) * conv_a.T((a_free + conv_a(w)) * mask)
        if rho > 0:
            g += (2.0 * rho / (n_rec * t0_load)) * conv_t.T((t_free + conv_t(w)) * mask)
        return g

    def hess(v):
        hv = (2.0 / (n_rec * a0)) * conv_a.T(conv_a(v) * mask)
        if rho > 0:
            hv += (2.0 * rho / (n_rec * t0_load)) * conv_t.T(conv_t(v) * mask)
        return hv

    def box_along(run):
        w = run['damper_force'] + c_ref * run['v_rel']
        tr = free['travel'] + conv_tr(w)
        vr = free['v_rel'] + conv_vr(w)
        lo, hi = force_model.body_force_range_array(tr, vr)
        lb, ub = lo + c_ref * vr, hi + c_ref * vr
        lb[0] = ub[0] = w[0]                    # the first period's force is the car's own
        return w, lb, ub

    best, history = sequential_projection(start, cost_of, box_along, rollout, grad,
                                          largest_eigenvalue(hess, n), outer=outer,
                                          maxiter=maxiter, callback=callback)
    cur = force_model.currents(best['damper_force'], best['travel'], best['v_rel'])
    replay = None
    if plant is not None:
        from quarter_car_sim.simulate import simulate
        sched = CurrentSchedule(cur, t0, dt, name=bound_name(rho))
        replay = simulate(params, road, sched, plant, dt=dt, settle_s=settle_s)
    predicted = {k: (v[mask] if isinstance(v, np.ndarray) else v) for k, v in best.items()}
    return BoundResult(force=best['damper_force'], current=np.asarray(cur), predicted=predicted,
                       predicted_metrics=ride_metrics(predicted), cost=min(history),
                       cost_start=history[0], cost_history=history, replay=replay,
                       rho=float(rho), nit=len(history) - 1, t0=t0)


def bound_name(rho=0.0):
    """Name of the bound in tables: ``bound`` (comfort only) or ``bound(rho=R)``."""
    return 'bound' if rho == 0 else f'bound(rho={rho:g})'
