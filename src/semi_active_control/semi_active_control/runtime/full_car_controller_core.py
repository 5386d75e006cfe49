"""
The full car's control step without ROS: the law, four inverses and four supervisors.

:class:`FullCarController` is the one home of "full-car law + per corner the inverse of that
corner's identified model under that corner's
:class:`~semi_active_control.supervision.failsafe.ModelSupervisor`": a corner without a valid,
fresh model gets its safe current, the other three go on controlling. The vehicle controller
(:class:`~semi_active_control.runtime.vehicle_controller.VehicleControllerCore`, on one
full-car state per cycle) and the simulated car's built-in law
(:class:`quarter_car_sim.runtime.full_car.FullCarRuntime`) both run it.
"""
from semi_active_control.runtime.controller_core import ControllerCore
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.full_car import CORNERS


def corner_supervisors(**settings):
    """Return one :class:`~semi_active_control.supervision.ModelSupervisor` per corner."""
    return [ModelSupervisor(**settings) for _ in CORNERS]


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
        return [core.command(corner, t_clock) for core, corner in zip(self.cores, state.corners())]

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
