"""
The full car's external controller without ROS: four corner states in, four currents out.

:class:`FullCarControllerCore` is what ``full_car_controller_node`` calls: it collects one
state of each corner (``fl, fr, rl, rr``, a :class:`~mr_damper_common.contract.CornerState`
whose body point carries its displacement too),
rebuilds the body's heave, pitch and roll from the four body points (least squares through the
corner map ``T`` of the car; the corners whose fields are not finite are left out, three are
enough) and runs :class:`~semi_active_control.runtime.full_car_controller_core.FullCarController`:
the full-car law, then per corner the inverse of that corner's identified model under that corner's
:class:`~semi_active_control.supervision.failsafe.ModelSupervisor`. A corner without a valid, fresh
model gets its safe current; the other three go on controlling.

A set is complete when each corner has a state not yet answered and the four stamps are equal;
it is then answered once. A corner's second state before the set completes replaces its first
(counted ``replaced``); four fresh states with different stamps drop the older ones (counted
``incomplete``): nothing is answered twice and nothing dropped silently.
"""
import math

import numpy as np

from semi_active_control.runtime.controller_core import ControllerCore
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.laws.registry import make_full_car_law
from semi_active_control.car.full_car_linear import FullCarState
from semi_active_control.car.full_car import CORNERS


def corner_supervisors(**settings):
    """Return one :class:`~semi_active_control.supervision.ModelSupervisor` per corner."""
    return [ModelSupervisor(**settings) for _ in CORNERS]


def body_coordinates(geometry, values):
    """
    Body ``[heave, pitch, roll]`` quantities from the four body points, by least squares.

    Parameters
    ----------
    geometry : ndarray with shape (4, 3)
        Corner map ``T`` (body points = ``T @ [z, theta, phi]``).
    values : array_like with shape (4,)
        Displacements, velocities or accelerations of the four body points.

    Returns
    -------
    ndarray with shape (3,)
        The body's coordinates (exact when the points lie on one rigid body), from the finite
        points only; NaN with fewer than three.

    """
    values = np.asarray(values, dtype=float)
    ok = np.isfinite(values)
    if ok.sum() < 3:
        return np.full(3, math.nan)
    sol, *_ = np.linalg.lstsq(geometry[ok], values[ok], rcond=None)
    return sol


def full_car_state_of_corners(params, corners):
    """
    Assemble a :class:`~semi_active_control.car.full_car_linear.FullCarState` from four corners.

    Parameters
    ----------
    params : FullCarParams
        Car (its corner map).
    corners : sequence of 4 mr_damper_common.contract.CornerState
        ``fl, fr, rl, rr`` at one stamp.

    Returns
    -------
    FullCarState
        Body coordinates from :func:`body_coordinates`; forces, tyre loads, road velocity and
        coil currents (not measured) are NaN.

    """
    T = params.geometry

    def col(name):
        return np.array([getattr(c, name) for c in corners], dtype=float)

    body_v, body_a = col('v_s'), col('a_s')
    nan4 = np.full(4, math.nan)
    return FullCarState(
        t=corners[0].t,
        q=np.concatenate([body_coordinates(T, col('z_s')), col('z_u')]),
        v=np.concatenate([body_coordinates(T, body_v), col('v_u')]),
        acc=np.concatenate([body_coordinates(T, body_a), nan4]),
        z_r=col('z_r'), zdot_r=nan4.copy(), travel=col('travel'), v_rel=col('v_rel'),
        tyre_force=nan4.copy(), damper_force=nan4.copy(), coil_current=nan4.copy(),
        body_v=body_v, body_a=body_a)


class FullCarControllerCore:
    """
    Four corner states in, four supervised coil currents out (see the module docstring).

    Parameters
    ----------
    params : FullCarParams
        Car (corner map; the law's design).
    law : str or law object
        Full-car law (:func:`~semi_active_control.laws.registry.make_full_car_law` names:
        ``modal-skyhook``, ``per-corner-<law>``, ``full-car-clipped-optimal``, ...).
    dt : float
        Period of the states [s] (laws with a filter inside).
    **supervisor_settings
        Settings of each corner's
        :class:`~semi_active_control.supervision.failsafe.ModelSupervisor` (``timeout_s``,
        ``safe_current_a``, ``i_min_a``, ``i_max_a``, ``min_current_span_a``, ``hold_on_reject``).

    Attributes
    ----------
    controller : FullCarController
        Law and the four corner cores.
    sets : int
        Complete sets answered.
    states : list of int
        States received per corner.
    dropped : dict
        ``replaced`` (a corner's state superseded before its set completed) and
        ``incomplete`` (states of a set that never completed) counts.
    normal_commands : list of int
        Commands per corner given in normal mode.
    first_normal_t : list of float
        Stamp of each corner's first state answered in normal mode [s] (nan: never).

    """

    def __init__(self, params, law, *, dt=1e-3, **supervisor_settings):
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f'`dt` must be > 0, got {dt}')
        if isinstance(law, str):
            law = make_full_car_law(law, params, dt=dt)
        sups = corner_supervisors(**supervisor_settings)
        self.params = params
        self.controller = FullCarController(law, sups)
        self._pending = [None] * 4
        self.sets = 0
        self.states = [0] * 4
        self.dropped = {'replaced': 0, 'incomplete': 0}
        self.normal_commands = [0] * 4
        self.first_normal_t = [math.nan] * 4
        self.currents = [sups[0].safe_current_a] * 4

    @staticmethod
    def index(corner):
        """Return the index 0..3 of ``corner`` (index or name of ``CORNERS``)."""
        return CORNERS.index(corner) if isinstance(corner, str) else int(corner)

    def supervisor(self, corner):
        """Return the supervisor of ``corner`` (index or name)."""
        return self.controller.supervisors[self.index(corner)]

    def offer_parameters(self, corner, values, t_clock):
        """Offer a decoded parameter set to one corner's supervisor; return its ``Verdict``."""
        return self.controller.offer_parameters(self.index(corner), values, t_clock)

    def offer_state(self, corner, state, t_clock):
        """
        Take one corner's state; answer the set when it completes.

        Parameters
        ----------
        corner : int or str
            Corner.
        state : mr_damper_common.contract.CornerState
            Its state.
        t_clock : float
            Supervisor clock [s].

        Returns
        -------
        list of 4 float or None
            The four coil currents [A] when this state completed a set, else None.

        """
        i = self.index(corner)
        self.states[i] += 1
        if self._pending[i] is not None:
            self.dropped['replaced'] += 1
        self._pending[i] = state
        if any(s is None for s in self._pending):
            return None
        stamps = [s.t for s in self._pending]
        newest = max(stamps)
        if min(stamps) != newest:
            for j, s in enumerate(self._pending):
                if s.t != newest:
                    self._pending[j] = None
                    self.dropped['incomplete'] += 1
            return None
        corners, self._pending = self._pending, [None] * 4
        state = full_car_state_of_corners(self.params, corners)
        self.before_command(state)
        currents = self.controller.command(state, t_clock)
        self.after_command(state)
        for j, mode in enumerate(self.controller.modes):
            if mode == 'normal':
                self.normal_commands[j] += 1
                if math.isnan(self.first_normal_t[j]):
                    self.first_normal_t[j] = corners[j].t
        self.sets += 1
        self.currents = currents
        return currents

    def before_command(self, state):
        """Run before the law on a complete set's state (a subclass's hook; nothing here)."""

    def after_command(self, state):
        """Run after the four currents of a set (a subclass's hook; nothing here)."""

    def status(self, t_clock=None):
        """
        Return a JSON-ready status.

        Returns
        -------
        dict
            ``controller``, ``sets``, ``corners_normal``, ``dropped`` and ``corners`` (per
            corner: the core's status with ``mode``, ``reason``, ``params_accepted``, ...,
            plus ``states``, ``normal_commands``, ``first_normal_t_sim``, ``current_a`` and,
            with ``t_clock``,
            ``param_age_s``).

        """
        if t_clock is not None:
            for sup in self.controller.supervisors:
                sup.update(t_clock)
        corners = self.controller.status()
        for i, c in enumerate(CORNERS):
            corners[c].update(states=self.states[i], normal_commands=self.normal_commands[i],
                              first_normal_t_sim=self.first_normal_t[i],
                              current_a=float(self.currents[i]))
            if t_clock is not None:
                corners[c]['param_age_s'] = self.controller.supervisors[i].age(t_clock)
        return {'controller': self.controller.name, 'sets': self.sets,
                'corners_normal': sum(m == 'normal' for m in self.controller.modes),
                'dropped': dict(self.dropped), 'corners': corners}


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
            :meth:`~semi_active_control.supervision.failsafe.ModelSupervisor.check`).
        t_clock : float
            Receipt time [s].

        Returns
        -------
        semi_active_control.supervision.failsafe.Verdict

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
