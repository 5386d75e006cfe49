"""
The full car's live runtime without ROS: one control step of the 7-DOF car at a time.

:class:`FullCarRuntime` holds the car (:class:`~quarter_car_sim.plant.full_car.FullCar`
with its four "true" damper plants and the two-track road), the full-car law under one
:class:`~semi_active_control.supervision.failsafe.ModelSupervisor` per corner
(:class:`~semi_active_control.runtime.full_car_controller_core.FullCarController`) and the counts a
node reports.
Each :meth:`FullCarRuntime.step` reads the state at ``t_k``, commands the four currents
(a corner without a valid, fresh model gets its safe current; the others go on controlling)
and advances the car to ``t_k + dt`` with them held, as the offline
:func:`~quarter_car_sim.simulate.full_car.simulate_full_car` does. The body's accelerations and
rates are kept (bounded by ``log_max_s``) for the ISO 2631-1 figures
(:meth:`FullCarRuntime.body_metrics`, weighted as the samples come: each call costs the samples
since the call before, not the run so far).

The full-car node (``full_car_node``) paces the steps and converts messages; the caller holds
one lock around :meth:`step`, :meth:`offer_parameters` and :meth:`status`;
:meth:`body_metrics` needs none (it reads only samples recorded before its call, which no step
changes), but one thread at a time.
"""
import math

import numpy as np


from semi_active_control.runtime.full_car_controller_core import (corner_supervisors,
                                                                  FullCarController)
from semi_active_control.laws.registry import make_full_car_law
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.metrics.full_car import RunningIso2631
from semi_active_control.car.full_car import CORNERS

#: Body coordinates published and logged, in order (``q[:3]`` of the car).
BODY_JOINTS = ('heave', 'pitch', 'roll')


class FullCarRuntime:
    """
    The live full car: plant, road, law and four supervised inverses, stepped one period at a time.

    Parameters
    ----------
    params : FullCarParams
        Car.
    road : TwoTrackRoad
        Road.
    plants : sequence of 4 DamperPlant
        True dampers of ``fl, fr, rl, rr``.
    law : str or law object
        Full-car law (:func:`~semi_active_control.laws.registry.make_full_car_law` names:
        ``modal-skyhook``, ``per-corner-<law>``, ``passive@<I>A``, ...).
    dt : float
        Control period [s].
    timeout_s, safe_current_a, i_min_a, i_max_a, min_current_span_a, hold_on_reject
        Settings of each corner's
        :class:`~semi_active_control.supervision.failsafe.ModelSupervisor`.
    settle_s : float
        Time run before the road starts (the car starts at ``t = -settle_s``) [s].
    log_max_s : float
        Longest body history kept for :meth:`body_metrics` [s] (recorded time, ``t >= 0``).

    Attributes
    ----------
    steps : int
        Steps run.
    normal_steps : list of int
        Steps each corner was in normal mode.
    first_normal_t : list of float
        Simulated time each corner first left fail-safe [s] (nan: never).

    """

    def __init__(self, params, road, plants, law, *, dt=1e-3, timeout_s=1.0,
                 safe_current_a=0.5, i_min_a=0.0, i_max_a=2.0, min_current_span_a=1.0,
                 hold_on_reject=False, settle_s=0.5, log_max_s=600.0):
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f'`dt` must be > 0, got {dt}')
        if not log_max_s >= 0:
            raise ValueError(f'`log_max_s` must be >= 0, got {log_max_s}')
        if isinstance(law, str):
            law = make_full_car_law(law, params, dt=dt)
        sups = corner_supervisors(timeout_s=timeout_s, safe_current_a=safe_current_a,
                                  i_min_a=i_min_a, i_max_a=i_max_a,
                                  hold_on_reject=hold_on_reject,
                                  min_current_span_a=min_current_span_a)
        self.params = params
        self.dt = float(dt)
        self.controller = FullCarController(law, sups)
        self.car = FullCar(params, plants, road, t0=-float(settle_s))
        self.currents = [float(safe_current_a)] * 4
        self.steps = 0
        self.normal_steps = [0] * 4
        self.first_normal_t = [math.nan] * 4
        n = int(round(log_max_s / self.dt)) + 1
        self._t = np.empty(n)
        self._acc = np.empty((n, 3))
        self._n = 0
        self._iso = RunningIso2631(self.dt)
        self._fed = 0                     # samples of the log the ISO 2631 figures hold

    @property
    def state(self):
        """Return the car's present :class:`~quarter_car_sim.plant.full_car.FullCarState`."""
        return self.car.state

    @property
    def modes(self):
        """Supervisor mode of each corner."""
        return self.controller.modes

    def offer_parameters(self, corner, values, t_clock):
        """Offer a decoded parameter set to one corner's supervisor; return its ``Verdict``."""
        return self.controller.offer_parameters(corner, values, t_clock)

    def supervisor(self, corner):
        """Return the supervisor of ``corner`` (index or name)."""
        i = CORNERS.index(corner) if isinstance(corner, str) else int(corner)
        return self.controller.supervisors[i]

    def step(self, t_clock, currents=None):
        """
        Run one control period.

        Parameters
        ----------
        t_clock : float
            Supervisor clock [s] (parameter ages and timeouts).
        currents : sequence of 4 float, optional
            Currents commanded from outside (an external controller) [A]; the law and the
            supervisors are then not run (nor ``normal_steps`` counted).

        Returns
        -------
        state : FullCarState
            The state the currents answered (at ``t_k``).
        currents : list of float
            The four coil current commands [A] (``fl, fr, rl, rr``).
        new : FullCarState
            The state at ``t_k + dt``.

        """
        state = self.car.state
        if currents is None:
            currents = self.controller.command(state, t_clock)
            for i, mode in enumerate(self.controller.modes):
                if mode == 'normal':
                    self.normal_steps[i] += 1
                    if math.isnan(self.first_normal_t[i]):
                        self.first_normal_t[i] = state.t
        else:
            currents = [float(c) for c in currents]
            if len(currents) != 4:
                raise ValueError(f'`currents` must hold 4 currents, got {len(currents)}')
        if state.t >= 0 and self._n < len(self._t):
            self._t[self._n] = state.t
            self._acc[self._n] = state.acc[:3]
            self._n += 1
        new = self.car.step(self.dt, currents)
        self.currents = currents
        self.steps += 1
        return state, currents, new

    def body_log(self):
        """Return ``(t, acc)``: recorded time [s] and body accelerations (n, 3) (copies)."""
        return self._t[:self._n].copy(), self._acc[:self._n].copy()

    def body_metrics(self):
        """
        ISO 2631-1 figures of the body centre over the recorded time.

        The samples recorded since the call before are added to a
        :class:`~quarter_car_sim.metrics.full_car.RunningIso2631` (see the module docstring).

        Returns
        -------
        dict
            :func:`~quarter_car_sim.metrics.full_car.iso2631_seat` of the logged heave, pitch
            and roll accelerations, plus ``duration_s``; empty before two recorded steps.

        """
        n = self._n
        if n < 2:
            return {}
        acc = self._acc[self._fed:n]
        self._iso.add(acc[:, 0], acc[:, 1], acc[:, 2])
        self._fed = n
        out = self._iso.as_dict()
        out['duration_s'] = float(self._t[n - 1] - self._t[0] + self.dt)
        return out

    def status(self):
        """
        Return a JSON-ready status.

        Returns
        -------
        dict
            ``controller``, ``steps``, ``t_sim``, ``corners`` (per corner: the core status
            with ``mode``, ``reason``, ``failsafe_s``, ``params_accepted``, ... plus
            ``normal_steps``, ``first_normal_t_sim``, ``current_a``), ``corners_normal``.

        """
        corners = self.controller.status()
        for i, c in enumerate(CORNERS):
            corners[c].update(normal_steps=self.normal_steps[i],
                              first_normal_t_sim=self.first_normal_t[i],
                              current_a=float(self.currents[i]))
        return {'controller': self.controller.name, 'steps': self.steps,
                't_sim': float(self.car.t), 'corners': corners,
                'corners_normal': sum(m == 'normal' for m in self.controller.modes)}
