"""LQR-designed laws: active LQR, clipped-optimal and the Wk frequency-shaped clipped-optimal."""
import math

import numpy as np

from semi_active_control.laws.base import car_state_feedback, clip_to_damper, Controller
from semi_active_control.car.quarter_car import QuarterCarParams
from semi_active_control.car.quarter_car_linear import lqr_design
from semi_active_control.iso2631 import wk_state_space


class LqrActive(Controller):
    """
    Fully active state feedback ``F = -K [travel, v_s, z_u - z_r, v_u]`` [N on body].

    Parameters
    ----------
    gain : array_like with shape (4,)
        LQR gain for the state ``[z_s - z_u, v_s, z_u - z_r, v_u]``
        (see :func:`semi_active_control.car.quarter_car_linear.lqr_design`).

    """

    kind = 'active'
    #: State fields beyond the common ones (tyre deflection ``z_u - z_r``): a controller core
    #: refuses a state where they are not finite
    #: (:mod:`semi_active_control.runtime.controller_core`).
    state_fields = ('z_u', 'z_r')

    def __init__(self, gain, name='lqr-active'):
        k = np.asarray(gain, dtype=float).ravel()
        if k.size != 4 or not np.all(np.isfinite(k)):
            raise ValueError('`gain` must be 4 finite numbers')
        self.k = [float(v) for v in k]
        self.name = name

    def demand(self, state):
        """Active force on the body [N]."""
        return car_state_feedback(self.k, state)


DEFAULT_CO_WEIGHTS = {'q_accel': 1.0, 'q_travel': 0.0, 'q_tyre': 1.0e3, 'r_force': 1.0e-5}
"""Default LQR weights of the clipped-optimal law (see :func:`clipped_optimal_gain`).

SI units. Comfort first (unit weight on a_s), no travel weight (the spring holds it), a light
tyre-deflection weight and a force weight that keeps the demand near the damper's soft end.
bench/bench_laws.py (Spencer plant, ISO 8608 C, 20 m/s, 60 s, seeds 1-3): Wk RMS / tyre load
against 0 A passive -4.6 % / -2.8 % (q_tyre 1e4, r_force 1e-6: -1.0 % / -9.7 %; q_tyre 1e5:
+25 % / -28 %); see docs/control-laws.md."""


def clipped_optimal_gain(params=None, **weights):
    """
    LQR gain of the clipped-optimal law: active force on the linear quarter car.

    Designed with :func:`semi_active_control.car.quarter_car_linear.lqr_design` (``control.lqr``)
    on the car without damper: cost ``q_accel a_s^2 + q_travel travel^2 + q_tyre tyre_def^2 +
    r_force F^2`` (SI units).

    Parameters
    ----------
    params : QuarterCarParams, optional
        Car parameters (default car).
    **weights
        Overrides of :data:`DEFAULT_CO_WEIGHTS`.

    Returns
    -------
    ndarray with shape (4,)
        Gain for ``F = -K [travel, v_s, z_u - z_r, v_u]``.

    """
    w = _lqr_weights(DEFAULT_CO_WEIGHTS, weights)
    return lqr_design(params or QuarterCarParams(), **w).gain


def _lqr_weights(defaults, overrides):
    """Return ``defaults`` updated by ``overrides``; ValueError on a weight not in defaults."""
    unknown = sorted(set(overrides) - set(defaults))
    if unknown:
        raise ValueError(f'unknown LQR weight(s): {", ".join(unknown)}')
    return {**defaults, **overrides}


class ClippedOptimal(LqrActive):
    """
    Clipped-optimal semi-active control (Dyke et al. 1996): LQR force clipped to the damper.

    The desired force is the fully active LQR force ``-K [travel, v_s, z_u - z_r, v_u]``; the
    demand is that force clipped to what the damper can give: to the force range of the
    damper model at the present travel and velocity over the current range
    (``force_range``), then to the dissipative half-line (``F v_rel <= 0``, 0 at
    ``v_rel = 0``). Without ``force_range`` only the dissipative clipping is done here and the
    inverse model's saturation (nearest reachable force) does the range clipping, which gives
    the same current for a force monotone in the current.

    Parameters
    ----------
    gain : array_like with shape (4,)
        LQR gain (:func:`clipped_optimal_gain`).
    force_range : callable, optional
        ``force_range(travel, v_rel) -> (lo, hi)``: reachable damper forces on the body [N]
        (e.g. :meth:`mr_damper_model.models.inverse.KwokCurrentInverse.body_force_range`).
    name : str
        Controller name.

    """

    kind = 'semi-active'

    def __init__(self, gain, force_range=None, name='clipped-optimal'):
        super().__init__(gain, name=name)
        self.force_range = force_range

    def desired(self, state):
        """Unclipped LQR force on the body [N]."""
        return LqrActive.demand(self, state)

    def demand(self, state):
        """Desired damper force on the body [N], clipped to the damper (dissipative)."""
        return clip_to_damper(self.desired(state), state, self.force_range)


DEFAULT_COWK_WEIGHTS = {'q_wk': 1.0, 'q_accel': 0.1, 'q_travel': 300.0, 'q_tyre': 1.0e3,
                        'r_force': 3.0e-6}
"""Default weights of the frequency-shaped clipped-optimal law (see :func:`wk_lqr_design`).

SI units: ``q_wk`` on the ISO 2631-1 Wk-weighted body acceleration [m/s^2], ``q_accel`` on the
plain one, ``q_travel`` and ``q_tyre`` on travel and tyre deflection [m], ``r_force`` on the
force [N]. Tuned by simulation on training roads (ISO 8608 C, 20 m/s, seeds 11-13, Spencer
plant), not on the bench roads; bench/bench_laws.py (seeds 1-3, 60 s): Wk RMS 0.931 m/s^2,
-6.0 % against 0 A passive (clipped-optimal -4.6 %), tyre load -3.6 %, 2.0 % above the offline
bound; see docs/control-laws.md."""


def wk_lqr_design(params=None, *, weighting='wk', **weights):
    """
    Frequency-shaped LQR: active force on the linear quarter car, cost on Wk-weighted a_s.

    :func:`semi_active_control.car.quarter_car_linear.lqr_design` (the one LQR cost) with the car
    (state ``x = [travel, v_s, z_u - z_r, v_u]``, force ``F`` on the body) augmented with the
    states ``w`` of the weighting filter driven by the body acceleration; it minimises ::

        integral( q_wk a_wk^2 + q_accel a_s^2 + q_travel travel^2 + q_tyre tyre_def^2
                  + r_force F^2 ) dt

    Parameters
    ----------
    params : QuarterCarParams, optional
        Car parameters (default car).
    weighting : {'wk', 'none'} or control.StateSpace
        Filter on a_s: ISO 2631-1 Wk (:func:`wk_state_space`), none (a static unit gain: the
        design is then :func:`clipped_optimal_gain` with ``q_accel + q_wk``), or any SISO
        stable state space.
    **weights
        Overrides of :data:`DEFAULT_COWK_WEIGHTS`.

    Returns
    -------
    semi_active_control.car.quarter_car_linear.LqrDesign
        With ``filter`` the weighting (gain ``4 + n_w`` long).

    """
    import control
    w = _lqr_weights(DEFAULT_COWK_WEIGHTS, weights)
    for k, v in w.items():
        if not (math.isfinite(v) and v >= 0.0):
            raise ValueError(f'`{k}` must be finite and >= 0, got {v}')
    if not w['r_force'] > 0.0:
        raise ValueError('`r_force` must be > 0')
    if isinstance(weighting, str):
        if weighting == 'wk':
            filt = wk_state_space()
        elif weighting == 'none':
            filt = control.ss([], [], [], [[1.0]])
        else:
            raise ValueError("`weighting` must be 'wk', 'none' or a StateSpace, "
                             f'got {weighting!r}')
    else:
        filt = weighting
    return lqr_design(params or QuarterCarParams(), weighting=filt, **w)


class ClippedOptimalWk(Controller):
    """
    Frequency-shaped clipped-optimal law: the Wk-weighted LQR force clipped to the damper.

    The desired force is ``-K [travel, v_s, z_u - z_r, v_u, w]`` of :func:`wk_lqr_design`,
    where ``w`` are the states of the Wk filter run inside the law on the measured body
    acceleration ``a_s``; the demand is clipped as :class:`ClippedOptimal` does (damper range,
    then dissipative). The filter is the design's analog filter made digital with the bilinear
    transform at the control period ``dt``: its output is the metric's digital Wk filter
    (:func:`quarter_car_sim.metrics.quarter_car.wk_sos`) on the same samples. The analog filter
    state at sample k is ``(I - A_w dt/2)^-1 (s_k + B_w a_s,k dt/2)`` with ``s_k`` the digital
    state (the bilinear realisation), so the state fed back is the one the design assumed.

    Stateful: :meth:`reset` clears the filter; a state whose time ``t`` does not advance does
    not step the filter again.

    Parameters
    ----------
    design : semi_active_control.car.quarter_car_linear.LqrDesign
        Design with its weighting filter (:func:`wk_lqr_design`).
    force_range : callable, optional
        ``force_range(travel, v_rel) -> (lo, hi)`` [N] (see :class:`ClippedOptimal`).
    dt : float
        Control period [s] (the law is called once per period).
    name : str
        Controller name.

    """

    state_fields = LqrActive.state_fields

    def __init__(self, design, force_range=None, *, dt=1e-3, name='clipped-optimal-wk'):
        from scipy.signal import cont2discrete
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'`dt` must be > 0, got {dt}')
        k = np.asarray(design.gain, dtype=float).ravel()
        f = design.filter
        aw, bw = np.asarray(f.A, float), np.asarray(f.B, float).reshape(-1, 1)
        cw, dw = np.asarray(f.C, float).reshape(1, -1), np.asarray(f.D, float).reshape(1, 1)
        nw = aw.shape[0]
        if k.size != 4 + nw or not np.all(np.isfinite(k)):
            raise ValueError(f'`design.gain` must be {4 + nw} finite numbers')
        self.design, self.force_range, self.dt, self.name = design, force_range, dt, name
        self.k_car = [float(v) for v in k[:4]]
        if nw:
            ad, bd, cd, dd, _ = cont2discrete((aw, bw, cw, dw), dt, method='bilinear')
            m = np.linalg.inv(np.eye(nw) - aw * dt / 2.0)
            kw = k[4:] @ m
            self._ad, self._bd = ad, bd.ravel()
            self._cd, self._dd = cd.ravel(), float(dd[0, 0])
            self._g_s = kw                                   # on the digital state
            self._g_a = float(kw @ bw.ravel()) * dt / 2.0    # on the present a_s
        else:
            self._ad = np.zeros((0, 0))
            self._bd = self._cd = self._g_s = np.zeros(0)
            self._dd, self._g_a = float(dw[0, 0]), 0.0
        self.reset()

    def reset(self):
        """Clear the filter state."""
        self._s = np.zeros(self._ad.shape[0])
        self._t = -math.inf
        self._a_prev = 0.0
        self._fw = 0.0

    @property
    def a_wk(self):
        """Wk-weighted body acceleration of the latest state [m/s^2] (the filter's output)."""
        return float(self._cd @ self._s) + self._dd * self._a_prev

    def desired(self, state):
        """Unclipped frequency-shaped LQR force on the body [N] (steps the filter)."""
        a = state.a_s
        if state.t != self._t:
            if self._t != -math.inf:
                self._s = self._ad @ self._s + self._bd * self._a_prev
            self._t = state.t
            self._a_prev = a
            self._fw = float(self._g_s @ self._s) + self._g_a * a
        return car_state_feedback(self.k_car, state) - self._fw

    def demand(self, state):
        """Desired damper force on the body [N], clipped to the damper (dissipative)."""
        return clip_to_damper(self.desired(state), state, self.force_range)
