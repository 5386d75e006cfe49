"""
Full-car laws: per-corner laws and modal skyhook, four corner forces from the whole car.

Each corner of a full-car law runs under its own supervisor in the full-car controller core
(:class:`semi_active_control.runtime.full_car_controller_core.FullCarController`: per corner the
inverse of that corner's identified model and its fail-safe), so a law only chooses forces.

Two kinds of full-car law:

- :class:`PerCornerLaws`: four quarter-car laws of :mod:`semi_active_control.laws`, each
  reading its corner (body point above the wheel, wheel, travel), the baseline;
- :class:`ModalSkyhook`: skyhook on the body modes. The demanded heave force, pitch and roll
  moments ``-[c_heave zdot, c_pitch thetadot, c_roll phidot]`` are distributed to the four
  corners by the minimum-norm solution of ``T' F = Q`` (``F = T (T'T)^-1 Q``), a passive part
  ``-c_p v_rel`` is added per corner, and each corner's force is clipped to what its damper can
  do (:func:`semi_active_control.laws.base.clip_dissipative`: dissipative, 0 otherwise).
"""
import math

import numpy as np

from semi_active_control.car.full_car import CORNERS
from semi_active_control.laws.base import clip_dissipative, Controller

DEFAULT_MODAL_ZETA = {'heave': 0.7, 'pitch': 1.5, 'roll': 1.5}
"""Default sky damping ratios of :meth:`ModalSkyhook.from_car` per body mode [-].

Each gain is ``2 zeta sqrt(K M)`` with the mode's ride stiffness (springs and tyres in series,
bars in roll) and the body mass or inertia. Picked by bench/bench_full_car.py on training
roads (ISO 8608 C, 20 m/s, 20 s, seeds 11-13, Spencer plants): median a_v 0.625 m/s^2, as
(0.7, 1, 1); (0.5, 1, 1) 0.637, (0.3, 0.3, 0.3) 0.722, (0.5, 2, 2) 0.639; the higher pitch and
roll ratios lower pitch and roll (We RMS 0.245 / 0.203 against 0.283 / 0.232 at (0.7, 1, 1))."""

DEFAULT_MODAL_C_P = 150.0
"""Default passive part per corner [N s/m] (as the quarter-car skyhook's ``c_p``)."""


class _CornerForce(Controller):
    """The force a full-car law chose for one corner, as a quarter-car law (for the core)."""

    kind = 'semi-active'

    def __init__(self, owner, index):
        self.owner, self.index = owner, index
        self.name = f'{owner.name}[{CORNERS[index]}]'

    def demand(self, state):
        """Return the owner's force for this corner [N on the body]."""
        return self.owner.forces[self.index]


class PerCornerLaws:
    """
    Four independent quarter-car laws, one per corner.

    Parameters
    ----------
    laws : sequence of 4 Controller
        Laws of ``fl, fr, rl, rr`` (kind ``'current'`` or ``'semi-active'``).
    name : str, optional
        Name (default the laws' common name with ``per-corner-`` in front).

    """

    def __init__(self, laws, name=None):
        self.corner_laws = list(laws)
        if len(self.corner_laws) != 4:
            raise ValueError('`laws` must hold 4 laws (fl, fr, rl, rr)')
        names = {law.name for law in self.corner_laws}
        self.name = name or ('per-corner-' + names.pop() if len(names) == 1 else 'per-corner')

    def prepare(self, state):
        """Nothing to do: each corner law reads its own corner."""

    def reset(self):
        """Reset the four laws."""
        for law in self.corner_laws:
            law.reset()


class ForceLaw:
    """
    Base of the full-car laws that choose four body forces from the whole car's state.

    A subclass sets ``name`` and implements :meth:`desired_forces`; :meth:`prepare` clips each
    corner's force to what its damper can do (dissipative, else 0) and the four
    ``corner_laws`` hand the forces to the corner cores.

    Attributes
    ----------
    forces : list of float
        Corner forces of the last :meth:`prepare` [N on the body] (clipped).
    desired : ndarray with shape (4,)
        Unclipped corner forces of the last :meth:`prepare` [N].

    """

    name = 'force-law'
    #: Corner-state fields beyond the common ones that the law needs finite.
    state_fields = ()

    def __init__(self):
        self.corner_laws = [_CornerForce(self, i) for i in range(4)]
        for cl in self.corner_laws:
            cl.state_fields = self.state_fields
        self.reset()

    def desired_forces(self, state):  # pragma: no cover - abstract
        """Return the four unclipped corner forces [N] for a full-car state."""
        raise NotImplementedError

    def prepare(self, state):
        """
        Compute the four clipped corner forces for a full-car state.

        Parameters
        ----------
        state : FullCarState
            Measured state (``v_rel`` per corner and what the law reads).

        Returns
        -------
        list of float
            Corner forces on the body [N].

        """
        self.desired = np.asarray(self.desired_forces(state), dtype=float)
        desired = self.desired.tolist()
        v_rel = np.asarray(state.v_rel, dtype=float).tolist()
        self.forces = [clip_dissipative(desired[i], v_rel[i]) for i in range(4)]
        return self.forces

    def reset(self):
        """Clear the last forces."""
        self.forces = [0.0] * 4
        self.desired = np.zeros(4)


class ModalSkyhook(ForceLaw):
    """
    Modal skyhook on heave, pitch and roll, mapped to four clipped corner forces.

    Parameters
    ----------
    geometry : array_like with shape (4, 3)
        Corner map ``T`` of the car (:attr:`FullCarParams.geometry`).
    c_heave : float
        Heave sky damping [N s/m].
    c_pitch, c_roll : float
        Pitch and roll sky damping [N m s/rad].
    c_p : float
        Passive damping per corner [N s/m].
    name : str
        Law name.

    """

    def __init__(self, geometry, c_heave, c_pitch, c_roll, c_p=DEFAULT_MODAL_C_P,
                 name='modal-skyhook'):
        T = np.asarray(geometry, dtype=float)
        if T.shape != (4, 3):
            raise ValueError('`geometry` must have shape (4, 3)')
        gains = np.array([c_heave, c_pitch, c_roll, c_p], dtype=float)
        if not np.all(np.isfinite(gains)) or np.any(gains < 0):
            raise ValueError('modal gains must be finite and >= 0')
        self.geometry = T
        self.c_modal = gains[:3]
        self.c_p = float(gains[3])
        self.name = name
        self._dist = T @ np.linalg.inv(T.T @ T)         # Q -> minimum-norm corner forces
        super().__init__()

    @classmethod
    def from_car(cls, params, zeta=None, c_p=DEFAULT_MODAL_C_P, name='modal-skyhook'):
        """
        Modal skyhook with gains from damping ratios of the car's body modes.

        Parameters
        ----------
        params : FullCarParams
            Car.
        zeta : dict, optional
            ``{'heave', 'pitch', 'roll'}`` sky damping ratios (default
            :data:`DEFAULT_MODAL_ZETA`; missing keys take the default).
        c_p : float
            Passive part per corner [N s/m].
        name : str
            Law name.

        Returns
        -------
        ModalSkyhook

        """
        z = {**DEFAULT_MODAL_ZETA, **(zeta or {})}
        k_heave, k_pitch, k_roll = body_mode_stiffness(params)
        c = [2.0 * z['heave'] * math.sqrt(k_heave * params.m_s),
             2.0 * z['pitch'] * math.sqrt(k_pitch * params.i_pitch),
             2.0 * z['roll'] * math.sqrt(k_roll * params.i_roll)]
        return cls(params.geometry, *c, c_p=c_p, name=name)

    def modal_velocities(self, state):
        """Return ``[zdot, thetadot, phidot]`` of the body [m/s, rad/s, rad/s]."""
        return np.asarray(state.v[:3], dtype=float)

    def desired_forces(self, state):
        """Return the modal sky forces distributed to the corners plus the passive part [N]."""
        q = -self.c_modal * self.modal_velocities(state)
        return self._dist @ q - self.c_p * np.asarray(state.v_rel, dtype=float)


def body_mode_stiffness(params):
    """
    Ride stiffness of the body modes: heave [N/m], pitch and roll [N m/rad].

    Each corner's spring (plus the bar's ``2 k_arb`` in roll) in series with its tyre, summed
    with the lever arms squared.
    """
    kt = params.k_t
    ks = params.k_s
    kr = ks + 2.0 * np.array([params.k_arb_f, params.k_arb_f, params.k_arb_r, params.k_arb_r])
    ride = ks * kt / (ks + kt)
    ride_roll = kr * kt / (kr + kt)
    return (float(ride.sum()), float((ride * params.x ** 2).sum()),
            float((ride_roll * params.y ** 2).sum()))
