"""Skyhook-family laws: skyhook, on-off skyhook, groundhook, hybrid, ideal skyhook."""
from semi_active_control.laws.base import Controller


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


class SkyhookIdeal(Skyhook):
    """
    Skyhook with a perfect semi-active actuator (force applied directly, no current limits).

    The same law as :class:`Skyhook`; its demand is already clipped to what a passive device can
    dissipate (zero when ``-c_sky v_s`` has the wrong sign for ``v_rel``).
    """

    kind = 'active'

    def __init__(self, c_sky=DEFAULT_C_SKY, c_p=DEFAULT_C_P, name='skyhook-ideal'):
        super().__init__(c_sky, c_p, name)
