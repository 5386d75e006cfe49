"""
Simulated vehicle sensors: the true state of a car sampled with each sensor's error model.

The error models and the datasheet figures are the vehicle side's
(:mod:`semi_active_control.estimation.sensor_specs`: :class:`SensorSpec`, :class:`Fault`,
:func:`default_specs`, ...); here they sample (no ROS; seeded, per sample):
:class:`Sensor` (one sensor), :class:`SensorSampler` (one sensor at the control rate, its
latency in whole periods), :func:`sample_series` (a whole time series), :class:`VehicleSensors`
(a quarter-car corner's set) and :class:`FullCarSensors` (the full car's production set).
"""
import math

import numpy as np

from semi_active_control.car.full_car import CORNERS
from semi_active_control.estimation.full_car import ACCEL_CORNERS
from semi_active_control.estimation.quarter_car import EstimatorError
from semi_active_control.estimation.sensor_specs import (accelerometer_spec, default_specs, Fault,
                                                         ride_height_spec, SensorError,
                                                         SensorSpec)


class Sensor:
    """
    One sensor: samples true values and returns readings with the error model of ``spec``.

    Parameters
    ----------
    spec : SensorSpec
        Error model.
    rng : int, numpy.random.Generator or None
        Seed or generator (``np.random.default_rng(rng)``).

    Attributes
    ----------
    bias_now : float
        Bias at the last sample [unit] (drift and random walk included, faults not).
    n_samples, n_dropped : int
        Samples taken, and those lost (random dropouts and ``dropout`` faults).

    """

    def __init__(self, spec, rng=None):
        if not isinstance(spec, SensorSpec):
            raise SensorError('`spec` must be a SensorSpec')
        self.spec = spec
        self.rng = np.random.default_rng(rng)
        self._bias0 = spec.bias + (self.rng.normal(0.0, spec.bias_std) if spec.bias_std else 0.0)
        self._rw = 0.0
        self._t_last = None
        self._last = math.nan
        self._normal, self._uniform = [], []
        self.bias_now = self._bias0
        self.n_samples = 0
        self.n_dropped = 0

    def _draw_normal(self):
        if not self._normal:
            self._normal = self.rng.standard_normal(1024).tolist()
        return self._normal.pop()

    def _draw_uniform(self):
        if not self._uniform:
            self._uniform = self.rng.random(1024).tolist()
        return self._uniform.pop()

    def _active(self, t, kind):
        if not self.spec.faults:
            return None
        for f in self.spec.faults:
            if f.kind == kind and f.t_start <= t < f.t_end:
                return f
        return None

    def sample(self, t, x):
        """
        Return the reading of true value ``x`` sampled at time ``t`` [s] (NaN when lost).

        Times must increase between calls; the bias random walk advances by the elapsed time.
        """
        s = self.spec
        t = float(t)
        if self._t_last is not None and s.bias_rw:
            dt = t - self._t_last
            if dt > 0:
                self._rw += s.bias_rw * math.sqrt(dt) * self._draw_normal()
        self._t_last = t
        self.bias_now = self._bias0 + s.bias_drift * t + self._rw
        noise = s.noise_std * self._draw_normal() if s.noise_std else 0.0
        lost = s.dropout_prob > 0 and self._draw_uniform() < s.dropout_prob
        self.n_samples += 1
        y = (1.0 + s.scale_error) * (x + s.offset) + self.bias_now + noise
        step = self._active(t, 'bias_step')
        if step is not None:
            y += step.value
        if s.quantum:
            y = s.quantum * round(y / s.quantum)
        if self._active(t, 'stuck') is not None and self._last == self._last:
            return self._last
        if self._active(t, 'dropout') is not None or lost:
            self.n_dropped += 1
            if s.dropout_mode == 'hold' and not self._active(t, 'dropout'):
                return self._last
            return math.nan
        self._last = y
        return y


class SensorSampler:
    """
    A sensor read by a control loop of period ``dt``: sample times, latency and delivery.

    At control step ``k`` (time ``t_k``) :meth:`step` gives the true value at ``t_k`` to the
    sensor when a sample is due (every ``1 / rate_hz``, on the step at or after the due time)
    and returns the reading that becomes available at this step: the one sampled
    ``latency_steps = round(latency_s / dt)`` steps earlier, or None when no reading arrives
    at this step (sensor slower than the loop).

    Parameters
    ----------
    spec : SensorSpec
        Error model.
    dt : float
        Control period [s].
    rng : int, numpy.random.Generator or None
        Seed or generator.

    """

    def __init__(self, spec, dt, rng=None):
        if not (math.isfinite(dt) and dt > 0):
            raise SensorError(f'`dt` must be > 0, got {dt}')
        if spec.rate_hz > 1.0 / dt * (1 + 1e-9):
            raise SensorError(f'`rate_hz` ({spec.rate_hz} Hz) is above the control rate '
                              f'({1.0 / dt:g} Hz): the loop would skip samples')
        self.sensor = Sensor(spec, rng)
        self.spec = spec
        self.dt = float(dt)
        self.latency_steps = int(round(spec.latency_s / dt))
        self._period = 1.0 / spec.rate_hz
        self._next_t = None
        self._queue = [None] * self.latency_steps

    def step(self, t, x):
        """Sample if due at ``t`` [s]; return the reading delivered now (float, NaN or None)."""
        if self._next_t is None:
            self._next_t = t
        reading = None
        if t >= self._next_t - 1e-9 * self.dt:
            reading = self.sensor.sample(t, x)
            self._next_t += self._period
            while self._next_t <= t:
                self._next_t += self._period
        self._queue.append(reading)
        return self._queue.pop(0)


def sample_series(spec, t, x, rng=None):
    """
    Sample a whole series at the times ``t`` (one sample each; no latency shift).

    Parameters
    ----------
    spec : SensorSpec
        Error model (``rate_hz`` is not used: every ``t`` is a sample).
    t, x : array_like with shape (n,)
        Sample times [s] and true values.
    rng : int, numpy.random.Generator or None
        Seed.

    Returns
    -------
    ndarray with shape (n,)

    """
    s = Sensor(spec, rng)
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    return np.array([s.sample(ti, xi) for ti, xi in zip(t, x)])


def sample_due(samplers, t, true):
    """
    Step every sampler at time ``t`` [s] on its true value; return the readings delivered.

    ``samplers``: ``{sensor: SensorSampler}``; ``true``: ``{sensor: value}``. A sensor with
    nothing due is left out of the result (NaN: a lost sample).
    """
    out = {}
    for name, sampler in samplers.items():
        reading = sampler.step(t, true[name])
        if reading is not None:
            out[name] = reading
    return out


def sampler_counts(samplers):
    """Return ``{sensor: {samples, lost}}`` of ``{sensor: SensorSampler}`` (JSON-ready)."""
    return {name: {'samples': s.sensor.n_samples, 'lost': s.sensor.n_dropped}
            for name, s in samplers.items()}


class VehicleSensors:
    """
    The sensors of one simulated corner, read by the car each control period (no ROS).

    What a vehicle gives the state estimator: the body accelerometer (``body_accel``, specific
    force) and the suspension position sensor (``travel``), each a :class:`SensorSampler` with
    the default automotive error model (:func:`default_specs`), seeded. A sensor dropout can be
    injected over a window of sample time (a ``dropout`` :class:`Fault`: every sample of the
    window is lost, delivered as NaN).

    Parameters
    ----------
    dt : float
        Control period [s].
    seed : int
        Seed of the sensors (each sensor draws from its own stream).
    dropout : tuple of (float, float), optional
        ``(start_s, duration_s)`` of an injected dropout [s of the car's time]; None or a
        duration of 0: none.
    dropout_sensors : tuple of str
        Sensors the dropout hits (default: the body accelerometer).
    specs : dict, optional
        ``{sensor: SensorSpec}`` instead of :func:`default_specs`.

    """

    def __init__(self, dt, seed=1, *, dropout=None, dropout_sensors=('body_accel',),
                 specs=None):
        specs = dict(default_specs() if specs is None else specs)
        self.dropout = None
        if dropout is not None and float(dropout[1]) > 0:
            start, duration = float(dropout[0]), float(dropout[1])
            self.dropout = (start, duration)
            for name in dropout_sensors:
                if name not in specs:
                    raise SensorError(f'`dropout_sensors`: {name!r} is not one of '
                                      f'{", ".join(specs)}')
                specs[name] = specs[name].replace(
                    faults=specs[name].faults + (Fault('dropout', start, start + duration),))
        self.dropout_sensors = tuple(dropout_sensors) if self.dropout else ()
        streams = np.random.SeedSequence(int(seed)).spawn(len(specs))
        self.samplers = {name: SensorSampler(spec, dt, np.random.default_rng(s))
                         for (name, spec), s in zip(sorted(specs.items()), streams)}

    def step(self, t, state):
        """
        Sample the sensors at time ``t`` [s] from a car state (``a_s``, ``a_u``, ``travel``).

        Returns ``{sensor: reading}`` of the readings delivered at this step (NaN: lost; a
        sensor with nothing due is left out).
        """
        true = {'body_accel': state.a_s, 'wheel_accel': state.a_u, 'travel': state.travel}
        return sample_due(self.samplers, t, true)

    def status(self):
        """Return ``{sensor: {samples, lost}}`` and the injected dropout (JSON-ready)."""
        return {'sensors': sampler_counts(self.samplers),
                'dropout_window_s': list(self.dropout) if self.dropout else [],
                'dropout_sensors': list(self.dropout_sensors)}


class FullCarSensors:
    """
    The production sensor set of a simulated full car (seeded samplers of each sensor).

    Parameters
    ----------
    dt : float
    seed : int
    accel, travel : SensorSpec, optional
    dropout : (str, float, float), optional
        ``(sensor, start_s, duration_s)`` of an injected dropout.
    accel_corners : sequence of str
        Corners with a body accelerometer (default :data:`ACCEL_CORNERS`).
    faults : sequence of (str, Fault)
        More faults injected, each on the named sensor.

    """

    def __init__(self, dt, seed=1, *, accel=None, travel=None, dropout=None,
                 accel_corners=ACCEL_CORNERS, faults=()):
        accel = accelerometer_spec() if accel is None else accel
        travel = ride_height_spec() if travel is None else travel
        self.accel_corners = tuple(accel_corners)
        self.sensors = (tuple(f'accel_{c}' for c in self.accel_corners)
                        + tuple(f'travel_{c}' for c in CORNERS))
        specs = {s: (accel if s.startswith('accel') else travel) for s in self.sensors}
        faults = list(faults)
        if dropout is not None:
            name, start, dur = dropout
            faults.append((name, Fault('dropout', start, start + dur)))
        for name, fault in faults:
            if name not in specs:
                raise EstimatorError(f'unknown sensor {name!r} (use {", ".join(self.sensors)})')
            specs[name] = specs[name].replace(faults=specs[name].faults + (fault,))
        streams = np.random.SeedSequence(int(seed)).spawn(len(self.sensors))
        self.samplers = {s: SensorSampler(specs[s], dt, np.random.default_rng(r))
                         for s, r in zip(self.sensors, streams)}
        self._rows = [CORNERS.index(c) for c in self.accel_corners]

    def step(self, t, state):
        """Return ``{sensor: reading}`` delivered at this step from a true state."""
        true = {f'accel_{c}': state.body_a[i] for c, i in zip(self.accel_corners, self._rows)}
        true.update({f'travel_{c}': state.travel[i] for i, c in enumerate(CORNERS)})
        return sample_due(self.samplers, t, true)

    def status(self):
        """Return ``{sensor: {samples, lost}}``."""
        return sampler_counts(self.samplers)


def bus_sensor_cluster(dt, cycle_s, seed=1):
    """
    Return the car's chassis sensors as its bus carries them (:class:`FullCarSensors`).

    The four body accelerometers and four ride height sensors of the chassis frames, each
    sampled once every bus cycle ``cycle_s`` [s] on a car stepped every ``dt`` [s], with the
    parts' error models but no latency or dropout of their own (the frames deliver the
    readings; a lost frame is the bus's). The one sensor cluster of the car's bus
    (``CanCarLink``) and of the vehicle chain offline (``simulate_vehicle_chain``).
    """
    rate = 1.0 / float(cycle_s)
    return FullCarSensors(dt, seed, accel_corners=CORNERS,
                          accel=accelerometer_spec(rate_hz=rate, latency_s=0.0, dropout_prob=0.0),
                          travel=ride_height_spec(rate_hz=rate, latency_s=0.0, dropout_prob=0.0))
