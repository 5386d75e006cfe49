"""
Closed-loop full-car simulation: car + four plants + full-car law + four supervised inverses.

Timing of one control period ``dt`` (as the quarter car's loop): the law and the four corner
cores read the state at ``t_k``, and the car advances to ``t_k + dt`` with the four currents
held. Each corner's supervisor is offered that corner's identified Kwok-current parameters at
the start (a corner given none stays in fail-safe on its safe current). Offline the model
timeout is longer than the run (:data:`OFFLINE_TIMEOUT_S`): nothing re-publishes the models.
"""
import dataclasses
import math
import time

import numpy as np

from semi_active_control.runtime.full_car_controller_core import FullCarController
from semi_active_control.laws.registry import make_full_car_law
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.metrics.full_car import full_car_metrics
from quarter_car_sim.plant.sensors import FullCarSensors
from quarter_car_sim.simulate.quarter_car import identified_set_of
from semi_active_control.estimation.full_car import (design_full_car_estimator,
                                                     FullCarEstimator, STATE_GROUPS)
from semi_active_control.estimation.sensor_specs import accelerometer_spec

#: Model timeout [s] of the offline supervisors (the models are offered once).
OFFLINE_TIMEOUT_S = 1.0e9

#: Sensing modes of :func:`simulate_full_car`.
SENSING = ('ideal', 'vehicle')

_SERIES = ('q', 'v', 'acc', 'z_r', 'travel', 'v_rel', 'tyre_force', 'damper_force',
           'coil_current')


@dataclasses.dataclass
class FullCarResult:
    """
    Time series of a full-car run (SI; corner columns in the order ``fl, fr, rl, rr``).

    Attributes
    ----------
    t : ndarray (n,)
        Time [s].
    q, v, acc : ndarray (n, 7)
        Coordinates ``[z, theta, phi, z_u x4]``, rates and accelerations.
    z_r, travel, v_rel, tyre_force, damper_force, coil_current : ndarray (n, 4)
        Road under each wheel [m], travel [m], travel rate [m/s], tyre force [N], damper
        force on the body [N], actual coil current [A].
    current_cmd : ndarray (n, 4)
        Current commands [A].
    demand : ndarray (n, 4)
        Demanded body force per corner [N] (NaN in fail-safe or with a passive law).
    normal : ndarray of bool (n, 4)
        Corner supervisor in normal mode.
    law : str
        Law name.
    status : dict
        Corner cores' status at the end.
    wall_time_s : float
        Wall time of the loop [s].

    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    acc: np.ndarray
    travel: np.ndarray
    v_rel: np.ndarray
    z_r: np.ndarray
    tyre_force: np.ndarray
    coil_current: np.ndarray
    damper_force: np.ndarray
    current_cmd: np.ndarray
    demand: np.ndarray
    normal: np.ndarray
    law: str = ''
    status: dict = dataclasses.field(default_factory=dict)
    wall_time_s: float = float('nan')

    def metrics(self, params, *, seat=(0.0, 0.0)):
        """Return :func:`quarter_car_sim.metrics.full_car.full_car_metrics` of this run."""
        return full_car_metrics(self, params, seat=seat)


class RunLog:
    """A full-car run's series, preallocated for ``n`` steps (:class:`FullCarResult`'s)."""

    def __init__(self, n):
        self.t = np.empty(n)
        self.series = {f: np.empty((n, 7 if f in ('q', 'v', 'acc') else 4)) for f in _SERIES}
        self.current_cmd = np.empty((n, 4))
        self.demand = np.empty((n, 4))
        self.normal = np.empty((n, 4), dtype=bool)

    def record(self, k, state, currents, demands, normal):
        """Record step ``k``: the car's state, the currents applied, the demands, the modes."""
        self.t[k] = state.t
        for f, a in self.series.items():
            a[k] = getattr(state, f)
        self.current_cmd[k] = currents
        self.demand[k] = demands
        self.normal[k] = normal

    def result(self, law, status, wall_time_s):
        """Return the run as a :class:`FullCarResult`."""
        return FullCarResult(t=self.t, current_cmd=self.current_cmd, demand=self.demand,
                             normal=self.normal, law=law, status=status,
                             wall_time_s=wall_time_s, **self.series)


def simulate_full_car(params, road, law, plants, damper_params=None, *, dt=1e-3, settle_s=0.5,
                      substeps=1, controller=None, duration_s=None, sensing='ideal',
                      sensor_seed=1):
    """
    Simulate the full car on a two-track road under a full-car law.

    Parameters
    ----------
    params : FullCarParams
        Car.
    road : TwoTrackRoad
        Road (the run covers ``road.duration`` unless ``duration_s`` is given).
    law : str, PerCornerLaws or ModalSkyhook
        Law (a name goes through :func:`make_full_car_law`).
    plants : sequence of 4 DamperPlant
        The "true" dampers of ``fl, fr, rl, rr`` (reset before the run).
    damper_params : sequence of 4 (dict, ParamsFile, path or None), optional
        Identified Kwok-current parameters per corner, offered to that corner's supervisor
        at the start (None: the corner gets no model and stays in fail-safe).
    dt : float
        Control period [s].
    settle_s : float
        Time run before t = 0 on the initial road heights (law active), not recorded.
    substeps : int
        Integration sub-steps per period.
    controller : FullCarController, optional
        Ready-made controller (its supervisors are offered ``damper_params`` too when given).
    duration_s : float, optional
        Recorded time [s] (default the road's duration).
    sensing : str
        ``'ideal'`` (the law reads the true state) or ``'vehicle'`` (the law reads the
        estimate of :class:`semi_active_control.estimation.full_car.FullCarEstimator` from the
        production sensor set; the estimation error is recorded in ``status['estimation']``).
    sensor_seed : int
        Seed of the sensors with ``sensing='vehicle'``.

    Returns
    -------
    FullCarResult

    """
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f'`dt` must be > 0, got {dt}')
    if controller is None:
        if isinstance(law, str):
            law = make_full_car_law(law, params, dt=dt)
        controller = FullCarController(law, timeout_s=OFFLINE_TIMEOUT_S, i_min_a=params.i_min,
                                       i_max_a=params.i_max)
    if sensing not in SENSING:
        raise ValueError(f'`sensing` must be one of {", ".join(SENSING)}, got {sensing!r}')
    sensed = None
    if sensing == 'vehicle':
        sensed = SensedState(params, dt, sensor_seed)
    n_settle = int(round(settle_s / dt))
    car = FullCar(params, plants, road, substeps=substeps, t0=-n_settle * dt)
    controller.reset()
    t_clock0 = car.t
    if damper_params is not None:
        if len(damper_params) != 4:
            raise ValueError('`damper_params` must hold 4 entries (fl, fr, rl, rr)')
        for i, dp in enumerate(damper_params):
            if dp is not None:
                controller.offer_parameters(i, identified_set_of(dp), t_clock0)
    s = car.state

    def seen(state):
        return state if sensed is None else sensed.update(state)

    for _ in range(n_settle):
        s = car.step(dt, controller.command(seen(s), s.t))
    if sensed is not None:
        sensed.start_recording()
    duration = road.duration if duration_s is None else float(duration_s)
    n = int(round(duration / dt)) + 1
    log = RunLog(n)
    start = time.perf_counter()
    for k in range(n):
        cur = controller.command(seen(s), s.t)
        log.record(k, s, cur, controller.demands, [m == 'normal' for m in controller.modes])
        s = car.step(dt, cur)
    wall = time.perf_counter() - start
    status = controller.status()
    if sensed is not None:
        status['estimation'] = sensed.summary()
    return log.result(controller.name, status, wall)


def compare_laws(params, road, laws, plants, damper_params, *, dt=1e-3, settle_s=0.5,
                 seat=(0.0, 0.0), sensing='ideal', sensor_seed=1):
    """
    Run several full-car laws on the same road and plants; return their metrics.

    Parameters
    ----------
    params, road
        Car and two-track road (:func:`simulate_full_car`).
    laws : sequence of (str or law object)
        Laws (names through :func:`make_full_car_law`).
    plants, damper_params, dt, settle_s
        As :func:`simulate_full_car`.
    seat : (float, float)
        Seat position from the CG [m] (:func:`full_car_metrics`).
    sensing, sensor_seed
        As :func:`simulate_full_car`; with ``'vehicle'`` each metrics dict also holds
        ``estimation`` (RMS estimation error per state group, invalid steps per reason).

    Returns
    -------
    dict
        ``{law name: metrics dict}`` in the given order.

    """
    out = {}
    for law in laws:
        res = simulate_full_car(params, road, law, plants, damper_params, dt=dt,
                                settle_s=settle_s, sensing=sensing, sensor_seed=sensor_seed)
        m = res.metrics(params, seat=seat)
        est = res.status.pop('estimation', None)
        if est is not None:
            m['estimation'] = est
        m['failsafe_corners'] = [c for c, st in res.status.items() if st['mode'] != 'normal']
        m['wall_time_s'] = res.wall_time_s
        out[res.law] = m
    return out


def true_vector(state):
    """Return the estimator's first 15 states from a true :class:`FullCarState`."""
    return np.concatenate([state.travel, state.q[3:] - state.z_r, state.v])


class SensedState:
    """
    Sensors plus filter of one simulated run: true state in, estimated state out.

    The filter's known input is the damper force each plant holds over the next period
    (``state.damper_force``): what the corner's identified model gives when it is exact. It
    starts with the accelerometers' turn-on bias unknown to the part's standard deviation
    (``bias_std0``, as the vehicle's estimator).

    Parameters
    ----------
    params : FullCarParams
    dt : float
    seed : int
        Sensor seed.
    dropout : (str, float, float), optional
        Injected dropout (:class:`FullCarSensors`).
    delay_steps : int, optional
        :class:`FullCarEstimator`'s ``delay_steps``; None: the default sensors' latency in
        periods, at most 1 (1 at 1 kHz).

    """

    def __init__(self, params, dt, seed=1, *, dropout=None, road_class='C', speed_m_s=20.0,
                 delay_steps=None):
        self.sensors = FullCarSensors(dt, seed, dropout=dropout)
        if delay_steps is None:
            delay_steps = min(1, int(round(accelerometer_spec().latency_s / dt)))
        # started as the vehicle's estimator starts: the accelerometers' turn-on bias unknown
        # to its standard deviation (the default sensors carry one)
        self.estimator = FullCarEstimator(design_full_car_estimator(
            params, dt, road_class=road_class, speed_m_s=speed_m_s), delay_steps=delay_steps,
            bias_std0=accelerometer_spec().bias_std)
        self._recording = False
        self._sq = np.zeros(15)
        self._n = 0

    def start_recording(self):
        """Accumulate estimation errors from now on (after the settling time)."""
        self._recording = True

    def update(self, state):
        """Read the sensors on the true ``state``, step the filter, return the estimate."""
        readings = self.sensors.step(state.t, state)
        x = self.estimator.step(state.t, readings, state.damper_force)
        if self._recording:
            e = x[:15] - true_vector(state)
            self._sq += e * e
            self._n += 1
        return self.estimator.state(state.t)

    def summary(self):
        """RMS estimation error per state group, invalid steps per reason, lost samples."""
        rms = np.sqrt(self._sq / max(self._n, 1))
        return {'rms_error': {g: [float(v) for v in rms[sl]] for g, sl in STATE_GROUPS.items()},
                'steps': self._n, 'invalid_steps': dict(self.estimator.n_invalid),
                'lost_samples': sum(s['lost'] for s in self.sensors.status().values())}
