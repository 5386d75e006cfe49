"""
Closed-loop simulation: car + damper plant + controller + inverse model, and comparisons.

The loop is :class:`quarter_car_sim.simulate.live_loop.ClosedLoop` without a supervisor (a fixed
identified inverse). Timing of one control period ``dt``: the controller reads the state at
``t_k``, its demand goes through the inverse model to a current command, and the car (plant)
advances to ``t_k + dt`` with that command held. The logged sample ``k`` holds the state at
``t_k`` with the demand and command computed from it.
"""
import dataclasses
import math
from operator import attrgetter
import time

import numpy as np

from mr_damper_common.contract import IdentifiedSet
from mr_damper_model.io.params_file import load_identified_set
from mr_damper_model.models.inverse import KwokCurrentInverse
from quarter_car_sim.plant.quarter_car import QuarterCar
from quarter_car_sim.simulate.live_loop import ClosedLoop
from quarter_car_sim.metrics.quarter_car import ride_metrics

_STATE_FIELDS = ('z_s', 'v_s', 'a_s', 'z_u', 'v_u', 'a_u', 'z_r', 'travel', 'v_rel',
                 'tyre_force', 'damper_force', 'coil_current')


@dataclasses.dataclass
class SimResult:
    """
    Time series of a closed-loop simulation.

    SI units; sign conventions of :mod:`semi_active_control.car.quarter_car`.

    Attributes
    ----------
    t : ndarray (n,)
        Time [s].
    z_s, v_s, a_s, z_u, v_u, a_u, z_r, travel, v_rel : ndarray (n,)
        States, accelerations, road height, suspension travel and velocity.
    tyre_force, damper_force : ndarray (n,)
        Total tyre force [N] and damper force on the body [N].
    coil_current : ndarray (n,)
        Actual plant coil current [A] (nan with direct force).
    demand : ndarray (n,)
        Controller output (force on body [N]; current [A] for passive).
    current_cmd : ndarray (n,)
        Current command [A] (nan for force-applying controllers).
    saturated : ndarray of bool (n,)
        Command saturated by the inverse model / current range.
    controller : str
        Controller name.
    static_tyre_load : float
        [N].
    wall_time_s : float
        Wall-clock time of the loop [s].

    """

    t: np.ndarray
    z_s: np.ndarray
    v_s: np.ndarray
    a_s: np.ndarray
    z_u: np.ndarray
    v_u: np.ndarray
    a_u: np.ndarray
    z_r: np.ndarray
    travel: np.ndarray
    v_rel: np.ndarray
    tyre_force: np.ndarray
    damper_force: np.ndarray
    coil_current: np.ndarray
    demand: np.ndarray
    current_cmd: np.ndarray
    saturated: np.ndarray
    controller: str = ''
    static_tyre_load: float = float('nan')
    wall_time_s: float = float('nan')

    @property
    def states(self):
        """State matrix ``[z_s, v_s, z_u, v_u]`` with shape (n, 4)."""
        return np.column_stack([self.z_s, self.v_s, self.z_u, self.v_u])

    @property
    def forces(self):
        """``[damper_force, tyre_force]`` with shape (n, 2) [N]."""
        return np.column_stack([self.damper_force, self.tyre_force])

    @property
    def currents(self):
        """``[current_cmd, coil_current]`` with shape (n, 2) [A]."""
        return np.column_stack([self.current_cmd, self.coil_current])

    def metrics(self):
        """Return the ride metrics of this run (:mod:`quarter_car_sim.metrics.quarter_car`)."""
        return ride_metrics(self)


#: Current tolerance [A] of the offline inverse model (as the car node's ``inverse_tol_a``).
INVERSE_TOL_A = 1e-4


def identified_set_of(damper_params):
    """
    Return the identified set of a study's damper parameters, whatever form they came in.

    Parameters
    ----------
    damper_params : IdentifiedSet, dict, ParamsFile or path
        A :class:`~mr_damper_common.contract.IdentifiedSet`; a JSON parameter file path
        (:func:`mr_damper_model.io.params_file.load_identified_set`); a parameter file's
        content (a dict or ``ParamsFile`` with ``parameters``, ``model_options``,
        ``current_min_a``, ``current_max_a``); or ``{name: value}`` of the ten kwok-current
        parameters (``i_ref_a`` 2 A, identified over 0-2 A).

    Returns
    -------
    mr_damper_common.contract.IdentifiedSet
        Marked valid unless the file says otherwise.

    """
    d = damper_params
    if isinstance(d, IdentifiedSet):
        return d
    if isinstance(d, (str, bytes)) or hasattr(d, '__fspath__'):
        return load_identified_set(d)
    if hasattr(d, 'parameters') or (isinstance(d, dict) and 'parameters' in d):
        return IdentifiedSet.from_params_file(d)
    return IdentifiedSet(dict(d), current_min_a=0.0, current_max_a=2.0, valid=True)


def make_inverse(damper_params, *, i_min=0.0, i_max=2.0):
    """
    Build the inverse model from identified parameters.

    Parameters
    ----------
    damper_params : IdentifiedSet, dict, ParamsFile, inverse object or path
        kwok-current parameters in a form :func:`identified_set_of` takes.
    i_min, i_max : float
        Coil current range [A] the command is saturated to (not applied when
        ``damper_params`` is already an inverse object, which is returned as is).

    Returns
    -------
    KwokCurrentInverse

    """
    if isinstance(damper_params, KwokCurrentInverse):
        return damper_params
    s = identified_set_of(damper_params)
    return KwokCurrentInverse(s.parameters, i_ref_a=s.i_ref_a, i_min=i_min, i_max=i_max,
                              tol_a=INVERSE_TOL_A, sign_convention='body')


def simulate(params, road, controller, plant=None, *, dt=1e-3, damper_params=None,
             substeps=1, settle_s=0.5, inverse=None):
    """
    Simulate the quarter car on a road with a controller.

    Parameters
    ----------
    params : QuarterCarParams
        Car parameters.
    road : RoadProfile
        Road (the result covers its duration).
    controller : Controller
        Controller (:mod:`semi_active_control.laws`).
    plant : DamperPlant, optional
        Damper plant (reset before the run); needed unless the controller is active.
    dt : float
        Control period [s] (default 1 ms).
    damper_params : dict, ParamsFile or path, optional
        Identified kwok-current parameters for the inverse model (semi-active controllers).
    substeps : int
        Integration sub-steps per control period.
    settle_s : float
        Time [s] run before t = 0 on the road's initial height (controller active) so the car
        settles on the damper's static force; not recorded.
    inverse : inverse object, optional
        Ready-made inverse (instead of ``damper_params``).

    Returns
    -------
    SimResult

    """
    blocks = list(simulate_blocks(params, road, controller, plant, dt=dt,
                                  damper_params=damper_params, substeps=substeps,
                                  settle_s=settle_s, inverse=inverse, block_steps=None))
    b = blocks[0]
    return SimResult(controller=controller.name, static_tyre_load=params.static_tyre_load,
                     **b)


def simulate_blocks(params, road, controller, plant=None, *, dt=1e-3, damper_params=None,
                    substeps=1, settle_s=0.5, inverse=None, duration_s=None,
                    block_steps=50000):
    """
    Simulate like :func:`simulate`, yielding the time series in blocks (bounded memory).

    Parameters are those of :func:`simulate`, plus:

    duration_s : float, optional
        Simulated time [s] from t = 0 (default: the road's duration); longer than the road
        for a periodic road (``RoadProfile.periodic``), else the road is held flat after its end.
    block_steps : int or None
        Control steps per block (None: one block of the whole run).

    Yields
    ------
    dict
        Arrays of the block: ``t``, the state fields of :class:`SimResult`, ``demand``,
        ``current_cmd``, ``saturated``, and ``wall_time_s`` (loop wall time of the block [s]).

    """
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f'`dt` must be > 0, got {dt}')
    if inverse is None and damper_params is not None:
        inverse = make_inverse(damper_params, i_min=params.i_min, i_max=params.i_max)
    if controller.kind != 'active' and plant is None:
        raise ValueError(f'controller {controller.name!r} needs a damper plant')
    n_settle = int(round(settle_s / dt))
    car = QuarterCar(params, plant if controller.kind != 'active' else None, road,
                     substeps=substeps, t0=road.t[0] - n_settle * dt)
    controller.reset()
    loop = ClosedLoop(car, controller, dt=dt, inverse=inverse)
    for _ in range(n_settle):
        loop.step()
    duration = road.duration if duration_s is None else float(duration_s)
    n = int(round(duration / dt)) + 1
    block = n if block_steps is None else max(1, int(block_steps))
    command = loop.core.demand_command
    step_i = car.step
    step_f = car.step_force
    s = car.state
    for start in range(0, n, block):
        m = min(block, n - start)
        states = [None] * m
        demand = [0.0] * m
        cmd = [0.0] * m
        sat = [False] * m
        t_start = time.perf_counter()
        for k in range(m):
            d, i, sa = command(s)
            states[k] = s
            demand[k], cmd[k], sat[k] = d, i, sa
            s = step_i(dt, i) if i == i else step_f(dt, d)
        wall = time.perf_counter() - t_start
        out = {f: np.fromiter(map(attrgetter(f), states), dtype=float, count=m)
               for f in _STATE_FIELDS}
        out['t'] = np.fromiter(map(attrgetter('t'), states), dtype=float, count=m)
        out.update(demand=np.asarray(demand), current_cmd=np.asarray(cmd),
                   saturated=np.asarray(sat, dtype=bool), wall_time_s=wall)
        yield out


def compare(params, road, controllers, plant, *, dt=1e-3, damper_params=None, substeps=1,
            settle_s=0.5):
    """
    Run several controllers on the same road (same seed) and the same (reset) plant.

    Returns
    -------
    dict
        name -> :class:`SimResult`, in the given order.

    """
    inverse = None
    if damper_params is not None:
        inverse = make_inverse(damper_params, i_min=params.i_min, i_max=params.i_max)
    out = {}
    for ctl in controllers:
        out[ctl.name] = simulate(params, road, ctl, plant, dt=dt, inverse=inverse,
                                 substeps=substeps, settle_s=settle_s)
    return out
