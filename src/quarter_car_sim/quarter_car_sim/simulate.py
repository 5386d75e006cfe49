"""
Closed-loop simulation: car + damper plant + controller + inverse model, and comparisons.

Timing of one control period ``dt`` (the same in :class:`ClosedLoop` and :func:`simulate`):
the controller reads the state at ``t_k``, its demand goes through the inverse model to a
current command, and the car (plant) advances to ``t_k + dt`` with that command held. The logged
sample ``k`` holds the state at ``t_k`` with the demand and command computed from it.
"""
import dataclasses
import math
from operator import attrgetter
import time

import numpy as np

from quarter_car_sim.dynamics import QuarterCar

_STATE_FIELDS = ('z_s', 'v_s', 'a_s', 'z_u', 'v_u', 'a_u', 'z_r', 'travel', 'v_rel',
                 'tyre_force', 'damper_force', 'coil_current')


@dataclasses.dataclass
class LoopSample:
    """
    One control period of :class:`ClosedLoop`.

    Attributes
    ----------
    state : CarState
        State at the start of the period (what the controller saw).
    demand : float
        Controller output: force on the body [N], or current [A] for passive controllers.
    current_cmd : float
        Coil current command [A] (nan for active / ideal force controllers).
    saturated : bool
        The command was clipped to the coil range (False for the others).
    next_state : CarState
        State at the end of the period.

    """

    state: object
    demand: float
    current_cmd: float
    saturated: bool
    next_state: object


class ClosedLoop:
    """
    Controller -> inverse model -> quarter car, one control period per :meth:`step`.

    Parameters
    ----------
    car : QuarterCar
        The car (with its damper plant).
    controller : Controller
        See :mod:`quarter_car_sim.controllers`.
    inverse : KwokCurrentInverse or None
        Scalar force -> current inverse (:class:`quarter_car_sim.controllers.KwokCurrentInverse`
        built from identified parameters); needed for semi-active controllers. May be replaced
        at any time (``loop.inverse = ...``), e.g. on new identified parameters.
    i_min, i_max : float
        Coil current range [A] (passive currents are clipped to it too).

    """

    def __init__(self, car, controller, inverse=None, *, i_min=0.0, i_max=2.0):
        self.car = car
        self.controller = controller
        self.inverse = inverse
        self.i_min, self.i_max = float(i_min), float(i_max)
        if controller.kind == 'semi-active' and inverse is None:
            raise ValueError(f'controller {controller.name!r} needs an inverse model')

    def command(self, state):
        """
        Demand and command for a state.

        Returns
        -------
        demand : float
            Controller output (force [N] on the body, or current [A]).
        current_cmd : float
            Current command [A] (nan for force-applying controllers).
        saturated : bool

        """
        ctl = self.controller
        d = ctl.demand(state)
        kind = ctl.kind
        if kind == 'semi-active':
            i, sat = self.inverse.current(d, state.travel, state.v_rel)
            return d, i, sat
        if kind == 'current':
            i = min(max(d, self.i_min), self.i_max)
            return d, i, i != d
        return d, float('nan'), False

    def step(self, dt):
        """Run one control period of ``dt`` [s]; return a :class:`LoopSample`."""
        s = self.car.state
        d, i, sat = self.command(s)
        if i == i:
            nxt = self.car.step(dt, i)
        else:
            nxt = self.car.step_force(dt, d)
        return LoopSample(s, d, i, sat, nxt)


@dataclasses.dataclass
class SimResult:
    """
    Time series of a closed-loop simulation.

    SI units; sign conventions of :mod:`quarter_car_sim.params`.

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
        """Return the ride metrics, see :func:`quarter_car_sim.ride_metrics.ride_metrics`."""
        from quarter_car_sim.ride_metrics import ride_metrics
        return ride_metrics(self)


def make_inverse(damper_params, *, i_min=0.0, i_max=2.0):
    """
    Build the inverse model from identified parameters.

    Parameters
    ----------
    damper_params : dict, ParamsFile, inverse object or path
        kwok-current parameters: a ``{name: value}`` dict, a dict/ParamsFile with
        ``parameters`` and ``model_options``, or a JSON parameter file path
        (``mr_damper_model.params_file.load_params``).
    i_min, i_max : float
        Coil current range [A] the command is saturated to (not applied when
        ``damper_params`` is already an inverse object, which is returned as is).

    Returns
    -------
    KwokCurrentInverse

    """
    from quarter_car_sim.controllers import KwokCurrentInverse
    if isinstance(damper_params, KwokCurrentInverse):
        return damper_params
    if isinstance(damper_params, (str, bytes)) or hasattr(damper_params, '__fspath__'):
        from mr_damper_model.params_file import load_params
        damper_params = load_params(damper_params, model='kwok-current')
    d = damper_params
    if hasattr(d, 'parameters'):
        params, opts = d.parameters, dict(getattr(d, 'model_options', None) or {})
    elif isinstance(d, dict) and 'parameters' in d:
        params, opts = d['parameters'], dict(d.get('model_options') or {})
    else:
        params, opts = dict(d), {}
    return KwokCurrentInverse(params, i_ref_a=float(opts.get('i_ref_a', 2.0)), i_min=i_min,
                              i_max=i_max)


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
        Controller (:mod:`quarter_car_sim.controllers`).
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
    loop = ClosedLoop(car, controller, inverse, i_min=params.i_min, i_max=params.i_max)
    for _ in range(n_settle):
        loop.step(dt)
    duration = road.duration if duration_s is None else float(duration_s)
    n = int(round(duration / dt)) + 1
    block = n if block_steps is None else max(1, int(block_steps))
    command = loop.command
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


RIG_CURRENTS_A = (0.0, 0.5, 1.0, 1.5, 2.0)
"""Coil current steps of the simulated identification test [A]."""

RIG_EXCITATIONS = ((1.1, 0.03), (3.0, 0.015))
"""(frequency [Hz], amplitude [m]) of the simulated identification test: the thesis cam
(1.1 Hz, 30 mm, peak 0.21 m/s) and a faster one (3 Hz, 15 mm, peak 0.28 m/s) that covers the
piston velocities of a class C road at 20 m/s better."""


def simulated_rig_data(plant, *, seed=0, periods=4):
    """
    Simulate a rig test of a damper plant on H1's virtual rig (``mr_damper_rig.virtual_rig``).

    For each excitation of :data:`RIG_EXCITATIONS` the rig steps the current through
    :data:`RIG_CURRENTS_A`, ``periods`` cam periods per level, with the rig's load-cell noise
    and 16-bit DAQ; the records are joined (time restamped).

    Parameters
    ----------
    plant : DamperPlant
        The "true" damper (reset by the rig).
    seed : int
        Noise seed.
    periods : int
        Cam periods per current level.

    Returns
    -------
    mr_damper_model.data.DamperData

    """
    from mr_damper_model.data import DamperData
    from mr_damper_rig.excitation import CamSine, StepSchedule
    from mr_damper_rig.virtual_rig import VirtualRig
    gen = np.random.default_rng(seed)
    parts = []
    for f_hz, amp in RIG_EXCITATIONS:
        rig = VirtualRig(plant, CamSine(f_hz, amp), StepSchedule(RIG_CURRENTS_A, periods / f_hz),
                         rng=gen)
        parts.append(rig.run())
    return DamperData.concatenate(parts, restamp=True)


def identify_damper(plant, *, seed=0, budget_s=None):
    """
    Identify kwok-current parameters of a plant from a simulated rig test.

    Uses :func:`simulated_rig_data` and ``mr_damper_model.identify.identify``.

    Returns
    -------
    dict
        Parameter-file dictionary (``model``, ``parameters``, ``model_options``, ``metrics``,
        ``seed``, ``source``, ...) as accepted by :func:`make_inverse`.

    """
    from mr_damper_model.identify import identify
    data = simulated_rig_data(plant, seed=seed)
    res = identify(data, 'kwok-current', seed=seed, budget_s=budget_s,
                   model_options={'i_ref_a': 2.0})
    d = res.to_json_dict()
    d['source'] = data.source
    return d
