"""
Suspension controllers and the force -> coil current path.

A controller has ``name``, ``kind`` and ``demand(state) -> float``:

- ``kind == 'current'`` (:class:`Passive`): ``demand`` returns a coil current [A];
- ``kind == 'semi-active'`` (skyhook, on-off skyhook, groundhook, hybrid, ADD, SH-ADD,
  clipped-optimal, frequency-shaped clipped-optimal): ``demand``
  returns the desired damper force **on the body** [N], positive up, always dissipative
  (``demand * v_rel <= 0``); it goes through an inverse damper model
  (:class:`mr_damper_model.models.inverse.KwokCurrentInverse` with ``sign_convention='body'``) to a
  current saturated to the coil's range;
- ``kind == 'active'`` (``skyhook-ideal``, ``lqr-active``): ``demand`` is a force on the body
  applied directly (``QuarterCar.step_force``), no damper and no current limits.

Controllers only read the measured :class:`~quarter_car_sim.dynamics.CarState` (and, for the
inverse, identified parameters); never the plant's true parameters.

Skyhook-family laws use absolute body / wheel velocities (``v_s``, ``v_u``) and the suspension
velocity ``v_rel = v_s - v_u``:

- skyhook (continuous, clipped, Karnopp 1974): ``F = -(c_sky v_s + c_p v_rel)`` when that is
  dissipative, else 0 (the damper's minimum);
- on-off skyhook: ``F = -c_on v_rel`` when ``v_s v_rel > 0`` else ``-c_off v_rel``;
- groundhook (Valasek 1997): ``F = +c_gnd v_u`` when ``v_u v_rel < 0``, else 0;
- hybrid (Ahmadian): ``F = -c (alpha s_sky + (1 - alpha) s_gnd)`` with ``s_sky = v_s`` when
  ``v_s v_rel > 0`` (else 0) and ``s_gnd = -v_u`` when ``v_u v_rel < 0`` (else 0);
- ADD (Savaresi 2005, acceleration-driven damper): ``F = -c_max v_rel`` when
  ``a_s v_rel > 0``, else ``-c_min v_rel``;
- SH-ADD (Savaresi and Spelta 2007, mixed skyhook / ADD): per sample, the skyhook choice
  (``c_max`` when ``v_s v_rel > 0``) if ``v_s^2 - alpha^2 a_s^2 >= 0`` (slow body motion), else
  the ADD choice (``c_max`` when ``a_s v_rel > 0``); ``F = -c v_rel`` with ``c`` the choice;
- clipped-optimal (Dyke et al. 1996): the fully active LQR force ``-K x`` clipped to what the
  damper can give: dissipative, and within ``[F(i_min), F(i_max)]`` of the identified model at
  the present travel and velocity;
- frequency-shaped clipped-optimal (``clipped-optimal-wk``): the same with an LQR whose cost
  weights the ISO 2631-1 Wk-weighted body acceleration (the comfort metric); the law runs the
  Wk filter on the measured body acceleration and feeds its states back.

See docs/control-laws.md for the laws, their gains and the offline semi-active bound
(:mod:`quarter_car_sim.bound`).
"""
import math

import numpy as np

DEFAULT_C_SKY = 2000.0
"""Default skyhook gain [N s/m].

Tuned with bench/bench_ride.py (ISO 8608 C, 20 m/s, 60 s, 3 seeds, thesis-like kwok-current
damper): Wk RMS of the MR skyhook 0.902 / 0.865 / 0.872 m/s^2 for c_sky = 1000 / 2000 / 3000
(c_p = 0), 0.869 with (2000, 150); the ideal actuator needs the passive part (c_p = 0 leaves
the wheel undamped whenever the sky damper is off: 1.19 m/s^2) and gives 0.782 at (2000, 150),
0.758 at (3000, 150). (2000, 150) is within 0.5 % of the MR skyhook's best and keeps the
ideal reference near its best."""

DEFAULT_C_P = 150.0
"""Default passive part of the skyhook law [N s/m] (see :data:`DEFAULT_C_SKY`)."""


class Controller:
    """Base class: ``name``, ``kind`` and ``demand(state)``; ``reset()`` clears memory."""

    name = 'controller'
    kind = 'semi-active'

    def reset(self):
        """Clear internal state (none by default)."""

    def demand(self, state):  # pragma: no cover - abstract
        """Return the demand for this state (force [N] or current [A], see ``kind``)."""
        raise NotImplementedError

    def __repr__(self):
        return f'{type(self).__name__}(name={self.name!r})'


class Passive(Controller):
    """
    Constant coil current (a passive damper at one setting).

    Parameters
    ----------
    current_a : float
        Coil current [A].

    """

    kind = 'current'

    def __init__(self, current_a=0.0):
        self.current_a = float(current_a)
        if not math.isfinite(self.current_a):
            raise ValueError('`current_a` must be finite')
        txt = f'{self.current_a:.2f}'.rstrip('0')
        self.name = f'passive@{txt}0A' if txt.endswith('.') else f'passive@{txt}A'

    def demand(self, state):
        """Return the constant current [A]."""
        return self.current_a


class Skyhook(Controller):
    """
    Continuous clipped skyhook with a passive part (Karnopp).

    ``F = -(c_sky v_s + c_p v_rel)`` when that force is dissipative (``F v_rel < 0``), else 0
    [N on body]. With ``c_p = 0`` this is the classic clipped skyhook (``-c_sky v_s`` when
    ``v_s v_rel > 0``); the passive part keeps some wheel damping when the sky damper is off,
    which an ideal actuator (:class:`SkyhookIdeal`) needs (a real MR damper has its 0 A force).

    Parameters
    ----------
    c_sky : float
        Skyhook damping [N s/m].
    c_p : float
        Passive damping [N s/m].
    name : str
        Controller name.

    """

    def __init__(self, c_sky=DEFAULT_C_SKY, c_p=DEFAULT_C_P, name='skyhook'):
        self.c_sky, self.c_p = float(c_sky), float(c_p)
        self.name = name

    def demand(self, state):
        """Desired damper force on the body [N]."""
        vr = state.v_rel
        f = -self.c_sky * state.v_s - self.c_p * vr
        if f * vr < 0.0:
            return f
        return 0.0


class SkyhookOnOff(Controller):
    """
    On-off skyhook: ``-c_on v_rel`` if ``v_s v_rel > 0`` else ``-c_off v_rel`` [N on body].

    Parameters
    ----------
    c_on, c_off : float
        High and low damping [N s/m].

    """

    def __init__(self, c_on=4000.0, c_off=0.0, name='skyhook-onoff'):
        self.c_on, self.c_off, self.name = float(c_on), float(c_off), name

    def demand(self, state):
        """Desired damper force on the body [N]."""
        vr = state.v_rel
        if state.v_s * vr > 0.0:
            return -self.c_on * vr
        return -self.c_off * vr


class Groundhook(Controller):
    """
    Groundhook: ``F = c_gnd v_u`` if ``v_u v_rel < 0`` else 0 [N on body].

    Parameters
    ----------
    c_gnd : float
        Groundhook damping [N s/m].

    """

    def __init__(self, c_gnd=3000.0, name='groundhook'):
        self.c_gnd, self.name = float(c_gnd), name

    def demand(self, state):
        """Desired damper force on the body [N]."""
        vu = state.v_u
        if vu * state.v_rel < 0.0:
            return self.c_gnd * vu
        return 0.0


class Hybrid(Controller):
    """
    Hybrid skyhook-groundhook: ``F = -c (alpha s_sky + (1 - alpha) s_gnd)`` [N on body].

    Parameters
    ----------
    c : float
        Gain [N s/m].
    alpha : float
        Weight of skyhook in [0, 1] (1 = skyhook, 0 = groundhook).

    """

    def __init__(self, c=DEFAULT_C_SKY, alpha=0.7, name='hybrid'):
        if not 0.0 <= alpha <= 1.0:
            raise ValueError(f'`alpha` must be in [0, 1], got {alpha}')
        self.c, self.alpha, self.name = float(c), float(alpha), name

    def demand(self, state):
        """Desired damper force on the body [N]."""
        vs, vu, vr = state.v_s, state.v_u, state.v_rel
        s_sky = vs if vs * vr > 0.0 else 0.0
        s_gnd = -vu if vu * vr < 0.0 else 0.0
        return -self.c * (self.alpha * s_sky + (1.0 - self.alpha) * s_gnd)


class ADD(Controller):
    """
    Acceleration-driven damper: ``-c_max v_rel`` if ``a_s v_rel > 0`` else ``-c_min v_rel``.

    Parameters
    ----------
    c_max, c_min : float
        High and low damping [N s/m].

    """

    def __init__(self, c_max=4000.0, c_min=0.0, name='add'):
        self.c_max, self.c_min, self.name = float(c_max), float(c_min), name

    def demand(self, state):
        """Desired damper force on the body [N]."""
        vr = state.v_rel
        if state.a_s * vr > 0.0:
            return -self.c_max * vr
        return -self.c_min * vr


DEFAULT_SHADD_F_SWITCH_HZ = 1.0
"""Default SH-ADD switching frequency ``1 / (2 pi alpha)`` [Hz] (see :class:`ShAdd`).

bench/bench_laws.py (Spencer plant, ISO 8608 C, 20 m/s, 60 s, seeds 1-3, c_max 4000 N s/m):
Wk RMS against 0 A passive -3.0 / 0.0 / +6.6 % at 1 / 2 / 4 Hz (tyre load -6.2 / -8.4 /
-11.9 %); 0.7 Hz: -3.3 % (-5.4 %). 1 Hz is the comfort choice."""


class ShAdd(Controller):
    """
    Mixed skyhook / acceleration-driven damper, SH-ADD (Savaresi and Spelta 2007).

    Each sample picks skyhook or ADD by the sign of ``v_s^2 - alpha^2 a_s^2``:

    - ``>= 0`` (the body moves slowly, below about ``1 / (2 pi alpha)`` Hz): skyhook choice,
      ``c_max`` when ``v_s v_rel > 0`` else ``c_min``;
    - ``< 0`` (fast body motion): ADD choice, ``c_max`` when ``a_s v_rel > 0`` else ``c_min``;

    and demands ``F = -c v_rel`` [N on body] (dissipative for ``c >= 0``).

    Parameters
    ----------
    c_max, c_min : float
        High and low damping [N s/m], ``c_max >= c_min >= 0``.
    f_switch_hz : float
        Switching frequency [Hz]: ``alpha = 1 / (2 pi f_switch_hz)`` [s] (for a sine of
        frequency f, ``|v_s| >= alpha |a_s|`` exactly when ``f <= f_switch_hz``).
    name : str
        Controller name.

    """

    def __init__(self, c_max=4000.0, c_min=0.0, f_switch_hz=DEFAULT_SHADD_F_SWITCH_HZ,
                 name='sh-add'):
        self.c_max, self.c_min = float(c_max), float(c_min)
        if not (math.isfinite(self.c_max) and 0.0 <= self.c_min <= self.c_max):
            raise ValueError(f'need 0 <= `c_min` <= `c_max`, got {c_min}, {c_max}')
        f_sw = float(f_switch_hz)
        if not (math.isfinite(f_sw) and f_sw > 0.0):
            raise ValueError(f'`f_switch_hz` must be > 0, got {f_switch_hz}')
        self.f_switch_hz = f_sw
        self.alpha = 1.0 / (2.0 * math.pi * f_sw)
        self.name = name

    def choice(self, state):
        """Return ``'skyhook'`` or ``'add'``: the law SH-ADD follows in this state."""
        vs, a = state.v_s, self.alpha * state.a_s
        return 'skyhook' if vs * vs - a * a >= 0.0 else 'add'

    def demand(self, state):
        """Desired damper force on the body [N]."""
        vr = state.v_rel
        if self.choice(state) == 'skyhook':
            high = state.v_s * vr > 0.0
        else:
            high = state.a_s * vr > 0.0
        return -(self.c_max if high else self.c_min) * vr


class SkyhookIdeal(Skyhook):
    """
    Skyhook with a perfect semi-active actuator (force applied directly, no current limits).

    The same law as :class:`Skyhook`; its demand is already clipped to what a passive device can
    dissipate (zero when ``-c_sky v_s`` has the wrong sign for ``v_rel``).
    """

    kind = 'active'

    def __init__(self, c_sky=DEFAULT_C_SKY, c_p=DEFAULT_C_P, name='skyhook-ideal'):
        super().__init__(c_sky, c_p, name)


class LqrActive(Controller):
    """
    Fully active state feedback ``F = -K [travel, v_s, z_u - z_r, v_u]`` [N on body].

    Parameters
    ----------
    gain : array_like with shape (4,)
        LQR gain for the state ``[z_s - z_u, v_s, z_u - z_r, v_u]``
        (see :func:`quarter_car_sim.linear_analysis.lqr_design`).

    """

    kind = 'active'
    #: State fields beyond the common ones (tyre deflection ``z_u - z_r``): a controller core
    #: refuses a state where they are not finite (:mod:`quarter_car_sim.controller_core`).
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


def car_state_feedback(k, state):
    """Return ``-k @ [travel, v_s, z_u - z_r, v_u]`` [N]: the car part of an LQR law."""
    return -(k[0] * state.travel + k[1] * state.v_s + k[2] * (state.z_u - state.z_r)
             + k[3] * state.v_u)


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

    Designed with :func:`quarter_car_sim.linear_analysis.lqr_design` (``control.lqr``) on the
    car without damper: cost ``q_accel a_s^2 + q_travel travel^2 + q_tyre tyre_def^2 +
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
    from quarter_car_sim.linear_analysis import lqr_design
    from quarter_car_sim.params import QuarterCarParams
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


def clip_to_damper(force, state, force_range=None):
    """
    Clip a desired body force [N] to what a semi-active damper can give in this state.

    First to ``force_range(travel, v_rel) -> (lo, hi)`` when given, then to the dissipative
    half-line (``F v_rel <= 0``, 0 at ``v_rel = 0``).
    """
    f = force
    vr = state.v_rel
    if force_range is not None:
        lo, hi = force_range(state.travel, vr)
        f = min(max(f, lo), hi)
    if vr > 0.0:
        return min(f, 0.0)
    if vr < 0.0:
        return max(f, 0.0)
    return 0.0


DEFAULT_COWK_WEIGHTS = {'q_wk': 1.0, 'q_accel': 0.1, 'q_travel': 300.0, 'q_tyre': 1.0e3,
                        'r_force': 3.0e-6}
"""Default weights of the frequency-shaped clipped-optimal law (see :func:`wk_lqr_design`).

SI units: ``q_wk`` on the ISO 2631-1 Wk-weighted body acceleration [m/s^2], ``q_accel`` on the
plain one, ``q_travel`` and ``q_tyre`` on travel and tyre deflection [m], ``r_force`` on the
force [N]. Tuned by simulation on training roads (ISO 8608 C, 20 m/s, seeds 11-13, Spencer
plant), not on the bench roads; bench/bench_laws.py (seeds 1-3, 60 s): Wk RMS 0.931 m/s^2,
-6.0 % against 0 A passive (clipped-optimal -4.6 %), tyre load -3.6 %, 2.0 % above the offline
bound; see docs/control-laws.md."""


def wk_state_space():
    """
    ISO 2631-1 Wk weighting as an 8-state ``control.StateSpace`` (analog, SI).

    The series connection of the four sections of
    :func:`quarter_car_sim.ride_metrics.wk_sections` (each a 2-state block, so the realisation
    stays well scaled); its transfer function is :func:`~quarter_car_sim.ride_metrics.wk_analog`.
    Input body acceleration [m/s^2], output Wk-weighted acceleration [m/s^2].
    """
    import control
    from quarter_car_sim.ride_metrics import wk_sections
    sys = None
    for num, den in wk_sections():
        sec = control.ss(control.tf(num, den))
        sys = sec if sys is None else control.series(sys, sec)
    return sys


def wk_lqr_design(params=None, *, weighting='wk', **weights):
    """
    Frequency-shaped LQR: active force on the linear quarter car, cost on Wk-weighted a_s.

    :func:`quarter_car_sim.linear_analysis.lqr_design` (the one LQR cost) with the car
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
    quarter_car_sim.linear_analysis.LqrDesign
        With ``filter`` the weighting (gain ``4 + n_w`` long).

    """
    import control
    from quarter_car_sim.linear_analysis import lqr_design
    from quarter_car_sim.params import QuarterCarParams
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
    (:func:`quarter_car_sim.ride_metrics.wk_sos`) on the same samples. The analog filter state
    at sample k is ``(I - A_w dt/2)^-1 (s_k + B_w a_s,k dt/2)`` with ``s_k`` the digital state
    (the bilinear realisation), so the state fed back is the one the design assumed.

    Stateful: :meth:`reset` clears the filter; a state whose time ``t`` does not advance does
    not step the filter again.

    Parameters
    ----------
    design : quarter_car_sim.linear_analysis.LqrDesign
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


def make_controller(name, *, c_sky=DEFAULT_C_SKY, c_p=DEFAULT_C_P, lqr_gain=None, alpha=0.7,
                    params=None, inverse=None, damper_only=False, dt=1e-3):
    """
    Build a controller from its name: the one controller factory (command line and nodes).

    Parameters
    ----------
    name : str
        ``passive@<I>A`` (or ``passive`` = 0 A), ``skyhook``, ``skyhook-onoff``, ``groundhook``,
        ``hybrid``, ``add``, ``sh-add``, ``clipped-optimal``, ``clipped-optimal-wk``,
        ``skyhook-ideal``, ``lqr-active``.
    c_sky, c_p : float
        Skyhook gain and passive part [N s/m] (skyhook, hybrid, skyhook-ideal).
    lqr_gain : array_like, optional
        LQR gain (lqr-active, clipped-optimal; refused by clipped-optimal-wk, which designs
        its own); default designed on ``params`` by
        :func:`quarter_car_sim.linear_analysis.lqr_design` (lqr-active) or
        :func:`clipped_optimal_gain` (clipped-optimal).
    alpha : float
        Hybrid weight.
    params : QuarterCarParams, optional
        Car parameters for the LQR design.
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse, optional
        Inverse model whose force range clips the clipped-optimal demands (else the inverse of
        the loop saturates them, see :class:`ClippedOptimal`).
    damper_only : bool
        Only controllers that drive an MR damper by its coil current (kinds ``'current'`` and
        ``'semi-active'``), as the car and controller nodes need.
    dt : float
        Control period [s]: the sample time of the Wk filter inside ``clipped-optimal-wk``
        (called once per period).

    Returns
    -------
    Controller

    Raises
    ------
    ValueError
        Unknown name; with ``damper_only``, a fully active controller (``skyhook-ideal``,
        ``lqr-active``): it applies forces directly and cannot drive an MR damper.

    """
    ctrl = _make_controller(name, c_sky, c_p, lqr_gain, alpha, params, inverse, dt)
    if damper_only and ctrl.kind not in ('current', 'semi-active'):
        raise ValueError(f'controller {name!r} is {ctrl.kind}: it needs a force actuator, not an '
                         f'MR damper (use {", ".join(DAMPER_LAW_NAMES)})')
    return ctrl


def _make_controller(name, c_sky, c_p, lqr_gain, alpha, params, inverse, dt):
    n = str(name).strip().lower()
    if n == 'passive':
        return Passive(0.0)
    if n.startswith('passive@'):
        txt = n[len('passive@'):].rstrip('a')
        try:
            return Passive(float(txt))
        except ValueError:
            raise ValueError(f'bad passive current in {name!r} (use e.g. passive@0.5A)') from None
    if n == 'skyhook':
        return Skyhook(c_sky, c_p)
    if n == 'skyhook-onoff':
        return SkyhookOnOff()
    if n == 'groundhook':
        return Groundhook()
    if n == 'hybrid':
        return Hybrid(c_sky, alpha)
    if n == 'add':
        return ADD()
    if n == 'sh-add':
        return ShAdd()
    if n == 'clipped-optimal':
        gain = clipped_optimal_gain(params) if lqr_gain is None else lqr_gain
        return ClippedOptimal(gain, None if inverse is None else inverse.body_force_range)
    if n == 'clipped-optimal-wk':
        if lqr_gain is not None:
            raise ValueError('clipped-optimal-wk designs its own gain from its weights '
                             '(wk_lqr_design); `lqr_gain` is for clipped-optimal and lqr-active')
        return ClippedOptimalWk(wk_lqr_design(params),
                                None if inverse is None else inverse.body_force_range, dt=dt)
    if n == 'skyhook-ideal':
        return SkyhookIdeal(c_sky, c_p)
    if n == 'lqr-active':
        if lqr_gain is None:
            from quarter_car_sim.linear_analysis import lqr_design
            from quarter_car_sim.params import QuarterCarParams
            lqr_gain = lqr_design(params or QuarterCarParams()).gain
        return LqrActive(lqr_gain)
    raise ValueError(f'unknown controller {name!r} (use {", ".join(CONTROLLER_NAMES)})')


CONTROLLER_NAMES = ('passive@<I>A', 'skyhook', 'skyhook-onoff', 'groundhook', 'hybrid', 'add',
                    'sh-add', 'clipped-optimal', 'clipped-optimal-wk', 'skyhook-ideal',
                    'lqr-active')
#: The laws that drive an MR damper by its coil current (``damper_only=True``; the nodes).
DAMPER_LAW_NAMES = tuple(n for n in CONTROLLER_NAMES if n not in ('skyhook-ideal', 'lqr-active'))
