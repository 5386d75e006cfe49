"""
Virtual MR damper test rig: excitation + damper plant + sensors + DAQ.

Sensor model (per DAQ sample, at ``sample_rate_hz``):

* displacement and velocity: the excitation's exact x(t), v(t) (an LVDT and a velocity
  transducer without noise), quantised;
* force: the plant force plus Gaussian load-cell noise of standard deviation
  ``force_noise_n`` [N] (white, independent per sample), quantised;
* current: the actual coil current of the plant (after driver slew and coil lag, as a current
  probe would see it), plus optional Gaussian noise ``current_noise_a``, quantised.

Quantisation: every channel passes a ``daq_bits`` (16) bit bipolar converter whose input span is
the channel's full scale, i.e. the range [-FS/2, FS/2) with a step of FS / 2**bits (for the
defaults: force 4000 N -> 0.061 N, position 0.2 m -> 3.05 um, velocity 2 m/s -> 30.5 um/s,
current 5 A -> 76 uA); values outside are clipped to the end codes (counted in
``clipped_samples``).
"""
import math

import numpy as np

from mr_damper_model.io.params_file import load_plant
from mr_damper_model.models.plant import make_plant
from mr_damper_rig.excitation import CamSine, ExcitationError, StepSchedule


class VirtualRig:
    """
    Simulated damper rig producing DAQ samples (t, x, v, f, i).

    Parameters
    ----------
    plant : DamperPlant or None
        The "true" damper; None: the thesis-like Spencer plant started in steady state
        (internal displacement at the excitation's centre).
    excitation : Excitation or None
        Piston motion; None: cam 1.1 Hz, 30 mm.
    schedule : CurrentSchedule or None
        Coil current command; None: steps 0, 0.5, 1, 1.5, 2 A, 4 cam periods each.
    sample_rate_hz : float
        DAQ rate [Hz].
    force_noise_n : float
        Load-cell noise standard deviation [N].
    force_full_scale_n, position_full_scale_m, velocity_full_scale_m_s, current_full_scale_a :
        float
        DAQ input spans [N], [m], [m/s], [A] (bipolar, centred on 0).
    current_noise_a : float
        Current probe noise standard deviation [A].
    daq_bits : int
        Converter resolution [bits].
    rng : None, int or numpy.random.Generator
        Seed of the noise.

    """

    def __init__(self, plant=None, excitation=None, schedule=None, *, sample_rate_hz=1000.0,
                 force_noise_n=2.0, force_full_scale_n=4000.0, position_full_scale_m=0.2,
                 velocity_full_scale_m_s=2.0, current_full_scale_a=5.0, current_noise_a=0.0,
                 daq_bits=16, rng=None):
        self.excitation = CamSine() if excitation is None else excitation
        self.schedule = StepSchedule() if schedule is None else schedule
        if plant is None:
            plant = make_plant('spencer', y0_m=self.excitation.center_m)
        self.plant = plant
        checks = (('sample_rate_hz', sample_rate_hz, True),
                  ('force_noise_n', force_noise_n, False),
                  ('force_full_scale_n', force_full_scale_n, True),
                  ('position_full_scale_m', position_full_scale_m, True),
                  ('velocity_full_scale_m_s', velocity_full_scale_m_s, True),
                  ('current_full_scale_a', current_full_scale_a, True),
                  ('current_noise_a', current_noise_a, False))
        for name, val, positive in checks:
            val = float(val)
            if not math.isfinite(val) or val < 0 or (positive and val == 0):
                kind = 'positive' if positive else 'non-negative'
                raise ExcitationError(f'`{name}` must be a {kind} number, got {val}')
        if int(daq_bits) != daq_bits or not 2 <= daq_bits <= 32:
            raise ExcitationError(f'`daq_bits` must be an integer in 2..32, got {daq_bits}')
        self.sample_rate_hz = float(sample_rate_hz)
        self.dt = 1.0 / self.sample_rate_hz
        self.force_noise_n = float(force_noise_n)
        self.current_noise_a = float(current_noise_a)
        self.daq_bits = int(daq_bits)
        self.full_scale = {'x': float(position_full_scale_m), 'v': float(velocity_full_scale_m_s),
                           'f': float(force_full_scale_n), 'i': float(current_full_scale_a)}
        self._rng = np.random.default_rng(rng)
        self._command = None
        self.reset()

    def reset(self):
        """Restart at t = 0 (plant reset; the noise generator continues)."""
        self.plant.reset()
        self._k = 0
        self._command = None
        self.clipped_samples = 0

    def quantisation_step(self, channel):
        """DAQ resolution of a channel ('x', 'v', 'f', 'i') [channel unit]."""
        return self.full_scale[channel] / 2 ** self.daq_bits

    def quantise(self, channel, value):
        """
        Convert a value as the DAQ does (round to the nearest code, clip to the span).

        Parameters
        ----------
        channel : {'x', 'v', 'f', 'i'}
            Channel.
        value : float
            Analogue value [channel unit].

        Returns
        -------
        float

        """
        q = self.full_scale[channel] / 2 ** self.daq_bits
        half = 2 ** (self.daq_bits - 1)
        code = round(value / q)
        if code > half - 1 or code < -half:
            self.clipped_samples += 1
            code = min(max(code, -half), half - 1)
        return code * q

    def command_current(self, i_a):
        """Follow an external controller: use ``i_a`` [A] from now on instead of the schedule."""
        i_a = float(i_a)
        if not math.isfinite(i_a):
            raise ExcitationError('commanded current must be finite')
        self._command = i_a

    def sample(self):
        """
        Advance one DAQ period and return the measured sample.

        Returns
        -------
        tuple of float
            (t [s], x [m], v [m/s], f [N], i [A]).

        """
        t = self._k * self.dt
        x, v = self.excitation(t)
        i_cmd = self._command if self._command is not None else self.schedule(t)
        f = self.plant.step(0.0 if self._k == 0 else self.dt, x, v, i_cmd)
        self._k += 1
        if self.force_noise_n > 0:
            f += self.force_noise_n * float(self._rng.standard_normal())
        i = self.plant.current
        if self.current_noise_a > 0:
            i += self.current_noise_a * float(self._rng.standard_normal())
        return (t, self.quantise('x', x), self.quantise('v', v), self.quantise('f', f),
                self.quantise('i', i))

    def run(self, duration_s=None):
        """
        Record ``duration_s`` seconds of samples (default: the schedule's duration).

        Parameters
        ----------
        duration_s : float or None
            Record length [s].

        Returns
        -------
        mr_damper_model.io.data.DamperData

        """
        from mr_damper_model.io.data import DamperData
        if duration_s is None:
            duration_s = self.schedule.duration_s
            if duration_s is None:
                raise ExcitationError('`duration_s` is needed with an open-ended schedule')
        duration_s = float(duration_s)
        if not math.isfinite(duration_s) or duration_s <= 0:
            raise ExcitationError(f'`duration_s` must be positive, got {duration_s}')
        n = int(round(duration_s * self.sample_rate_hz))
        rows = np.array([self.sample() for _ in range(n)])
        return DamperData(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4],
                          source=f'virtual rig ({self.plant.model_name})')

    def true_parameters(self):
        """
        Return the true damper: ``{'model', 'parameters', 'model_options'}``.

        Returns
        -------
        dict

        """
        return {'model': self.plant.model_name, 'parameters': dict(self.plant.params),
                'model_options': dict(self.plant.model_options)}


class RepeatingSchedule:
    """A current schedule started again at the end of each pass (``duration_s`` None)."""

    duration_s = None

    def __init__(self, schedule):
        self._schedule = schedule
        self._period = float(schedule.duration_s)

    def __call__(self, t):
        return self._schedule(t % self._period)


def build_virtual_rig(options):
    """
    Build the virtual rig from the rig node's sim options (its parameters of the same names).

    Parameters
    ----------
    options : dict
        ``plant``, ``excitation``, ``amplitude_m``, ``frequency_hz``, ``currents_a``,
        ``step_s``, ``current_source``, ``noise_n``, ``seed``, ``rate_hz``, ``truth_file``;
        with ``excitation`` ``'commanded'`` also ``actuator``, ``actuator_tau_s``,
        ``actuator_wn_rad_s``, ``actuator_zeta``, ``actuator_delay_s``.

    Returns
    -------
    VirtualRig

    """
    from . import excitation as exc_mod
    plant = load_plant(options['plant'], options['truth_file'])     # '' : the preset truth
    if options['excitation'] == 'commanded':
        from .actuator import CommandedMotion, ServoActuator
        excitation = CommandedMotion(ServoActuator(
            options['actuator'], 1.0 / options['rate_hz'], tau_s=options['actuator_tau_s'],
            wn_rad_s=options['actuator_wn_rad_s'], zeta=options['actuator_zeta'],
            delay_s=options['actuator_delay_s']))
    else:
        excitation = exc_mod.make_excitation(options['excitation'],
                                             amplitude_m=options['amplitude_m'],
                                             frequency_hz=options['frequency_hz'],
                                             seed=options['seed'])
    if options['current_source'] == 'command':
        schedule = exc_mod.ConstantSchedule(0.0)   # until the first command arrives
    elif options['current_source'] == 'schedule':
        schedule = RepeatingSchedule(exc_mod.step_schedule(options['currents_a'],
                                                           options['step_s']))
    else:
        raise ValueError("current_source must be 'schedule' or 'command', "
                         f"got {options['current_source']!r}")
    return VirtualRig(plant, excitation, schedule, sample_rate_hz=options['rate_hz'],
                      force_noise_n=options['noise_n'], rng=options['seed'])


RIG_CURRENTS_A = (0.0, 0.5, 1.0, 1.5, 2.0)
"""Coil current steps of the simulated identification test [A]."""

RIG_EXCITATIONS = ((1.1, 0.03), (3.0, 0.015))
"""(frequency [Hz], amplitude [m]) of the simulated identification test: the thesis cam
(1.1 Hz, 30 mm, peak 0.21 m/s) and a faster one (3 Hz, 15 mm, peak 0.28 m/s) that covers the
piston velocities of a class C road at 20 m/s better."""


def simulated_rig_data(plant, *, seed=0, periods=4):
    """
    Simulate an identification test of a damper plant on the virtual rig.

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
    mr_damper_model.io.data.DamperData

    """
    from mr_damper_model.io.data import DamperData
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

    Uses :func:`simulated_rig_data` and ``mr_damper_model.identification.identify.identify``.

    Returns
    -------
    dict
        Parameter-file dictionary (``model``, ``parameters``, ``model_options``, ``metrics``,
        ``seed``, ``source``, ...) as accepted by
        ``quarter_car_sim.simulate.quarter_car.make_inverse``.

    """
    from mr_damper_model.identification.identify import identify
    data = simulated_rig_data(plant, seed=seed)
    res = identify(data, 'kwok-current', seed=seed, budget_s=budget_s,
                   model_options={'i_ref_a': 2.0})
    d = res.to_json_dict()
    d['source'] = data.source
    return d
