"""
The vehicle computer's chain offline: bus sensors -> vehicle estimator -> controller -> car.

The offline counterpart of ``mr-damper-suite --config vehicle`` without ROS, bus or wall
clock, to see where the chain's a_v goes against the same law on the true states in lock-step
(the suite's ``a_v_lockstep``): the control cycle, the command's delay, the estimate. The cores
are the vehicle computer's own (``VehicleLoop`` runs the same two). One car step ``dt`` of
:func:`simulate_vehicle_chain`:

1. the car's sensor cluster (:func:`~quarter_car_sim.plant.sensors.bus_sensor_cluster`: the
   bus's four body accelerometers and four ride heights at the sensor cycle, the one
   :class:`~quarter_car_sim.runtime.can_link.CanCarLink` samples) reads the true state;
   each sensor's newest reading is held for the next frame, gravity removed, on the bus
   signal's resolution (``EstimatorSettings.accel_quantum`` / ``travel_quantum``);
2. every ``cycle_steps`` steps, a sensor cycle: ``sensing='estimate'`` hands the held readings
   to :class:`~semi_active_control.estimation.VehicleEstimatorCore`, ``'true'`` the true state
   as its exact estimate; :class:`~semi_active_control.runtime.VehicleControllerCore` answers;
3. the drivers apply the answer ``delay_steps`` car steps after its cycle (1: the live loop
   answering within a car step of 1 ms, its p50 of about 0.8 ms; 0: at once, as lock-step),
   holding the last one until then;
4. the car advances by ``dt`` on the drivers' currents (each plant has its coil lag).

No deadline is ever missed here: what the platform adds live (late cycles, the watchdog's
safe current) is the live run's share of its gap (``bench/bench_vehicle_chain.py`` prints
the offline shares, ``bench/bench_vehicle.py`` the live figures).
"""
import math
import time

import numpy as np

from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.plant.sensors import bus_sensor_cluster
from quarter_car_sim.simulate.full_car import RunLog
from semi_active_control.car.full_car import CORNERS
from semi_active_control.estimation.sensor_specs import G0
from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings, VehicleEstimate,
                                                              VehicleEstimatorCore)
from semi_active_control.runtime.vehicle_controller import (full_car_state, MODE_NORMAL,
                                                            VehicleControllerCore)
from semi_active_control.supervision.corner_models import CornerModels
from semi_active_control.supervision.failsafe import COIL_SETTINGS

#: Sensing modes of :func:`simulate_vehicle_chain`.
CHAIN_SENSING = ('estimate', 'true')


def _on_bus(value, quantum):
    # the bus signal's resolution: the estimator settings' quantum, which a test holds equal
    # to the DBC's scale (tests/mr_damper_can/test_codec.py); rounding here, not cantools per
    # reading, keeps the offline chain fast
    return value if quantum <= 0 else round(value / quantum) * quantum


class _BusSensors:
    """The car's sensor cluster at the bus cycle: each sensor's newest reading, on the bus."""

    def __init__(self, dt, settings, seed):
        self.sensors = bus_sensor_cluster(dt, settings.cycle_s, seed)
        self._q = (settings.accel_quantum, settings.travel_quantum)
        self.accel = np.full(4, math.nan)
        self.travel = np.full(4, math.nan)

    def step(self, state):
        r = self.sensors.step(state.t, state)
        if r:
            qa, qt = self._q
            for i, c in enumerate(CORNERS):
                if f'accel_{c}' in r:
                    self.accel[i] = _on_bus(r[f'accel_{c}'] - G0, qa)
                if f'travel_{c}' in r:
                    self.travel[i] = _on_bus(r[f'travel_{c}'], qt)


def simulate_vehicle_chain(params, road, law, plants, model_files, *, dt=1e-3, cycle_steps=2,
                           delay_steps=1, sensing='estimate', estimator=None, settle_s=0.5,
                           duration_s=None, sensor_seed=1, supervision=None):
    """
    Simulate the full car under the vehicle computer's chain (see the module docstring).

    Parameters
    ----------
    params : FullCarParams
        The car (the simulated one and the one the estimator and the law assume).
    road : TwoTrackRoad
        Road (the run covers ``road.duration`` unless ``duration_s`` is given).
    law : str or law object
        Full-car law (:class:`VehicleControllerCore`'s ``law``).
    plants : sequence of 4 DamperPlant
        The true dampers of ``fl, fr, rl, rr`` (reset by the car).
    model_files : sequence of 4 str
        Each corner's end-of-line record, the controller's models (``model_files``).
    dt : float
        Car step [s].
    cycle_steps : int
        Car steps per sensor (control) cycle.
    delay_steps : int
        Car steps from a sensor cycle to its command at the drivers (>= 0).
    sensing : str
        ``'estimate'`` (the vehicle estimator on the bus's sensors) or ``'true'``.
    estimator : VehicleEstimatorCore, optional
        A designed estimator (its ``settings.cycle_s`` must be the cycle; it is reset here);
        default the vehicle's (:class:`EstimatorSettings` at the cycle).
    settle_s : float
        Time run before t = 0 (the chain active), not recorded [s].
    duration_s : float, optional
        Recorded time [s] (default the road's duration).
    sensor_seed : int
        Seed of the sensors' errors.
    supervision : dict, optional
        The corner supervisors' settings (default
        :data:`~semi_active_control.supervision.failsafe.COIL_SETTINGS`, the vehicle computer's).

    Returns
    -------
    FullCarResult
        ``current_cmd`` holds the currents the drivers applied; ``status`` the controller's
        and (``'estimate'``) the estimator's status and ``cycles``.

    """
    if sensing not in CHAIN_SENSING:
        raise ValueError(f'`sensing` must be one of {", ".join(CHAIN_SENSING)}, got {sensing!r}')
    if int(cycle_steps) < 1 or int(delay_steps) < 0:
        raise ValueError(f'`cycle_steps` must be >= 1 and `delay_steps` >= 0, got '
                         f'{cycle_steps}, {delay_steps}')
    cycle_steps, delay_steps = int(cycle_steps), int(delay_steps)
    cycle_s = cycle_steps * dt
    sup = dict(COIL_SETTINGS if supervision is None else supervision)
    ctl = VehicleControllerCore(params, law, CornerModels(model_files, **sup), cycle_s=cycle_s,
                                max_consecutive_misses=1 << 30)
    bus = None
    if sensing == 'estimate':
        if estimator is None:
            estimator = VehicleEstimatorCore(params, EstimatorSettings(cycle_s=cycle_s))
        elif not math.isclose(estimator.settings.cycle_s, cycle_s):
            raise ValueError(f'the estimator runs every {estimator.settings.cycle_s} s, the '
                             f'cycle is {cycle_s} s')
        estimator.reset()
        bus = _BusSensors(dt, estimator.settings, sensor_seed)
    n_settle = int(round(settle_s / dt))
    car = FullCar(params, plants, road, t0=-n_settle * dt)
    s = car.state
    refused = {c: v.reason for c, v in ctl.configure(s.t).items() if not v.accepted}
    ctl.activate(s.t)
    duration = road.duration if duration_s is None else float(duration_s)
    n = int(round(duration / dt)) + 1
    log = RunLog(n)
    pending = []                  # (car step it reaches the drivers, command)
    applied = [sup['safe_current_a']] * 4
    last = None
    sequence = 0
    start = time.perf_counter()
    for k in range(-n_settle, n):
        j = k + n_settle
        if bus is not None:
            bus.step(s)
        if j % cycle_steps == 0:
            sequence += 1
            if bus is None:
                e = VehicleEstimate.exact(s, sequence)
            else:
                e = estimator.step(sequence, s.t, bus.accel.copy(), bus.travel.copy())
            state = full_car_state(params.geometry, e.t, e.body, e.body_rates, e.body_acc,
                                   e.travel, e.travel_velocity, e.tyre_deflection,
                                   e.wheel_velocity, e.damper_force)
            last = ctl.command(state, e.sequence, e.valid, e.reason, s.t)
            pending.append((j + delay_steps, last))
        while pending and pending[0][0] <= j:
            applied = list(pending.pop(0)[1].currents_a)
        if k >= 0:
            log.record(k, s, applied, ctl.controller.demands,
                       [m == MODE_NORMAL for m in last.modes])
        s = car.step(dt, applied)
    status = {'controller': ctl.status(s.t), 'cycles': sequence, 'refused_models': refused}
    if estimator is not None and bus is not None:
        status['estimator'] = estimator.status()
    return log.result(ctl.controller.name, status, time.perf_counter() - start)
