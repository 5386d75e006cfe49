"""
Closed loop on estimated states: car -> modelled sensors -> Kalman filter -> law -> inverse.

The offline counterpart of putting the suite on a vehicle (``quarter-car-sim --sensing
vehicle``, ``bench/bench_sensing.py``). One control period ``dt`` of :func:`simulate_sensed`:

1. each sensor (:class:`quarter_car_sim.plant.sensors.SensorSampler`) samples the true car state at
   ``t_k`` (body acceleration, optionally wheel acceleration, suspension travel) and delivers
   what arrives now (latency, rate, dropouts, faults);
2. the estimator (:class:`semi_active_control.estimation.quarter_car.QuarterCarEstimator`, designed
on the
   *nominal* car, which may differ from the simulated one) takes those readings and the last
   current command (the damper force of the identified model is its known input);
3. a valid estimate goes to the law and the inverse exactly as a measured state would
   (:class:`quarter_car_sim.simulate.live_loop.FixedModelCore`); an invalid one gets the safe
   current (counted);
4. the car advances by ``dt`` with that command.

No ROS; the ride metrics are those of :func:`quarter_car_sim.simulate.quarter_car.simulate` on the
true states, plus the RMS error of each estimated state.
"""
import dataclasses
import math
import time

import numpy as np

from quarter_car_sim.simulate.live_loop import FixedModelCore
from quarter_car_sim.plant.quarter_car import QuarterCar
from semi_active_control.estimation.quarter_car import design_estimator, QuarterCarEstimator
from quarter_car_sim.plant.sensors import SensorSampler
from semi_active_control.estimation.sensor_specs import default_specs
from quarter_car_sim.simulate.quarter_car import _STATE_FIELDS, SimResult

#: Estimated quantities whose RMS error is reported (true value from the car state).
ERROR_STATES = ('travel', 'v_s', 'tyre_def', 'v_u', 'v_rel', 'a_s')

#: Coil time constant [s] the estimator assumes by default: the simulated dampers' 1/190 s
#: (``mr_damper_model.models.plant``; Spencer's eta = 190 1/s), a datasheet figure of a real coil.
COIL_TAU_S = 1.0 / 190.0

#: Default safe current [A] on an invalid estimate (the nodes' ``safe_current_a``).
SAFE_CURRENT_A = 0.5


@dataclasses.dataclass
class SensedResult:
    """
    A run on estimated states: the ride (true states) and the estimates.

    Attributes
    ----------
    sim : SimResult
        True states and commands.
    est : dict
        ``{name: ndarray (n,)}`` for :data:`ERROR_STATES`, ``valid`` (bool) and the
        standard deviations ``std_<state>`` of the filter.
    status : dict
        Estimator counters (:meth:`QuarterCarEstimator.status`) and ``failsafe_steps``.

    """

    sim: SimResult
    est: dict
    status: dict

    def metrics(self):
        """Return the ride metrics of the true states plus estimation RMS errors."""
        m = self.sim.metrics()
        m.update(estimation_rms_error(self.sim, self.est))
        m['estimate_invalid_fraction'] = float(np.mean(~self.est['valid']))
        return m


def true_values(sim):
    """Return ``{state: ndarray}`` of :data:`ERROR_STATES` from a :class:`SimResult`."""
    return {'travel': sim.travel, 'v_s': sim.v_s, 'tyre_def': sim.z_u - sim.z_r,
            'v_u': sim.v_u, 'v_rel': sim.v_rel, 'a_s': sim.a_s}


def estimation_rms_error(sim, est):
    """
    RMS estimation error of each state over the run, and relative to the state's own RMS.

    Returns
    -------
    dict
        ``est_rms_error_<state>`` [SI unit of the state] and ``est_rel_error_<state>`` [-].

    """
    out = {}
    for k, truth in true_values(sim).items():
        err = est[k] - truth
        rms = float(np.sqrt(np.mean(err ** 2)))
        out[f'est_rms_error_{k}'] = rms
        ref = float(np.sqrt(np.mean(truth ** 2)))
        out[f'est_rel_error_{k}'] = rms / ref if ref > 0 else math.nan
    return out


def make_estimator(car_params, dt, specs, inverse, **options):
    """
    Build the corner's estimator for ``specs`` with the identified model as the force input.

    Parameters
    ----------
    car_params : QuarterCarParams
        The car the filter assumes (nominal).
    dt : float
        Control period [s].
    specs : dict
        ``{sensor: SensorSpec}``.
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse
        Identified model (``force(i, x, v)``, model sign: the body force is its negative).
    **options
        Design options of :func:`~semi_active_control.estimation.quarter_car.design_estimator` and
        runtime options of
        :class:`~semi_active_control.estimation.quarter_car.QuarterCarEstimator`.

    """
    run_keys = ('stuck_s', 'dropout_s', 'nis_window_s', 'nis_threshold', 'nis_cap', 'gravity',
                'coil_tau_s', 'travel_deadband_m')
    run = {k: options.pop(k) for k in run_keys if k in options}
    design = design_estimator(car_params, dt, specs, **options)
    force = inverse.force

    def body_force(i, x, v):
        return -force(i, x, v)
    return QuarterCarEstimator(design, body_force, **run)


def simulate_sensed(params, road, controller, plant, inverse, *, dt=1e-3, specs=None,
                    nominal=None, rng=None, settle_s=0.5, safe_current_a=SAFE_CURRENT_A,
                    estimator_options=None):
    """
    Simulate the car with the law on states estimated from modelled sensors.

    Parameters
    ----------
    params : QuarterCarParams
        The simulated ("true") car.
    road : RoadProfile
        Road.
    controller : Controller
        Law of kind ``'current'`` or ``'semi-active'``.
    plant : DamperPlant
        True damper.
    inverse : KwokCurrentInverse
        Identified model (``sign_convention='body'``): the law's inverse and the estimator's
        force input.
    dt : float
        Control period [s].
    specs : dict, optional
        ``{sensor: SensorSpec}`` (default
        :func:`semi_active_control.estimation.sensor_specs.default_specs`).
    nominal : QuarterCarParams, optional
        Car the estimator assumes (default ``params``).
    rng : int or None
        Seed of the sensor errors (each sensor gets its own stream).
    settle_s : float
        Time run before t = 0 (not recorded), as
        :func:`quarter_car_sim.simulate.quarter_car.simulate`.
    safe_current_a : float
        Current [A] commanded while the estimate is invalid.
    estimator_options : dict, optional
        Options of :func:`make_estimator`.

    Returns
    -------
    SensedResult

    """
    if controller.kind not in ('current', 'semi-active'):
        raise ValueError(f'controller {controller.name!r} is {controller.kind}: sensing '
                         'needs a damper law')
    specs = default_specs() if specs is None else dict(specs)
    options = {'coil_tau_s': COIL_TAU_S, **dict(estimator_options or {})}
    est = make_estimator(nominal or params, dt, specs, inverse, **options)
    seeds = np.random.SeedSequence(rng).spawn(len(specs))
    samplers = {name: SensorSampler(spec, dt, np.random.default_rng(sq))
                for (name, spec), sq in zip(sorted(specs.items()), seeds)}
    truth = {'body_accel': 'a_s', 'wheel_accel': 'a_u', 'travel': 'travel'}
    n_settle = int(round(settle_s / dt))
    car = QuarterCar(params, plant, road, t0=road.t[0] - n_settle * dt)
    controller.reset()
    core = FixedModelCore(controller, inverse, i_min=params.i_min, i_max=params.i_max)
    command = core.demand_command
    n = int(round(road.duration / dt)) + 1
    s = car.state
    i_prev = safe_current_a
    states, demand, cmd, sat = [], [], [], []
    e_rows = []
    failsafe = 0
    t0 = time.perf_counter()
    for k in range(-n_settle, n):
        readings = {name: sp.step(s.t, getattr(s, truth[name])) for name, sp in samplers.items()}
        e = est.step(s.t, readings, i_prev)
        if e.valid:
            d, i, sa = command(e)
        else:
            d, i, sa = math.nan, safe_current_a, False
            failsafe += k >= 0
        if k >= 0:
            states.append(s)
            demand.append(d)
            cmd.append(i)
            sat.append(sa)
            e_rows.append((e.travel, e.v_s, e.tyre_def, e.v_u, e.v_rel, e.a_s, e.valid)
                          + e.std)
        s = car.step(dt, i)
        i_prev = i
    wall = time.perf_counter() - t0
    out = {f: np.array([getattr(st, f) for st in states]) for f in _STATE_FIELDS}
    sim = SimResult(t=np.array([st.t for st in states]), demand=np.asarray(demand),
                    current_cmd=np.asarray(cmd), saturated=np.asarray(sat, dtype=bool),
                    controller=controller.name, static_tyre_load=params.static_tyre_load,
                    wall_time_s=wall, **out)
    rows = np.array(e_rows, dtype=float)
    names = ERROR_STATES + ('valid', 'std_travel', 'std_v_s', 'std_tyre_def', 'std_v_u',
                            'std_v_rel')
    est_arrays = {nm: rows[:, j] for j, nm in enumerate(names)}
    est_arrays['valid'] = est_arrays['valid'].astype(bool)
    status = est.status()
    status['failsafe_steps'] = failsafe
    status['sensor_samples_dropped'] = {nm: sp.sensor.n_dropped for nm, sp in samplers.items()}
    return SensedResult(sim=sim, est=est_arrays, status=status)
