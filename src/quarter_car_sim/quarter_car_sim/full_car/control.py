"""
Full-car control: per-corner laws and modal skyhook, each corner under its own supervisor.

:class:`FullCarController` is one control step of the whole car: it runs one
:class:`quarter_car_sim.controller_core.ControllerCore` per corner (law + the inverse of that
corner's identified Kwok-current model + that corner's
:class:`quarter_car_sim.failsafe.ModelSupervisor`). A corner without a valid, fresh model
commands its safe current; the other three go on controlling (each core only knows its own
corner).

Two kinds of full-car law:

- :class:`PerCornerLaws`: four quarter-car laws of :mod:`quarter_car_sim.controllers`, each
  reading its corner (body point above the wheel, wheel, travel), the baseline;
- :class:`ModalSkyhook`: skyhook on the body modes. The demanded heave force, pitch and roll
  moments ``-[c_heave zdot, c_pitch thetadot, c_roll phidot]`` are distributed to the four
  corners by the minimum-norm solution of ``T' F = Q`` (``F = T (T'T)^-1 Q``), a passive part
  ``-c_p v_rel`` is added per corner, and each corner's force is clipped to what its damper can
  do (:func:`quarter_car_sim.controllers.clip_to_damper`: dissipative, 0 otherwise).
"""
import math

import numpy as np

from quarter_car_sim.controller_core import ControllerCore
from quarter_car_sim.controllers import clip_to_damper, Controller, make_controller
from quarter_car_sim.failsafe import ModelSupervisor
from semi_active_control.car.full_car import CORNERS

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
        v_rel = state.v_rel
        self.forces = [clip_to_damper(float(self.desired[i]), _Rel(float(v_rel[i])))
                       for i in range(4)]
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


class _Rel:
    """The one field :func:`clip_to_damper` reads without a force range."""

    __slots__ = ('v_rel',)

    def __init__(self, v_rel):
        self.v_rel = v_rel


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


def make_full_car_law(name, params, *, dt=1e-3, zeta=None, c_p=DEFAULT_MODAL_C_P):
    """
    Build a full-car law by name.

    Parameters
    ----------
    name : str
        ``'modal-skyhook'``, ``'full-car-clipped-optimal'``
        (:class:`quarter_car_sim.full_car.lqr.FullCarClippedOptimal`),
        ``'full-car-clipped-optimal-wk'`` (ISO-weighted,
        :class:`quarter_car_sim.full_car.lqr_wk.FullCarClippedOptimalWk`), ``'passive@<I>A'`` (the
        current at every corner) or
        ``'per-corner-<law>'`` with a damper law of
        :data:`quarter_car_sim.controllers.DAMPER_LAW_NAMES` (e.g. ``per-corner-skyhook``),
        each corner's law designed on its quarter car (:meth:`FullCarParams.corner`).
    params : FullCarParams
        Car.
    dt : float
        Control period [s].
    zeta, c_p
        Modal skyhook options (:meth:`ModalSkyhook.from_car`).

    Returns
    -------
    PerCornerLaws or ModalSkyhook

    """
    n = str(name).strip().lower()
    if n == 'modal-skyhook':
        return ModalSkyhook.from_car(params, zeta=zeta, c_p=c_p)
    if n == 'full-car-clipped-optimal':
        from quarter_car_sim.full_car.lqr import FullCarClippedOptimal
        return FullCarClippedOptimal.from_car(params)
    if n == 'full-car-clipped-optimal-wk':
        from quarter_car_sim.full_car.lqr_wk import FullCarClippedOptimalWk
        return FullCarClippedOptimalWk.from_car(params, dt=dt)
    if n.startswith('passive'):
        laws = [make_controller(n, damper_only=True) for _ in range(4)]
        return PerCornerLaws(laws, name=laws[0].name)
    if n.startswith('per-corner-'):
        law = n[len('per-corner-'):]
        return PerCornerLaws([make_controller(law, params=params.corner(i), damper_only=True,
                                              dt=dt) for i in range(4)])
    raise ValueError(f'unknown full-car law {name!r} (use modal-skyhook, '
                     'full-car-clipped-optimal(-wk), passive@<I>A or per-corner-<law>)')


class FullCarController:
    """
    One full-car control step: the law, then per corner inverse + supervisor (four cores).

    Parameters
    ----------
    law : PerCornerLaws or ModalSkyhook
        Full-car law (``prepare(state)`` and four ``corner_laws``).
    supervisors : sequence of 4 ModelSupervisor, optional
        One per corner (default: four with ``timeout_s``, ``safe_current_a`` and the coil
        range given).
    timeout_s, safe_current_a, i_min_a, i_max_a : float
        Settings of the default supervisors.
    inverse_tol_a : float
        Current tolerance [A] of the inverse models.

    Attributes
    ----------
    cores : list of ControllerCore
        The four corner cores (``cores[i].status()`` per corner).

    """

    def __init__(self, law, supervisors=None, *, timeout_s=1.0, safe_current_a=0.0,
                 i_min_a=0.0, i_max_a=2.0, inverse_tol_a=1e-4):
        if supervisors is None:
            supervisors = [ModelSupervisor(timeout_s=timeout_s, safe_current_a=safe_current_a,
                                           i_min_a=i_min_a, i_max_a=i_max_a)
                           for _ in range(4)]
        supervisors = list(supervisors)
        if len(supervisors) != 4:
            raise ValueError('`supervisors` must hold 4 supervisors (fl, fr, rl, rr)')
        self.law = law
        self.supervisors = supervisors
        self.cores = [ControllerCore(cl, sup, inverse_tol_a=inverse_tol_a)
                      for cl, sup in zip(law.corner_laws, supervisors)]

    @property
    def name(self):
        """Return the law's name."""
        return self.law.name

    def offer_parameters(self, corner, values, t_clock):
        """
        Offer a decoded parameter message to one corner's supervisor.

        Parameters
        ----------
        corner : int or str
            Index 0..3 or name of :data:`~semi_active_control.car.full_car.CORNERS`.
        values : mr_damper_common.contract.IdentifiedSet or mapping
            The corner's identified set (a flat mapping is converted, see
            :meth:`~quarter_car_sim.failsafe.ModelSupervisor.check`).
        t_clock : float
            Receipt time [s].

        Returns
        -------
        quarter_car_sim.failsafe.Verdict

        """
        i = CORNERS.index(corner) if isinstance(corner, str) else int(corner)
        return self.cores[i].offer_parameters(values, t_clock)

    def command(self, state, t_clock):
        """
        Return the four coil currents [A] for a full-car state.

        Parameters
        ----------
        state : FullCarState
            Measured state.
        t_clock : float
            Supervisor clock [s].

        Returns
        -------
        list of float
            Currents of ``fl, fr, rl, rr``.

        """
        self.law.prepare(state)
        return [core.command(state.corner(i), t_clock) for i, core in enumerate(self.cores)]

    @property
    def modes(self):
        """Supervisor mode of each corner (``'normal'`` / ``'failsafe'``)."""
        return [s.mode for s in self.supervisors]

    @property
    def demands(self):
        """Last demanded body force of each corner [N] (NaN without a model or passive)."""
        return [c.f_demand for c in self.cores]

    @property
    def saturated(self):
        """Return, per corner, True when its last command hit a limit (None: no model)."""
        return [c.last_saturated for c in self.cores]

    def reset(self):
        """Reset the law's memory (the supervisors keep their models)."""
        self.law.reset()

    def status(self):
        """Return ``{corner: core status}`` (JSON-ready)."""
        return {name: core.status() for name, core in zip(CORNERS, self.cores)}
