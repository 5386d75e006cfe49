"""
Frequency-weighted full-car clipped-optimal control: the ISO 2631-1 filters inside the LQR.

The road-relative car of :mod:`quarter_car_sim.full_car.lqr` (state ``x = [s, d, v_b, v_u]``,
the four corner forces ``F`` on the body) augmented with the ISO 2631-1 weighting filters the
ride metric uses (:mod:`quarter_car_sim.full_car.metrics`), each driven by a body
acceleration ``y = Cy x + Dy F``:

- Wk (8 states, :func:`quarter_car_sim.controllers.optimal.wk_state_space`) on the vertical
  acceleration at the seat ``zdd - x_seat thetadd + y_seat phidd`` (the CG by default, as the
  metric);
- We (6 states each, :func:`quarter_car_sim.controllers.optimal.weighting_state_space` of
  :data:`quarter_car_sim.ride_metrics.WE_CONSTANTS`) on the pitch and the roll acceleration.

Cost (SI)::

    integral( q_wk a_wz^2 + q_we_pitch a_w,pitch^2 + q_we_roll a_w,roll^2
              + q_heave zdd^2 + q_pitch thetadd^2 + q_roll phidd^2
              + q_travel |s|^2 + q_tyre |d|^2 + r_force |F|^2 ) dt

with the default rotational weights the squares of the axis factors (0.40, 0.63 m/rad), so
the weighted part is the integrand of the metric's a_v squared. The design runs on the
14-dimensional controllable subspace of the car (the road warp left out, as
:func:`~quarter_car_sim.full_car.lqr.full_car_lqr_design` does) plus the 20 filter states
(stable, driven through the accelerations). The law (:class:`FullCarClippedOptimalWk`) runs
the filters made digital with the bilinear transform at the control period on the body
accelerations the full-car state carries (``state.acc[:3]``, computed by the plant from the
forces acting at that sample), feeds back the analog filter state the design assumed, and the
demands are clipped per damper (dissipative) by :class:`~quarter_car_sim.full_car.control.
ForceLaw`.
"""
import math

import numpy as np
from scipy.linalg import block_diag, null_space

from quarter_car_sim.full_car.control import ForceLaw
from quarter_car_sim.full_car.lqr import checked_weights, relative_model

DEFAULT_FULL_LQR_WK_WEIGHTS = {'q_wk': 1.0, 'q_we_pitch': 0.16, 'q_we_roll': 0.3969,
                               'q_heave': 0.0, 'q_pitch': 0.0, 'q_roll': 0.0,
                               'q_travel': 300.0, 'q_tyre': 1.0e3, 'r_force': 3.0e-7}
"""Default weights of :func:`full_car_lqr_wk_design` (SI).

Those of :data:`quarter_car_sim.full_car.lqr.DEFAULT_FULL_LQR_WEIGHTS` moved from the plain to
the ISO-weighted accelerations, plus the quarter car's ``clipped-optimal-wk`` travel weight:
bench/bench_full_car.py on its training roads (ISO 8608 C, 20 m/s, 20 s, seeds 11-13, Spencer
plants) gives median a_v 0.571 m/s^2 (q_travel 0: 0.572, r_force 1e-7: 0.575, plain
accelerations weighted 0.1 x: 0.574); docs/full-car.md has the bench roads."""


def _filters(weighting):
    """Return the three (A, B, C, D) filters: seat vertical, pitch, roll."""
    if weighting == 'none':
        unit = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1)))
        return [unit] * 3
    if weighting != 'iso':
        raise ValueError(f"`weighting` must be 'iso' or 'none', got {weighting!r}")
    from quarter_car_sim.controllers.optimal import weighting_state_space, wk_state_space
    from quarter_car_sim.ride_metrics import WE_CONSTANTS
    out = []
    for sys in (wk_state_space(), weighting_state_space(WE_CONSTANTS)):
        out.append(tuple(np.atleast_2d(np.asarray(m, dtype=float))
                         for m in (sys.A, sys.B, sys.C, sys.D)))
    return [out[0], out[1], out[1]]


def weighting_filter(weighting='iso'):
    """
    Return the block-diagonal analog weighting of the three body accelerations.

    Parameters
    ----------
    weighting : {'iso', 'none'}
        ISO 2631-1 (Wk vertical, We pitch and roll) or static unit gains.

    Returns
    -------
    Aw, Bw, Cw, Dw : ndarray
        ``w' = Aw w + Bw a``, ``a_w = Cw w + Dw a`` with ``a = [a_seat, thetadd, phidd]``.

    """
    fs = _filters(weighting)
    Aw = block_diag(*[f[0] for f in fs]) if fs[0][0].size else np.zeros((0, 0))
    nw = Aw.shape[0]
    Bw, Cw, Dw = np.zeros((nw, 3)), np.zeros((3, nw)), np.zeros((3, 3))
    i = 0
    for j, (a, b, c, d) in enumerate(fs):
        n = a.shape[0]
        Bw[i:i + n, j] = b.ravel()
        Cw[j, i:i + n] = c.ravel()
        Dw[j, j] = d.item()
        i += n
    return Aw, Bw, Cw, Dw


class FullCarLqrWkDesign:
    """
    Result of :func:`full_car_lqr_wk_design`.

    Attributes
    ----------
    gain : ndarray (4, 15 + n_w)
        ``F = -gain @ [s, d, v_b, v_u, w]`` (``w`` the analog filter states).
    poles : ndarray (14 + n_w,)
        Closed-loop poles of the reduced augmented model.
    filter : tuple of ndarray
        ``(Aw, Bw, Cw, Dw)`` of :func:`weighting_filter`.
    seat : (float, float)
        Seat point of the vertical acceleration [m].
    weights : dict
        The weights used.
    model : dict or None
        The design problem on the reduced augmented state ``X = [V' x, w]``: ``A``, ``B``,
        ``Q``, ``R``, ``N`` (``control.lqr``'s), ``V`` (the warp-free basis, (15, 14)), ``Cz``,
        ``Dz``, ``W`` (cost outputs and weights) and ``Ca``, ``Cy`` (seat and body
        accelerations on the full state), for the preview design
        (:mod:`quarter_car_sim.full_car.preview`).

    """

    def __init__(self, gain, poles, filt, seat, weights, model=None):
        self.gain, self.poles, self.filter = gain, poles, filt
        self.seat, self.weights, self.model = seat, weights, model


def full_car_lqr_wk_design(params, *, weighting='iso', seat=(0.0, 0.0), **weights):
    """
    Frequency-weighted LQR of the fully active road-relative full car.

    Parameters
    ----------
    params : FullCarParams
        Car.
    weighting : {'iso', 'none'}
        ISO 2631-1 filters, or static unit gains (the design is then
        :func:`~quarter_car_sim.full_car.lqr.full_car_lqr_design` with ``q_heave + q_wk`` ...).
    seat : (float, float)
        Seat ``(x, y)`` [m] from the CG of the vertical acceleration (as the metric's).
    **weights
        Overrides of :data:`DEFAULT_FULL_LQR_WK_WEIGHTS`.

    Returns
    -------
    FullCarLqrWkDesign

    """
    import control
    w = checked_weights(DEFAULT_FULL_LQR_WK_WEIGHTS, weights)
    sx, sy = (float(v) for v in seat)
    A, B, Cy, Dy, n = relative_model(params)
    seat_map = np.array([[1.0, -sx, sy], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    Ca, Da = seat_map @ Cy, seat_map @ Dy               # [a_seat, thetadd, phidd]
    Aw, Bw, Cw, Dw = weighting_filter(weighting)
    nw = Aw.shape[0]
    c = np.zeros(15)
    c[0:4], c[4:8] = n, n
    V = null_space(c[None, :])                           # (15, 14), orthonormal
    nx = 14 + nw
    Ag = np.zeros((nx, nx))
    Ag[:14, :14] = V.T @ A @ V
    Ag[14:, :14] = Bw @ Ca @ V
    Ag[14:, 14:] = Aw
    Bg = np.vstack([V.T @ B, Bw @ Da])
    # cost outputs z = Cz X + Dz F: weighted and plain accelerations, travels, tyres, forces
    Cz = np.zeros((18, nx))
    Cz[0:3, :14], Cz[0:3, 14:] = Dw @ Ca @ V, Cw
    Cz[3:6, :14] = Cy @ V
    Cz[6:14, :14] = V[0:8]
    Dz = np.vstack([Dw @ Da, Dy, np.zeros((8, 4)), np.eye(4)])
    W = np.diag([w['q_wk'], w['q_we_pitch'], w['q_we_roll'], w['q_heave'], w['q_pitch'],
                 w['q_roll']] + [w['q_travel']] * 4 + [w['q_tyre']] * 4 + [w['r_force']] * 4)
    Q = Cz.T @ W @ Cz
    R = Dz.T @ W @ Dz
    N = Cz.T @ W @ Dz
    Q, R = 0.5 * (Q + Q.T), 0.5 * (R + R.T)
    K_g, _, E = control.lqr(Ag, Bg, Q, R, N)
    K_g = np.asarray(K_g)
    gain = np.hstack([K_g[:, :14] @ V.T, K_g[:, 14:]])
    model = {'A': Ag, 'B': Bg, 'Q': Q, 'R': R, 'N': N, 'V': V, 'Cz': Cz, 'Dz': Dz, 'W': W,
             'Ca': Ca, 'Cy': Cy}
    return FullCarLqrWkDesign(gain, np.asarray(E), (Aw, Bw, Cw, Dw), (sx, sy), w, model)


class FullCarClippedOptimalWk(ForceLaw):
    """
    Frequency-weighted full-car clipped-optimal law (:func:`full_car_lqr_wk_design`).

    ``F = -K [s, d, v_b, v_u, w]`` with ``w`` the analog state of the weighting filters run
    inside the law on the state's body accelerations: the filters are made digital with the
    bilinear transform at ``dt`` (so their outputs are the metric's digital Wk / We on the same
    samples), and the analog state at sample k is ``(I - Aw dt/2)^-1 (s_k + Bw a_k dt/2)`` with
    ``s_k`` the digital state. Each corner's force is then clipped to its damper (dissipative).

    Stateful: :meth:`reset` clears the filters; a state whose time does not advance does not
    step them again; non-finite accelerations are counted (``rejected_samples``) and held.

    Parameters
    ----------
    design : FullCarLqrWkDesign
        Design.
    dt : float
        Control period [s] (the law is called once per period).
    name : str
        Law name.

    """

    state_fields = ('z_u', 'z_r')

    def __init__(self, design, *, dt=1e-3, name='full-car-clipped-optimal-wk'):
        from scipy.signal import cont2discrete
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'`dt` must be > 0, got {dt}')
        self.design, self.dt, self.name = design, dt, name
        gain = np.asarray(design.gain, dtype=float)
        aw, bw, cw, dw = design.filter
        nw = aw.shape[0]
        if gain.shape != (4, 15 + nw) or not np.all(np.isfinite(gain)):
            raise ValueError(f'`design.gain` must be 4 x {15 + nw} finite numbers')
        self.k_car = gain[:, :15]
        sx, sy = design.seat
        self._seat = np.array([[1.0, -sx, sy], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        if nw:
            ad, bd, cd, dd, _ = cont2discrete((aw, bw, cw, dw), dt, method='bilinear')
            m = np.linalg.inv(np.eye(nw) - aw * dt / 2.0)
            self._ad, self._bd, self._cd, self._dd = ad, bd, cd, dd
            self._g_s = gain[:, 15:] @ m                 # on the digital state
            self._g_a = self._g_s @ bw * (dt / 2.0)      # on the present accelerations
        else:
            self._ad, self._bd = np.zeros((0, 0)), np.zeros((0, 3))
            self._cd, self._dd = np.zeros((3, 0)), dw
            self._g_s, self._g_a = np.zeros((4, 0)), np.zeros((4, 3))
        super().__init__()

    @classmethod
    def from_car(cls, params, *, dt=1e-3, name='full-car-clipped-optimal-wk', **weights):
        """Design on ``params`` (weights: :data:`DEFAULT_FULL_LQR_WK_WEIGHTS` overrides)."""
        return cls(full_car_lqr_wk_design(params, **weights), dt=dt, name=name)

    def reset(self):
        """Clear the filters and the last forces."""
        super().reset()
        self._s = np.zeros(self._ad.shape[0])
        self._t = -math.inf
        self._a = np.zeros(3)
        self._fw = np.zeros(4)
        self.rejected_samples = 0

    @property
    def weighted(self):
        """Weighted ``[a_wz, a_w,pitch, a_w,roll]`` of the latest state (the filters' output)."""
        return self._cd @ self._s + self._dd @ self._a

    def step_filters(self, state):
        """
        Step the filters to ``state`` (once per time) and return their feedback force [N].

        A state whose body accelerations are not finite is counted in ``rejected_samples``
        and the filters hold the last finite accelerations (so one bad sample cannot poison
        them).
        """
        if state.t != self._t:
            if self._t != -math.inf:
                self._s = self._ad @ self._s + self._bd @ self._a
            self._t = state.t
            a = self._seat @ np.asarray(state.acc[:3], dtype=float)
            if np.all(np.isfinite(a)):
                self._a = a
            else:
                self.rejected_samples += 1
            self._fw = self._g_s @ self._s + self._g_a @ self._a
        return self._fw

    def desired_forces(self, state):
        """Return the weighted LQR forces ``-K [s, d, v_b, v_u, w]`` [N] (steps the filters)."""
        fw = self.step_filters(state)
        x = np.concatenate([state.travel, state.q[3:] - state.z_r, state.v])
        return -self.k_car @ x - fw
