"""
The vehicle computer's full-car state estimator without ROS: chassis sensors in, one state out.

One home of the filter: :class:`semi_active_control.estimation.full_car.FullCarEstimator` (the
7-DOF car's Kalman filter), designed here at the sensor cycle on the chassis bus's sensors:
the four body accelerometers (gravity removed) and the four ride height sensors, with the
noise of the automotive parts and the bus's resolution (:class:`EstimatorSettings`). It runs
with ``degrade``: a sensor that drops out, freezes or saturates is named and left out, and the
estimate stays valid while three accelerometers and three position sensors observe the car.

The four damper forces are states of the filter (``force_states``, random walks), not the
identified models' forces: an MR damper's force rises by tens of kN per m/s near zero velocity
(its hysteretic ``tanh`` term), and a model force computed from the estimate and held over the
2 ms cycle feeds back through the accelerometer rows of the update and makes the filter
diverge (already a linear damper of 3 kN s/m does: the closed loop's spectral radius is 1.7;
docs/vehicle.md). With the forces estimated from the accelerometers and the travels' dynamics
the estimator needs no model and no current, and modal skyhook on it lost 0.8 % of its a_v
against the same law on the true states (20 s, ISO 8608 C, 20 m/s, the shipped dampers, 2 ms
cycle; the true forces as a known input, the offline simplification, lost 1.2 %).

:class:`VehicleEstimatorCore` adds what a vehicle needs around the filter:

- **cycles by sequence number**: a cycle lost on the bus or in the middleware (a gap in the
  numbers) is predicted through without readings (counted ``cycles.lost``); a repeated or older
  cycle is not used; a gap longer than ``max_gap_cycles`` restarts the filter (``restarts``);
- **readings as ROS topics** (:meth:`offer_reading`, :meth:`tick`): each sensor's newest
  reading since the last tick, for a vehicle whose sensors come as ``sensor_msgs/Imu`` and
  ``JointState`` instead of from the bus.
"""
from dataclasses import dataclass
import math

import numpy as np

from mr_damper_common.sequence import SequenceTracker
from semi_active_control.estimation.full_car import (design_full_car_estimator, FullCarEstimator,
                                                     N_CAR)
from semi_active_control.car.full_car import CORNERS
from semi_active_control.estimation.sensor_specs import accelerometer_spec, ride_height_spec

#: Driving intensity of the estimated damper forces [N^2/s] (their correlation time 0.05 s).
#: Offline on the vehicle chain (``bench/bench_vehicle_chain.py``: 2 ms cycle, the command 1 ms
#: after its sensor cycle, the turn-on biases learnt from :data:`ACCEL_BIAS_STD`, 60 s of the
#: suite's road), a_v against the law on true states in 1 ms lock-step: modal skyhook +3.0 %
#: with 1e8, +1.7 % with 1e9, +0.8 % with 3e9; full-car clipped optimal +2.7 / +2.9 / +3.1 %;
#: per-corner skyhook +1.6 / +2.2 / +3.1 %. 1e9: the suite's law gains most, the others lose
#: a few tenths.
Q_FORCE = 1.0e9

#: Turn-on bias standard deviation of the accelerometers the filter starts with [m/s^2]: the
#: default part's (ADXL313, 15 mg; :func:`accelerometer_spec`).
ACCEL_BIAS_STD = accelerometer_spec().bias_std

#: Relative distance of the covariance from the steady one at which the filter goes over to the
#: steady-state gain. The time-varying filter costs about four times the steady gain's CPU per
#: cycle (240 against 60 us here); from the start's wide bias variances 0.2 is reached after
#: about 12 s of road, 1e-3 after about 40 s (the biases are learnt within seconds either way).
#: Until then the clean cycles run on the gain schedule (:mod:`.gain_schedule`), as cheap as
#: the steady gain's.
STEADY_TOL = 0.2

#: Sensor names of the chassis bus, in the order of the readings array.
BUS_SENSORS = tuple(f'accel_{c}' for c in CORNERS) + tuple(f'travel_{c}' for c in CORNERS)


@dataclass(frozen=True)
class EstimatorSettings:
    """
    Design and run settings of the vehicle's full-car filter (SI units).

    Attributes
    ----------
    cycle_s : float
        Sensor cycle, the filter's period [s].
    accel_noise_density : float
        Accelerometer noise density [m/s^2/sqrt(Hz)] (ADXL313: 250 ug/sqrt(Hz)).
    accel_quantum : float
        Resolution of an acceleration reading [m/s^2] (the bus signal's: 0.01).
    travel_noise_density : float
        Ride height sensor noise density [m/sqrt(Hz)].
    travel_quantum : float
        Resolution of a travel reading [m] (the bus signal's: 0.1 mm).
    accel_range, travel_range : tuple of float
        Ends of each reading's range (the bus signals'): a reading there is saturated.
    road_class, speed_m_s
        Design road of the process noise (ISO 8608 class, speed [m/s]).
    dropout_s : float
        No reading of a sensor for this long: it is left out (``dropout_<sensor>``) [s].
    stuck_accel_s, stuck_travel_s : float
        The same reading for this long: the sensor is stuck [s].
    repeat_gate : float
        A repeated reading this many innovation standard deviations off is stuck at once.
    q_force : float
        Driving intensity of the damper force states [N^2/s].
    max_gap_cycles : int
        A gap of more cycles than this restarts the filter.
    accel_bias_std : float
        Standard deviation of an accelerometer's turn-on bias [m/s^2] the filter starts (and
        restarts) with (``FullCarEstimator``'s ``bias_std0``; ADXL313: 15 mg, the default of
        :func:`~semi_active_control.estimation.sensor_specs.accelerometer_spec`; 0: a bias
        calibrated away).
    steady_tol : float
        The filter goes over to the steady-state gain once its covariance is within this
        relative distance of the steady one (``FullCarEstimator``'s ``steady_tol``).
    gain_schedule : bool
        Until then, run the clean cycles on the gains worked out at design
        (``FullCarEstimator``'s ``gain_schedule``); False: the general step on every cycle
        until the steady gain, as before 30 Nov 2026 (``bench/bench_estimator_start.py``).

    """

    cycle_s: float = 0.002
    accel_noise_density: float = 250e-6 * 9.80665
    accel_quantum: float = 0.01
    travel_noise_density: float = 2.2e-6
    travel_quantum: float = 1e-4
    accel_range: tuple = (-20.48, 20.47)
    travel_range: tuple = (-0.2048, 0.2047)
    road_class: str = 'C'
    speed_m_s: float = 20.0
    dropout_s: float = 0.02
    stuck_accel_s: float = 0.05
    stuck_travel_s: float = 0.25
    repeat_gate: float = 5.0
    q_force: float = Q_FORCE
    max_gap_cycles: int = 250
    accel_bias_std: float = ACCEL_BIAS_STD
    steady_tol: float = STEADY_TOL
    gain_schedule: bool = True

    def __post_init__(self):
        for name in ('cycle_s', 'accel_noise_density', 'travel_noise_density', 'dropout_s',
                     'stuck_accel_s', 'stuck_travel_s', 'repeat_gate', 'speed_m_s', 'q_force'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f'`{name}` must be > 0, got {value}')
        for name in ('accel_quantum', 'travel_quantum', 'accel_bias_std', 'steady_tol'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f'`{name}` must be >= 0, got {value}')
        if self.max_gap_cycles < 1:
            raise ValueError(f'`max_gap_cycles` must be >= 1, got {self.max_gap_cycles}')


@dataclass
class VehicleEstimate:
    """
    One cycle's estimate (SI; corners ``fl, fr, rl, rr``; what ``FullCarState`` carries).

    ``body`` holds heave [m], pitch, roll [rad]; ``body_rates`` and ``body_acc`` their rates
    and accelerations; ``damper_force`` the estimated forces on the body [N]. ``faults`` names
    the sensors not used this cycle.
    """

    sequence: int
    t: float
    body: np.ndarray
    body_rates: np.ndarray
    body_acc: np.ndarray
    travel: np.ndarray
    travel_velocity: np.ndarray
    tyre_deflection: np.ndarray
    wheel_velocity: np.ndarray
    damper_force: np.ndarray
    valid: bool
    reason: str
    faults: list
    travel_std_m: float
    heave_velocity_std_m_s: float
    tyre_deflection_std_m: float
    wheel_velocity_std_m_s: float

    @classmethod
    def exact(cls, state, sequence, t=None):
        """
        Return the exact estimate of a true state (a simulated car's, a test's): valid, std 0.

        Parameters
        ----------
        state : FullCarState
            The car's true state (:class:`semi_active_control.car.full_car_linear.FullCarState`).
        sequence : int
            The cycle's number.
        t : float, optional
            The stamp [s] (default ``state.t``), e.g. the clock a controller's deadlines are on.

        """
        return cls(sequence=int(sequence), t=float(state.t if t is None else t),
                   body=state.q[:3].copy(), body_rates=state.v[:3].copy(),
                   body_acc=state.acc[:3].copy(), travel=state.travel.copy(),
                   travel_velocity=state.v_rel.copy(),
                   tyre_deflection=state.q[3:] - state.z_r, wheel_velocity=state.v[3:].copy(),
                   damper_force=state.damper_force.copy(), valid=True, reason='', faults=[],
                   travel_std_m=0.0, heave_velocity_std_m_s=0.0, tyre_deflection_std_m=0.0,
                   wheel_velocity_std_m_s=0.0)


class VehicleEstimatorCore:
    """
    Chassis sensor cycles (or topic readings) in, one full-car estimate per cycle out.

    Parameters
    ----------
    car_params : FullCarParams
        The car the filter assumes.
    settings : EstimatorSettings, optional

    Attributes
    ----------
    filter : FullCarEstimator
    cycles : SequenceTracker
        Cycle numbers taken: ``lost`` (predicted through), ``repeated`` / ``out_of_order``.
    restarts, steps, invalid_steps : int
    last : VehicleEstimate or None

    """

    def __init__(self, car_params, settings=None):
        s = settings or EstimatorSettings()
        self.settings = s
        rate = 1.0 / s.cycle_s
        accel = accelerometer_spec(noise_density=s.accel_noise_density, rate_hz=rate,
                                   quantum=s.accel_quantum, latency_s=0.0)
        travel = ride_height_spec(noise_density=s.travel_noise_density, rate_hz=rate,
                                  quantum=s.travel_quantum, latency_s=0.0)
        self.design = design_full_car_estimator(car_params, s.cycle_s, accel=accel,
                                                travel=travel, road_class=s.road_class,
                                                speed_m_s=s.speed_m_s, accel_corners=CORNERS,
                                                force_states=True, q_force=s.q_force)
        self.filter = FullCarEstimator(
            self.design, dropout_s=s.dropout_s, gravity=0.0, degrade=True,
            stuck_s={'accel': s.stuck_accel_s, 'travel': s.stuck_travel_s},
            ranges={'accel': s.accel_range, 'travel': s.travel_range},
            repeat_gate=s.repeat_gate, steady_tol=s.steady_tol, bias_std0=s.accel_bias_std,
            gain_schedule=s.gain_schedule)
        self._zero = np.zeros(4)
        self._none = np.full(8, math.nan)
        self._S_rate = self.design.A[0:4].copy()
        self._force = self.design.force_slice
        self._T_pinv = np.linalg.pinv(car_params.geometry)
        self._std_of = None         # the standard deviations the four figures below are of
        self._std_figures = None
        self.cycles = SequenceTracker()
        self.restarts = 0
        self.steps = 0
        self.invalid_steps = 0
        self.invalid_entries = {}
        self.last = None
        self._pending = {}
        self.readings_received = dict.fromkeys(BUS_SENSORS, 0)
        self.readings_replaced = dict.fromkeys(BUS_SENSORS, 0)

    def reset(self):
        """Start again (a new configuration): the filter at rest, the counts kept."""
        self.filter.reset()
        self.cycles = SequenceTracker()
        self._pending = {}
        self.last = None

    def step(self, sequence, t, body_accel, travel):
        """
        Run one sensor cycle; return the :class:`VehicleEstimate` (None: cycle not used).

        Parameters
        ----------
        sequence : int
            The cycle's number (+1 per cycle; gaps are lost cycles).
        t : float
            The cycle's time [s] (the estimate's stamp).
        body_accel : array_like (4,)
            Body accelerations, gravity removed [m/s^2] (NaN: no reading).
        travel : array_like (4,)
            Suspension travels [m] (NaN: no reading).

        """
        gap = self.cycles.offer(sequence)
        if gap < 0:
            return None
        flt = self.filter
        dt = self.settings.cycle_s
        if gap > self.settings.max_gap_cycles:
            flt.reset()
            self.restarts += 1
        elif gap > 0 and flt.n_steps:
            for k in range(gap):
                flt.step(t - (gap - k) * dt, self._none, self._zero)
        y = np.empty(8)
        y[:4] = body_accel
        y[4:] = travel
        flt.step(t, y, self._zero)
        return self._estimate(int(sequence), t)

    def _estimate(self, sequence, t):
        flt = self.filter
        x = flt.x
        travel, tyre, v = x[0:4], x[4:8], x[8:15]
        acc = flt.body_accelerations()
        std = flt.std()
        if std is not self._std_of:
            # the steady gain's are one array for as long as it runs: its figures once
            self._std_of = std
            self._std_figures = (float(std[0:4].max()), float(std[8]),
                                 float(std[4:8].max()), float(std[11:N_CAR].max()))
        s_travel, s_heave_v, s_tyre, s_wheel_v = self._std_figures
        est = VehicleEstimate(
            sequence=sequence, t=float(t), body=self._T_pinv @ (travel + tyre),
            body_rates=v[:3].copy(), body_acc=acc[:3].copy(), travel=travel.copy(),
            travel_velocity=self._S_rate @ x, tyre_deflection=tyre.copy(),
            wheel_velocity=v[3:].copy(), damper_force=x[self._force].copy(),
            valid=flt.valid, reason=flt.reason, faults=list(flt.faults),
            travel_std_m=s_travel, heave_velocity_std_m_s=s_heave_v,
            tyre_deflection_std_m=s_tyre, wheel_velocity_std_m_s=s_wheel_v)
        self.steps += 1
        if not est.valid:
            self.invalid_steps += 1
            if self.last is None or self.last.reason != est.reason:
                self.invalid_entries[est.reason] = self.invalid_entries.get(est.reason, 0) + 1
        self.last = est
        return est

    # --- readings as topics --------------------------------------------------------------------
    def offer_reading(self, sensor, value):
        """
        Keep the newest reading of ``sensor`` (:data:`BUS_SENSORS`) until the next :meth:`tick`.

        Accelerations with gravity removed [m/s^2], travels [m]; NaN marks a lost sample.
        Raises ValueError for an unknown sensor.
        """
        if sensor not in self.readings_received:
            raise ValueError(f'sensor {sensor!r} is not one of {", ".join(BUS_SENSORS)}')
        if sensor in self._pending:
            self.readings_replaced[sensor] += 1
        self._pending[sensor] = float(value)
        self.readings_received[sensor] += 1

    def tick(self, t):
        """
        Run one cycle on the readings offered since the last tick, at time ``t`` [s].

        The cycle's number is ``round(t / cycle_s)``: ticks that skip cycles predict through
        them (``cycles.lost``), a tick not later than the last is not used (None).
        """
        readings, self._pending = self._pending, {}
        y = [readings.get(s, math.nan) for s in BUS_SENSORS]
        return self.step(int(round(t / self.settings.cycle_s)), t, y[:4], y[4:])

    def status(self):
        """Return the counters (JSON-ready): cycles, validity, sensor faults, readings."""
        flt = self.filter
        last = self.last
        return {'steps': self.steps, 'valid': bool(last.valid) if last else False,
                'reason': last.reason if last else 'no_data_yet',
                'faults': list(last.faults) if last else [],
                'invalid_steps': self.invalid_steps,
                'invalid_entries': dict(self.invalid_entries),
                'sensor_fault_entries': dict(flt.fault_entries),
                'sensor_fault_steps': dict(flt.fault_steps),
                'cycles': self.cycles.status(), 'restarts': self.restarts,
                'steady_gain': flt.steady,
                'readings_received': dict(self.readings_received),
                'readings_replaced': dict(self.readings_replaced)}
