"""
Receding-horizon MPC with road preview and the dampers' semi-active limits (issue 36).

The offline bound (:mod:`quarter_car_sim.full_car.bound`) plans the four damper forces of a
whole run with the road known; this law plans them over the preview horizon from the present
state, every ``update_every`` control periods, and applies the plan in between:

- **prediction**: the linear full car (tyres on the road), exactly discretised at the control
  period (:func:`~quarter_car_sim.full_car.dynamics.discretise`), with each corner's force
  ``-c_ref v_rel + w`` (the bound's parametrisation); its response to the present state and to
  the previewed road (heights under ``fl, fr, rl, rr`` from the law's
  :class:`~quarter_car_sim.road_preview.RoadPreview`, relative to the road under each wheel
  now) is a precomputed state map plus an FFT convolution, its response to ``w`` the bound's
  impulse responses;
- **cost**: the squared ISO 2631-1 weighted accelerations over the horizon (Wk on the seat's
  vertical, We x 0.40 on pitch and We x 0.63 on roll: the integrand of a_v squared), the
  filters starting from their state now (run inside the law on the measured accelerations);
- **constraints**: each corner's force within its damper's range at the predicted travel and
  velocity over the current range (``body_force_range_array`` of the corner's force model, the
  identified kwok-current set: dissipative, 0 A floor, 2 A ceiling), taken along the previous
  plan's prediction; a box on ``w`` as in the bound;
- **solver**: the bound's projected accelerated gradient (:func:`quarter_car_sim.bound.
  fista_box`) warm-started from the previous plan shifted, ``maxiter`` iterations. The box QP
  is a convolution: FFTs make each iteration O(H log H), with no matrix of the horizon's size
  formed (a general QP solver such as OSQP would take the dense condensed problem or the
  banded one with the states as variables; not tried, docs/preview.md);
- **applied**: a command acts from the next control period on (the damper makes its force at
  the end of a period, as the bound's replay schedules it), so the plan keeps the present
  period's force (the one acting) and each period the law asks for the next period's planned
  ``w``, clipped to the damper range at the measured state (the bound's projection), then
  clipped (dissipative) and sent through the corner's inverse and supervisor as every
  full-car law.

Without a preview window (no speed signal yet, a dropout longer than the map ahead) the law is
``full-car-clipped-optimal-wk`` for that step (run every step so its filters stay current),
counted in ``stats``.
"""
import math
import time

import numpy as np
from scipy import signal

from quarter_car_sim.bound import fista_box, largest_eigenvalue
from quarter_car_sim.controllers.preview import PreviewStats
from quarter_car_sim.full_car.bound import impulse_responses, MimoConv
from quarter_car_sim.full_car.control import ForceLaw
from quarter_car_sim.full_car.dynamics import corner_maps, discretise, N_Q, N_X
from quarter_car_sim.full_car.metrics import AXIS_FACTORS, we_sos
from quarter_car_sim.ride_metrics import wk_sos

#: Defaults of :class:`FullCarMpcPreview`: horizon [s], control periods between plans,
#: projected-gradient iterations per plan, reference damping of the parametrisation [N s/m].
DEFAULT_MPC = {'horizon_s': 0.5, 'update_every': 20, 'maxiter': 10, 'c_ref': 1500.0}


class FullCarMpcPreview(ForceLaw):
    """
    Receding-horizon MPC of the four damper forces with road preview (module docstring).

    Parameters
    ----------
    params : FullCarParams
        Car (the prediction model).
    force_models : sequence of 4
        Each corner's damper force map (``body_force_range``, ``body_force_range_array``),
        e.g. :func:`quarter_car_sim.full_car.bound.corner_force_model` of its identified set;
        :meth:`set_force_model` replaces one (a node does when a corner's supervisor accepts
        a new set).
    road : RoadPreview
        The car's road preview (:func:`quarter_car_sim.full_car.preview.make_road_preview`).
    fallback : ForceLaw
        The law without preview (``full-car-clipped-optimal-wk``), run every step.
    horizon_s : float
        Prediction horizon [s].
    update_every : int
        Control periods between plans.
    maxiter : int
        Projected-gradient iterations per plan.
    c_ref : float
        Reference damping of the parametrisation [N s/m].
    dt : float
        Control period [s].
    name : str
        Law name.

    Attributes
    ----------
    solve_s : list of float
        Wall time of each plan [s] (the bench's timing).

    """

    state_fields = ('z_u', 'z_r')

    def __init__(self, params, force_models, road, fallback, *,
                 horizon_s=DEFAULT_MPC['horizon_s'], update_every=DEFAULT_MPC['update_every'],
                 maxiter=DEFAULT_MPC['maxiter'], c_ref=DEFAULT_MPC['c_ref'], dt=1e-3,
                 name='full-car-mpc-preview'):
        self.models = list(force_models)
        if len(self.models) != 4 or len(road.wheels) != 4:
            raise ValueError('`force_models` and `road` must cover the four corners')
        self.dt, self.c_ref, self.name = float(dt), float(c_ref), name
        self.H = int(round(horizon_s / self.dt))
        self.update_every, self.maxiter = int(update_every), int(maxiter)
        if self.H < 2 or not 1 <= self.update_every <= self.H or self.maxiter < 1:
            raise ValueError('need horizon_s >= 2 dt, 1 <= update_every <= horizon steps and '
                             'maxiter >= 1')
        self.road, self.fallback = road, fallback
        H, fs = self.H, 1.0 / self.dt
        self.sos = [wk_sos(fs), we_sos(fs), we_sos(fs)]
        self.kx = np.array([1.0, AXIS_FACTORS['pitch'], AXIS_FACTORS['roll']])
        h = impulse_responses(params, self.dt, self.c_ref, H)
        hc = np.stack([self.kx[i] * signal.sosfilt(self.sos[i], h[i], axis=-1)
                       for i in range(3)])
        self._conv_j = MimoConv(hc, H)                       # w -> weighted accelerations
        self._conv_tv = MimoConv(h[3:11], H)                 # w -> travels and their rates
        self._lip = largest_eigenvalue(
            lambda v: (2.0 * self._conv_j.T(self._conv_j(v.reshape(4, H)))).ravel(), 4 * H)
        self._free_maps(params)
        self.times_s = np.arange(H + 1) * self.dt
        self.stats = PreviewStats()
        super().__init__()

    def _free_maps(self, params):
        """Precompute the prediction of the outputs from the state and the previewed road."""
        H = self.H
        d = discretise(params, self.dt)
        T, S, _ = corner_maps(params)
        sv = np.hstack([np.zeros((4, N_Q)), S])
        phi = d[:, :N_X] - self.c_ref * d[:, 26:30] @ sv
        r0 = d[:, 14:18] - d[:, 22:26] / self.dt          # road at the step's start ...
        r1 = d[:, 18:22] + d[:, 22:26] / self.dt          # ... and end (first-order hold)
        p = params
        fs = np.hstack([-p.spring_matrix() @ S, -(np.diag(p.c_s) + self.c_ref * np.eye(4)) @ S])
        minv_b = 1.0 / np.array([p.m_s, p.i_pitch, p.i_roll])
        C = np.vstack([minv_b[:, None] * (T.T @ fs), np.hstack([S, np.zeros((4, N_Q))]), sv])
        M = np.empty((H + 1, C.shape[0], N_X))            # C phi^k
        x = np.eye(N_X)
        for k in range(H + 1):
            M[k] = C @ x
            x = phi @ x
        self._M = M[:H]
        self._MR1 = M[:H] @ r1
        kz = np.zeros((C.shape[0], 4, H))                 # y_k = M_k (x0 - r1 z_0) + sum Kz z
        kz[:, :, 0] = (M[0] @ r1)
        kz[:, :, 1:] = np.transpose(M[:H - 1] @ r0 + M[1:H] @ r1, (1, 2, 0))
        self._conv_z = MimoConv(kz, H)

    def set_force_model(self, corner, model):
        """Replace one corner's damper force map (index 0..3)."""
        self.models[int(corner)] = model

    def reset(self):
        """Clear the plan, the filters, the road preview, the fallback law and the counters."""
        super().reset()
        self.fallback.reset()
        self.road.reset()
        self.stats.reset()
        self._zi = [np.zeros((s.shape[0], 2)) for s in self.sos]
        self._acc = np.zeros(3)
        self._plan = None
        self._k = 0
        self._t = -math.inf
        self.solve_s = []

    def _step_filters(self, acc):
        """Advance the weighting filters by the accelerations of the new sample."""
        for i in range(3):
            _, self._zi[i] = signal.sosfilt(self.sos[i], [acc[i]], zi=self._zi[i])

    def plan(self, state, heights):
        """
        Plan ``w`` (4, H) from the state and the previewed heights (H + 1, 4) [m].

        The heights are taken relative to the road under each wheel now (``state.z_r``), so
        an offset of the preview does not matter and an estimated state (road 0) works too.
        """
        start = time.perf_counter()
        H = self.H
        z = (state.z_r[None, :] + (heights - heights[0])).T          # (4, H + 1)
        x0 = np.concatenate([state.q, state.v])
        y = self._M @ x0 - self._MR1 @ z[:, 0] + self._conv_z(z[:, :H]).T   # (H, 11)
        acc, tv = y[:, :3], y[:, 3:]
        y_free = np.stack([self.kx[i] * signal.sosfilt(self.sos[i], acc[:, i],
                                                       zi=self._zi[i])[0] for i in range(3)])
        if self._plan is None:
            w = np.zeros((4, H))
        else:
            e = self.update_every
            w = np.concatenate([self._plan[:, e:], np.repeat(self._plan[:, -1:], e, axis=1)],
                               axis=1)
        pred = tv.T + self._conv_tv(w)
        tr, vr = pred[:4], pred[4:]
        lb, ub = np.empty((4, H)), np.empty((4, H))
        for i, m in enumerate(self.models):
            lo, hi = m.body_force_range_array(tr[i], vr[i])
            lb[i], ub[i] = lo + self.c_ref * vr[i], hi + self.c_ref * vr[i]
        # the force of the present period is the one acting: a command acts from the next
        lb[:, 0] = ub[:, 0] = np.asarray(state.damper_force) + self.c_ref * np.asarray(
            state.v_rel)
        conv = self._conv_j

        def grad(wf):
            return (2.0 * conv.T(y_free + conv(wf.reshape(4, H)))).ravel()

        lb, ub = lb.ravel(), ub.ravel()
        wf = fista_box(grad, self._lip, np.clip(w.ravel(), lb, ub), lb, ub, self.maxiter)
        self.solve_s.append(time.perf_counter() - start)
        return wf.reshape(4, H)

    def desired_forces(self, state):
        """Return the planned forces of this period, or the fallback law's without a window."""
        f_fallback = self.fallback.desired_forces(state)
        if state.t != self._t:
            self._t = state.t
            self._step_filters(self._acc)
            self._acc = np.asarray(state.acc[:3], dtype=float)
            self._k += 1
            if self._plan is None or self._k >= self.update_every:
                z = self.road.window(self.times_s)
                self._plan = None if z is None else self._replan(state, z)
        self.stats.count(self._plan is not None)
        if self._plan is None:
            return f_fallback
        w = self._plan[:, self._k + 1]                    # the next period's (module docstring)
        f = np.empty(4)
        for i, m in enumerate(self.models):
            lo, hi = m.body_force_range(float(state.travel[i]), float(state.v_rel[i]))
            f[i] = min(max(-self.c_ref * float(state.v_rel[i]) + w[i], lo), hi)
        return f

    def _replan(self, state, heights):
        # the filters hold the samples before this one; the plan's first output is this one
        plan = self.plan(state, heights)
        self._k = 0
        return plan

    def status(self):
        """Counters and plan timing (JSON-ready)."""
        st = {'law': self.stats.as_dict(), 'road_preview': self.road.status(),
              'plans': len(self.solve_s)}
        if self.solve_s:
            st['plan_ms_median'] = 1e3 * float(np.median(self.solve_s))
            st['plan_ms_p95'] = 1e3 * float(np.percentile(self.solve_s, 95))
        return st


def make_full_car_mpc_preview(params, force_models, *, dt=1e-3, name='full-car-mpc-preview',
                              **options):
    """
    Build :class:`FullCarMpcPreview` with the ``full-car-clipped-optimal-wk`` fallback.

    ``options`` override :data:`DEFAULT_MPC`.
    """
    from quarter_car_sim.full_car.lqr_wk import FullCarClippedOptimalWk
    from quarter_car_sim.full_car.preview import make_road_preview
    opts = {**DEFAULT_MPC, **options}
    return FullCarMpcPreview(params, force_models, make_road_preview(params),
                             FullCarClippedOptimalWk.from_car(params, dt=dt), dt=dt, name=name,
                             **opts)
