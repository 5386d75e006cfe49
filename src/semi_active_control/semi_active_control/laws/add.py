"""Acceleration-driven damper laws: ADD (Savaresi 2005) and SH-ADD (Savaresi and Spelta 2007)."""
import math

from semi_active_control.laws.base import Controller


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
