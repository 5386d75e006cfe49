"""
Vehicle sensors of a corner by their datasheets: accelerometers and the ride-height sensor.

What a production semi-active suspension measures at a corner, and each sensor's error model
(:class:`SensorSpec`): the estimators are designed on these figures (noise, rate, latency,
offset), the simulator samples the true state with them
(:class:`quarter_car_sim.plant.sensors.SensorSampler`):

- the **body accelerometer** at the corner (vertical specific force, gravity included, as a
  ``sensor_msgs/Imu`` reports it: +9.81 m/s^2 at rest);
- optionally a **wheel accelerometer** (same model, on the hub);
- the **suspension position (ride-height) sensor**: suspension travel ``z_s - z_u`` [m],
  extension positive, zero at static equilibrium.

Error model of one sensor (:class:`SensorSpec`), applied in this order to the true value ``x``
at each sample time ``t_j = j / rate_hz``::

    y = (1 + scale_error) (x + offset) + b(t) + n_j,    quantised to ``quantum``,
    b(t) = bias + bias_drift t + random walk (bias_rw [unit/sqrt(s)])

with ``offset`` the constant gravity term (accelerometers) and ``n_j`` white, Gaussian, standard
deviation ``noise_density * sqrt(bandwidth_hz)`` (``bandwidth_hz`` defaults to ``rate_hz / 2``,
the Nyquist band of the output data rate, as ``ADXL313`` datasheet note 3 "Bandwidth is half the
output data rate" states). The sample ``t_j`` is delivered ``latency_s`` later (rounded to whole
control periods by the sampler, :class:`SensorSampler`). A sample is lost with probability
``dropout_prob``: it is delivered as NaN (``dropout_mode='nan'``, a missing frame the receiver
sees) or as the previous value again (``'hold'``, a bus that repeats its last frame). Faults
(:class:`Fault`) are injected over time windows: ``stuck`` (the output freezes), ``dropout`` (NaN),
``bias_step`` (an added offset).

Default figures (:func:`default_specs`) come from datasheets of typical automotive parts:

- body (and wheel) accelerometer: Analog Devices ADXL313 (AEC-Q100 automotive 3-axis MEMS
  accelerometer), z axis: noise density 250 ug/sqrt(Hz); full-resolution sensitivity
  1024 LSB/g (quantum 1/1024 g = 9.58e-3 m/s^2), sensitivity tolerance 921-1126 LSB/g (the
  scale error, 1 % left after an end-of-line calibration is used here); 0 g offset tempco
  +-0.75 mg/degC (bias: 15 mg, a 20 degC change after calibration, as the default standard
  deviation of the turn-on bias); output data rate up to 3200 Hz, read at the 1 kHz control
  rate; group delay and bus transfer: 1 ms latency;
- ride-height sensor: Bourns non-contacting chassis level sensor (AMR angle sensor with a lever,
  the ECAS / active-suspension part): 12 bit over an electrical range of +-50 deg, accuracy /
  resolution 0.05 deg, update rate < 1 ms. Mapped to +-0.1 m of travel by the lever: quantum
  0.2 m / 4096 = 4.9e-5 m, noise 0.05 deg = 0.1 mm taken as 2 standard deviations (0.05 mm at
  the 500 Hz band: 2.2e-6 m/sqrt(Hz)), latency 1 ms.
"""
import dataclasses
import math

#: Standard gravity [m/s^2].
G0 = 9.80665

#: Sensor names of a corner.
SENSOR_NAMES = ('body_accel', 'wheel_accel', 'travel')

#: Fault kinds of :class:`Fault`.
FAULT_KINDS = ('stuck', 'dropout', 'bias_step')

DROPOUT_MODES = ('nan', 'hold')


class SensorError(ValueError):
    """Invalid sensor setting (the message names the setting)."""


@dataclasses.dataclass(frozen=True)
class Fault:
    """
    A fault injected over ``t_start <= t < t_end`` [s] of sample time.

    Attributes
    ----------
    kind : str
        ``'stuck'`` (the output repeats the last value before ``t_start``), ``'dropout'``
        (every sample is NaN), ``'bias_step'`` (``value`` added to the output).
    t_start, t_end : float
        Window [s] (``t_end`` inf: to the end).
    value : float
        Offset of a ``bias_step`` [sensor unit].

    """

    kind: str
    t_start: float
    t_end: float = math.inf
    value: float = 0.0

    def __post_init__(self):
        if self.kind not in FAULT_KINDS:
            raise SensorError(f'`kind` must be one of {", ".join(FAULT_KINDS)}, got '
                              f'{self.kind!r}')
        if not (math.isfinite(self.t_start) and self.t_end > self.t_start):
            raise SensorError(f'fault window needs a finite `t_start` < `t_end`, got '
                              f'{self.t_start} .. {self.t_end}')
        if not math.isfinite(self.value):
            raise SensorError(f'`value` must be finite, got {self.value}')


@dataclasses.dataclass(frozen=True)
class SensorSpec:
    """
    Error model of one sensor (SI units of the measured quantity: m/s^2 or m).

    Attributes
    ----------
    noise_density : float
        White-noise density [unit/sqrt(Hz)].
    rate_hz : float
        Output data rate [Hz].
    bandwidth_hz : float or None
        Noise bandwidth [Hz]; None: ``rate_hz / 2``.
    bias : float
        Turn-on bias [unit]; with ``bias_std`` > 0 a seeded draw is added to it.
    bias_std : float
        Standard deviation of a random turn-on bias [unit] (drawn once per sensor).
    bias_rw : float
        Bias random walk [unit/sqrt(s)].
    bias_drift : float
        Deterministic bias drift [unit/s] (e.g. a warm-up ramp).
    scale_error : float
        Relative sensitivity error [-] (0.01 = reads 1 % high).
    quantum : float
        Quantisation step [unit] (0: none).
    latency_s : float
        Delay from sampling to delivery [s].
    dropout_prob : float
        Probability a sample is lost [-].
    dropout_mode : str
        ``'nan'`` (lost sample delivered as NaN) or ``'hold'`` (the previous value repeated).
    offset : float
        Constant added to the true value before the scale error [unit]: gravity for an
        accelerometer (it reads specific force), 0 for the position sensor.
    faults : tuple of Fault
        Injected faults.

    """

    noise_density: float
    rate_hz: float = 1000.0
    bandwidth_hz: float = None
    bias: float = 0.0
    bias_std: float = 0.0
    bias_rw: float = 0.0
    bias_drift: float = 0.0
    scale_error: float = 0.0
    quantum: float = 0.0
    latency_s: float = 0.0
    dropout_prob: float = 0.0
    dropout_mode: str = 'nan'
    offset: float = 0.0
    faults: tuple = ()

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if f.name in ('bandwidth_hz', 'dropout_mode', 'faults'):
                continue
            v = getattr(self, f.name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise SensorError(f'`{f.name}` must be a finite number, got {v!r}')
        for name in ('noise_density', 'bias_std', 'bias_rw', 'quantum', 'latency_s'):
            if getattr(self, name) < 0:
                raise SensorError(f'`{name}` must be >= 0, got {getattr(self, name)}')
        if not self.rate_hz > 0:
            raise SensorError(f'`rate_hz` must be > 0, got {self.rate_hz}')
        if self.bandwidth_hz is not None and not (
                math.isfinite(self.bandwidth_hz) and self.bandwidth_hz > 0):
            raise SensorError(f'`bandwidth_hz` must be > 0, got {self.bandwidth_hz}')
        if not 0.0 <= self.dropout_prob < 1.0:
            raise SensorError(f'`dropout_prob` must be in [0, 1), got {self.dropout_prob}')
        if self.dropout_mode not in DROPOUT_MODES:
            raise SensorError(f"`dropout_mode` must be 'nan' or 'hold', got "
                              f'{self.dropout_mode!r}')
        if not self.scale_error > -1.0:
            raise SensorError(f'`scale_error` must be > -1, got {self.scale_error}')
        object.__setattr__(self, 'faults', tuple(self.faults))
        for f in self.faults:
            if not isinstance(f, Fault):
                raise SensorError(f'`faults` must hold Fault objects, got {f!r}')

    @property
    def band_hz(self):
        """Noise bandwidth [Hz] actually used."""
        return self.rate_hz / 2.0 if self.bandwidth_hz is None else float(self.bandwidth_hz)

    @property
    def noise_std(self):
        """White-noise standard deviation per sample [unit]: density * sqrt(bandwidth)."""
        return self.noise_density * math.sqrt(self.band_hz)

    @property
    def variance(self):
        """Per-sample error variance of noise plus quantisation (q^2 / 12) [unit^2]."""
        return self.noise_std ** 2 + self.quantum ** 2 / 12.0

    def replace(self, **changes):
        """Return a copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)


def accelerometer_spec(**changes):
    """
    Return the default automotive MEMS accelerometer (ADXL313 z axis, see module docstring).

    Keyword arguments override fields of :class:`SensorSpec`.
    """
    base = dict(noise_density=250e-6 * G0, rate_hz=1000.0, bias_std=15e-3 * G0,
                bias_rw=1e-3, scale_error=0.01, quantum=G0 / 1024.0, latency_s=1e-3,
                dropout_prob=1e-4, offset=G0)
    base.update(changes)
    return SensorSpec(**base)


def ride_height_spec(**changes):
    """
    Return the default ride-height sensor (Bourns chassis level sensor, see module docstring).

    Keyword arguments override fields of :class:`SensorSpec`.
    """
    base = dict(noise_density=5e-5 / math.sqrt(500.0), rate_hz=1000.0, quantum=0.2 / 4096.0,
                latency_s=1e-3, dropout_prob=1e-4)
    base.update(changes)
    return SensorSpec(**base)


def ideal_spec(offset=0.0, rate_hz=1000.0):
    """Return an error-free sensor (no noise, bias, scale error, quantum, latency, loss)."""
    return SensorSpec(noise_density=0.0, rate_hz=rate_hz, offset=offset)


def default_specs(*, wheel_accel=False):
    """
    Return the default sensor set of a corner: ``{name: SensorSpec}``.

    Parameters
    ----------
    wheel_accel : bool
        Also a wheel (hub) accelerometer.

    """
    out = {'body_accel': accelerometer_spec(), 'travel': ride_height_spec()}
    if wheel_accel:
        out['wheel_accel'] = accelerometer_spec()
    return out
