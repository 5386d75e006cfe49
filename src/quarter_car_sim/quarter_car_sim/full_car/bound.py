"""
Offline optimal semi-active bound of the full car: the best ride four dampers could give.

Not a live law: like the quarter car's bound (:mod:`quarter_car_sim.bound`, its method in
docs/control-laws.md) it knows the whole road in advance and optimises the four damper force
sequences of the whole run at once; this is the same method with four inputs.

1. **Cost.** ``J = a_v^2 / a_v0^2 + rho * mean_i(mean(F_t,dyn,i^2) / T0_i)``: ``a_v`` the ISO
   2631-1 vibration total value of :func:`quarter_car_sim.full_car.metrics.iso2631_seat` at the
   seat (Wk vertical, We pitch x 0.40, We roll x 0.63, the metric's own filters), squared, so
   the comfort part is exactly the metric; ``F_t,dyn,i`` the dynamic tyre load of wheel ``i``;
   ``a_v0`` and ``T0_i`` those of the car with every damper at ``i_min``. Only the recorded
   samples count (``t >= 0``; the settling before it, as :func:`simulate_full_car` runs it, is
   planned too but not scored).
2. **Prediction.** With all wheels on the road the car is linear. Each corner's force is
   written ``F_i,k = -c_ref v_rel,i,k + w_i,k`` (a reference viscous part that only conditions
   the problem), so every output is ``y = y_free + H w``: ``y_free`` one run of the car
   with ``F = -c_ref v_rel``, ``H`` a 4-input convolution with the impulse responses of the
   exactly discretised car (:func:`quarter_car_sim.full_car.dynamics.discretise`), applied
   with one FFT per input and output (and its transpose for the gradient).
3. **Limits.** At each sample each corner's force lies in that corner's damper range at its
   travel and velocity over the current range (``body_force_range`` of its force model, e.g.
   :class:`quarter_car_sim.bound.KwokForceModel` of the corner's identified set): dissipative,
   0 A floor, 2 A ceiling. As for the quarter car the limits are fixed along the present
   trajectory, the box-constrained QP in ``w`` is solved by projected accelerated gradient
   (:func:`quarter_car_sim.bound.fista_box`), the plan is **projected** by running the
   nonlinear car (:class:`FullCar`, tyres may lift) sample by sample with each corner's force
   clipped to its limits at the state reached, and the QP is solved again along that run. The
   best projected run, the ``i_min`` start included, is kept. The outer loop is the quarter
   car's (:func:`quarter_car_sim.bound.sequential_projection`), and so is the start of the
   plan: over the first period the car's own initial forces, which no command reaches.
4. **Honest evaluation.** Each corner's forces become coil currents through its force model's
   inverse; the four current sequences are replayed open loop through
   :func:`quarter_car_sim.full_car.simulate.simulate_full_car` on the "true" plants (coil lag
   included) and scored with the same metrics as every live law.

Assumptions (those of the quarter-car bound): exact road preview; the damper model's static
force map (no coil lag) in the prediction; the optimum is local (the limits make the problem
non-convex): the best found, a bound in the engineering sense, not a certificate.
"""
import dataclasses
import math

import numpy as np
from scipy import fft as sfft, signal

from quarter_car_sim.bound import (bound_name, BoundResult, check_bound_options,
                                   CurrentSchedule, largest_eigenvalue, sequential_projection,
                                   Unlimited)
from quarter_car_sim.full_car.dynamics import corner_maps, discretise, FullCar, N_Q
from quarter_car_sim.full_car.metrics import AXIS_FACTORS, we_sos
from quarter_car_sim.ride_metrics import wk_sos


class MimoConv:
    """Causal multi-input multi-output convolution (FFT) and its transpose, length n."""

    def __init__(self, kernels, n):
        k = np.asarray(kernels, dtype=float)            # (outputs, inputs, nk)
        self.n = int(n)
        self.nfft = sfft.next_fast_len(self.n + k.shape[2], real=True)
        self.hf = sfft.rfft(k, self.nfft, axis=-1)

    def __call__(self, w):
        """Return the outputs (o, n) of inputs ``w`` (i, n)."""
        wf = sfft.rfft(w, self.nfft, axis=-1)
        return sfft.irfft(np.einsum('oif,if->of', self.hf, wf), self.nfft, axis=-1)[:, :self.n]

    def T(self, r):
        """Apply the transpose: inputs (i, n) of output residuals ``r`` (o, n)."""
        rf = sfft.rfft(r[:, ::-1], self.nfft, axis=-1)
        g = sfft.irfft(np.einsum('oif,of->if', self.hf, rf), self.nfft, axis=-1)
        return g[:, :self.n][:, ::-1]


def _output_maps(params, c_ref):
    """
    Output matrices of ``[body acc (3), travel (4), v_rel (4), dynamic tyre load (4)]``.

    With ``F = -c_ref v_rel + w`` each output at a sample is ``C x + D w`` (``x = [q, v]``).
    """
    p = params
    T, S, P = corner_maps(p)
    ks = p.spring_matrix()
    cs = np.diag(p.c_s + c_ref)
    minv_b = np.diag(1.0 / np.array([p.m_s, p.i_pitch, p.i_roll]))
    z4 = np.zeros((4, N_Q))
    C = np.vstack([
        np.hstack([-minv_b @ T.T @ ks @ S, -minv_b @ T.T @ cs @ S]),
        np.hstack([S, z4]),
        np.hstack([z4, S]),
        np.hstack([-p.k_t * P, -p.c_t * P]),
    ])
    D = np.vstack([minv_b @ T.T, np.zeros((12, 4))])
    return C, D


def impulse_responses(params, dt, c_ref, n):
    """
    Responses of the linear car to a unit ``w`` at one corner, shape (15, 4, n).

    Rows: body accelerations ``[zdd, thetadd, phidd]``, travels (4), travel rates (4), dynamic
    tyre loads (4); columns: the corner of the unit input (``fl, fr, rl, rr``).
    """
    d = discretise(params, dt)
    phi, g = d[:, :2 * N_Q], d[:, 26:30]
    _, S, _ = corner_maps(params)
    sv = np.hstack([np.zeros((4, N_Q)), S])
    phi_cl = phi - c_ref * g @ sv
    C, D = _output_maps(params, c_ref)
    h = np.empty((C.shape[0], 4, n))
    h[:, :, 0] = D
    x = g.copy()
    for k in range(1, n):
        h[:, :, k] = C @ x
        x = phi_cl @ x
    return h


def _rollout(params, road, dt, n, t0, models, w, c_ref):
    """
    Run the nonlinear car with ``F_i,k = clip(-c_ref v_rel + w_i,k, lo, hi)`` per corner.

    Over the first period the forces are the car's initial ones, whatever ``w[:, 0]`` (no
    command reaches it; their limits are those forces). Returns the series of the run as a
    dict of arrays (time first).
    """
    car = FullCar(params, None, road, t0=t0)
    rng = [m.body_force_range for m in models]
    keys = ('q', 'v', 'travel', 'v_rel', 'tyre_force')
    out = {k: np.empty((n, 7 if k in ('q', 'v') else 4)) for k in keys}
    t = np.empty(n)
    force, lo, hi = np.empty((n, 4)), np.empty((n, 4)), np.empty((n, 4))
    wt = np.asarray(w, dtype=float).T.tolist()
    s = car.state
    step = car.step_force
    f_init = s.damper_force.tolist()
    for k in range(n):
        tr, vr = s.travel.tolist(), s.v_rel.tolist()
        wk = wt[k]
        f = [0.0] * 4
        for i in range(4):
            a, b = rng[i](tr[i], vr[i]) if k else (f_init[i], f_init[i])
            fi = -c_ref * vr[i] + wk[i]
            f[i] = a if fi < a else (b if fi > b else fi)
            lo[k, i], hi[k, i] = a, b
        force[k] = f
        t[k] = s.t
        for key in keys:
            out[key][k] = getattr(s, key)
        s = step(dt, f)
    out.update(t=t, damper_force=force, force_lo=lo, force_hi=hi)
    out['acc'] = _accelerations(params, out)
    return out


def _accelerations(params, run):
    """Accelerations (n, 7) at each sample with the force held over the following period."""
    p = params
    T = p.geometry
    fs = (run['damper_force'] - run['travel'] @ p.spring_matrix().T
          - run['v_rel'] * p.c_s)
    acc = np.empty((fs.shape[0], N_Q))
    acc[:, :3] = (fs @ T) / np.array([p.m_s, p.i_pitch, p.i_roll])
    acc[:, 3:] = (run['tyre_force'] - p.static_tyre_loads - fs) / p.m_u
    return acc


@dataclasses.dataclass
class FullCarBoundResult(BoundResult):
    """
    Result of :func:`full_car_bound`: the fields of the quarter car's ``BoundResult``.

    There ``force``, ``current`` are (n, 4) (a column per corner, samples from ``t0``),
    ``predicted`` is the projected run's recorded part (``t >= 0``) as a ``FullCarResult``,
    ``predicted_metrics`` its :func:`full_car_metrics`, ``replay`` the currents replayed on
    the plants by :func:`simulate_full_car` (None without plants), ``cost_start`` the cost
    with every damper at ``i_min``, ``t0`` the time of the first planned sample
    (``-settle_s``); and:

    Attributes
    ----------
    force_lo, force_hi : ndarray (n, 4)
        Each corner's force limits along the kept run [N].

    """

    force_lo: np.ndarray = None
    force_hi: np.ndarray = None

    def metrics(self, params, *, seat=(0.0, 0.0)):
        """Metrics of the replay on the plants (else of the prediction)."""
        if self.replay is None:
            return self.predicted_metrics
        return self.replay.metrics(params, seat=seat)


def _as_result(run, mask, name):
    """Return the recorded part of a rollout as a :class:`FullCarResult`."""
    from quarter_car_sim.full_car.simulate import FullCarResult
    n = int(mask.sum())
    nan4 = np.full((n, 4), math.nan)
    return FullCarResult(
        t=run['t'][mask], q=run['q'][mask], v=run['v'][mask], acc=run['acc'][mask],
        travel=run['travel'][mask], v_rel=run['v_rel'][mask], z_r=nan4,
        tyre_force=run['tyre_force'][mask], coil_current=nan4,
        damper_force=run['damper_force'][mask], current_cmd=nan4, demand=nan4,
        normal=np.zeros((n, 4), dtype=bool), law=name)


def corner_force_model(damper_params, params):
    """
    Force map of one corner's identified Kwok-current set, for the bound.

    Parameters
    ----------
    damper_params : dict, ParamsFile or path
        The corner's identified set (as :func:`quarter_car_sim.full_car.simulate.corner_message`
        takes it).
    params : FullCarParams
        Car (its coil current range).

    Returns
    -------
    quarter_car_sim.bound.KwokForceModel
        Over the current range the set was identified on, within the car's.

    """
    from mr_damper_model.models.inverse import KwokCurrentInverse
    from quarter_car_sim.bound import KwokForceModel
    from quarter_car_sim.full_car.simulate import corner_message
    msg = corner_message(damper_params)
    lo = max(params.i_min, msg['current_min_a'])
    hi = min(params.i_max, msg['current_max_a'])
    if not hi > lo:
        lo, hi = params.i_min, params.i_max
    return KwokForceModel(KwokCurrentInverse(msg, i_ref_a=msg['i_ref_a'], i_min=lo, i_max=hi,
                                             tol_a=1e-6, sign_convention='body'))


def full_car_bound(params, road, force_models, plants=None, damper_params=None, *, rho=0.0,
                   dt=1e-3, c_ref=1500.0, outer=6, maxiter=100, kernel_s=4.0, settle_s=0.5,
                   seat=(0.0, 0.0), callback=None):
    """
    Offline optimal semi-active control of the full car on a known road (a bound).

    Parameters
    ----------
    params : FullCarParams
        Car.
    road : TwoTrackRoad
        Road, known in full in advance (the recorded part covers ``road.duration``).
    force_models : sequence of 4
        Damper force map of each corner ``fl, fr, rl, rr``: ``body_force_range(travel,
        v_rel)`` -> ``(lo, hi)`` forces on the body [N] (floats) and ``currents(f_body,
        travel, v_rel)`` -> currents [A] (arrays), e.g.
        :class:`quarter_car_sim.bound.KwokForceModel`.
    plants : sequence of 4 DamperPlant, optional
        The "true" dampers for the honest replay of the current sequences.
    damper_params : sequence of 4, optional
        Identified sets offered to the replay's supervisors (as :func:`simulate_full_car`;
        the replayed currents do not depend on them).
    rho : float
        Weight of the dynamic tyre loads in the cost (0: comfort only).
    dt : float
        Control period [s].
    c_ref : float
        Reference viscous damping of the parametrisation [N s/m] (conditioning only).
    outer, maxiter : int
        Projection iterations; projected-gradient iterations per QP.
    kernel_s : float
        Length of the impulse responses [s].
    settle_s : float
        Time planned before ``t = 0`` and run by the replay's settling (not scored).
    seat : (float, float)
        Seat ``(x, y)`` from the CG [m] of the comfort cost and the metrics.
    callback : callable, optional
        ``callback(k, cost)`` after each projected run; returning True stops.

    Returns
    -------
    FullCarBoundResult

    """
    check_bound_options(rho, dt, outer, maxiter, settle_s)
    models = list(force_models)
    if len(models) != 4:
        raise ValueError(f'`force_models` must hold 4 models (fl, fr, rl, rr), got '
                         f'{len(models)}')
    n_settle = int(round(settle_s / dt))
    t0 = -n_settle * dt
    n = n_settle + int(round(road.duration / dt)) + 1
    mask = np.arange(n) >= n_settle
    n_rec = float(mask.sum())
    fs = 1.0 / dt
    x_s, y_s = seat
    wk, we = wk_sos(fs), we_sos(fs)
    kx = AXIS_FACTORS

    def comfort(acc):
        """ISO-weighted seat vertical, pitch, roll of ``acc`` (3, ..., n), axis factors in."""
        a_z = acc[0] - x_s * acc[1] + y_s * acc[2]
        return np.stack([signal.sosfilt(wk, a_z, axis=-1),
                         kx['pitch'] * signal.sosfilt(we, acc[1], axis=-1),
                         kx['roll'] * signal.sosfilt(we, acc[2], axis=-1)])

    nk = min(n, max(2, int(round(kernel_s / dt))))
    h = impulse_responses(params, dt, c_ref, nk)
    h_comfort = comfort(h[:3])                        # (3, 4, nk): the filters are linear
    conv_tv = MimoConv(h[3:11], n)                       # travels and rates, for the limits

    free = _rollout(params, road, dt, n, t0, [Unlimited] * 4, np.zeros((4, n)), c_ref)
    start = _rollout(params, road, dt, n, t0, models, np.zeros((4, n)), 0.0)
    w_load = params.static_tyre_loads
    a0 = float(np.sum(comfort(start['acc'].T)[:, mask] ** 2) / n_rec)
    t0_i = np.sum(((start['tyre_force'] - w_load).T[:, mask]) ** 2, axis=1) / n_rec
    if not (a0 > 0 and np.all(t0_i > 0)):
        raise ValueError('the road does not excite the car (no cost to bound)')
    # cost rows scaled so that J = sum(mask * rows^2) / n_rec
    scale_c = 1.0 / math.sqrt(a0)
    scale_t = np.sqrt(rho / (4.0 * t0_i))
    kern = [h_comfort * scale_c]
    y_free = [comfort(free['acc'].T) * scale_c]
    if rho > 0:
        kern.append(h[11:15] * scale_t[:, None, None])
        y_free.append((free['tyre_force'] - w_load).T * scale_t[:, None])
    conv_j = MimoConv(np.concatenate(kern), n)
    y_free = np.concatenate(y_free)

    def rows_of(run):
        rows = [comfort(run['acc'].T) * scale_c]
        if rho > 0:
            rows.append((run['tyre_force'] - w_load).T * scale_t[:, None])
        return np.concatenate(rows)

    def cost_of(run):
        return float(np.sum(rows_of(run)[:, mask] ** 2) / n_rec)

    def grad(wf):
        e = (y_free + conv_j(wf.reshape(4, n))) * mask
        return ((2.0 / n_rec) * conv_j.T(e)).ravel()

    def hess(vf):
        return ((2.0 / n_rec) * conv_j.T(conv_j(vf.reshape(4, n)) * mask)).ravel()

    def box_along(run):
        w = (run['damper_force'] + c_ref * run['v_rel']).T
        tv = np.concatenate([free['travel'].T, free['v_rel'].T]) + conv_tv(w)
        tr, vr = tv[:4], tv[4:]
        lb, ub = np.empty((4, n)), np.empty((4, n))
        for i, m in enumerate(models):
            lo, hi = m.body_force_range_array(tr[i], vr[i])
            lb[i], ub[i] = lo + c_ref * vr[i], hi + c_ref * vr[i]
        lb[:, 0] = ub[:, 0] = w[:, 0]           # the first period's forces are the car's own
        return w.ravel(), lb.ravel(), ub.ravel()

    def rollout(wf):
        return _rollout(params, road, dt, n, t0, models, wf.reshape(4, n), c_ref)

    best, history = sequential_projection(start, cost_of, box_along, rollout, grad,
                                          largest_eigenvalue(hess, 4 * n), outer=outer,
                                          maxiter=maxiter, callback=callback)
    force = best['damper_force']
    current = np.column_stack([np.asarray(m.currents(force[:, i], best['travel'][:, i],
                                                     best['v_rel'][:, i]), dtype=float)
                               for i, m in enumerate(models)])
    name = bound_name(rho)
    predicted = _as_result(best, mask, name)
    replay = None
    if plants is not None:
        from quarter_car_sim.full_car.control import PerCornerLaws
        from quarter_car_sim.full_car.simulate import simulate_full_car
        law = PerCornerLaws([CurrentSchedule(current[:, i], t0, dt, name=name)
                             for i in range(4)], name=name)
        replay = simulate_full_car(params, road, law, plants, damper_params, dt=dt,
                                   settle_s=settle_s)
    return FullCarBoundResult(
        force=force, current=current, predicted=predicted,
        predicted_metrics=predicted.metrics(params, seat=seat), cost=min(history),
        cost_start=history[0], cost_history=history, replay=replay, rho=float(rho),
        nit=len(history) - 1, t0=t0, force_lo=best['force_lo'], force_hi=best['force_hi'])
