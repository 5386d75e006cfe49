"""The controller interface, the passive damper and what every damper law shares."""
import math


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


def car_state_feedback(k, state):
    """Return ``-k @ [travel, v_s, z_u - z_r, v_u]`` [N]: the car part of an LQR law."""
    return -(k[0] * state.travel + k[1] * state.v_s + k[2] * (state.z_u - state.z_r)
             + k[3] * state.v_u)


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
    return clip_dissipative(f, vr)


def clip_dissipative(force, v_rel):
    """
    Clip a body force [N] to the dissipative half-line at suspension velocity ``v_rel`` [m/s].

    ``force v_rel <= 0``: at most 0 in extension (``v_rel > 0``), at least 0 in compression,
    0 at rest (what :func:`clip_to_damper` does after the force range).
    """
    if v_rel > 0.0:
        return min(force, 0.0)
    if v_rel < 0.0:
        return max(force, 0.0)
    return 0.0
