"""
The car's damper force from a virtual rig in the same process (hardware in the loop, no ROS).

The rig side of :mod:`quarter_car_sim.runtime.hil` (which holds the car side: delay compensation,
:class:`quarter_car_sim.runtime.hil.RemoteRigPlant` and ``run_loop``). A study that combines the
rig and the car, so it lives above both (in bringup): ``mr_damper_model <- quarter_car_sim`` and
``mr_damper_model <- mr_damper_rig``, neither imports the other; this module composes the car's
pieces with the rig's :class:`mr_damper_rig.virtual_rig.VirtualRig`.

- :class:`HilPlant` has the streaming damper-plant interface of
  :class:`quarter_car_sim.plant.quarter_car.QuarterCar` (``step(dt, x, v, i_cmd) -> F``), so the
  one closed loop (:class:`quarter_car_sim.simulate.live_loop.ClosedLoop`) runs unchanged with a
  rig in place of the damper model. Per (sub)step of the car: the car's suspension travel goes
  through the delay compensator and is sent as the displacement command, the rig's actuator
  (:mod:`mr_damper_rig.actuator`) follows it, the true damper is moved by the actuator's actual
  motion and the rig measures force; the measured force goes back to the car
  ``feedback_delay_steps`` samples late.
- :class:`SimulatedLink` is what the ROS 2 nodes do over ``plant:=rig`` (docs/hil.md), in one
  process: :class:`quarter_car_sim.runtime.hil.RemoteRigPlant` and a guarded rig
  (:class:`mr_damper_rig.commands.CommandFollower`) with a message latency.
- :func:`cam_rig_comparison` rates a model the identifier learnt from road-induced motion
  against one learnt on the cam rig; :func:`hil_summary` is the HIL part of a suite summary.
"""
import math

import numpy as np

from mr_damper_model.io.params_file import load_plant
from mr_damper_model.models.plant import make_plant
from mr_damper_rig.actuator import CommandedMotion, ServoActuator
from mr_damper_rig.commands import CommandFollower, DisplacementCommandGuard
from mr_damper_rig.excitation import CamSine, StepSchedule
from mr_damper_rig.virtual_rig import VirtualRig
from quarter_car_sim.runtime.hil import (DelayCompensator, HilError, make_remote_plant,
                                         TrackingMonitor)


class HilPlant:
    """
    Damper-plant interface over a virtual rig driven by displacement commands.

    Parameters
    ----------
    rig : mr_damper_rig.virtual_rig.VirtualRig
        Rig whose excitation is a ``mr_damper_rig.actuator.CommandedMotion``.
    compensator : DelayCompensator or None
        Delay compensation of the command (None: the travel is sent as is).
    feedback_delay_steps : int
        Samples between the rig's force measurement and its use by the car (>= 0).
    adapt_every : int
        Samples between horizon adaptations of the compensator.

    Attributes
    ----------
    current : float
        Measured coil current [A].
    monitor : TrackingMonitor
        Desired (car travel) vs measured (rig) displacement.

    """

    model_name = 'hil'

    def __init__(self, rig, compensator=None, *, feedback_delay_steps=1, adapt_every=100):
        if not isinstance(rig.excitation, CommandedMotion):
            raise HilError('the rig must be driven by a CommandedMotion excitation')
        if int(feedback_delay_steps) != feedback_delay_steps or feedback_delay_steps < 0:
            raise HilError(f'`feedback_delay_steps` must be an integer >= 0, '
                           f'got {feedback_delay_steps}')
        self.rig = rig
        self.compensator = compensator
        self.feedback_delay_steps = int(feedback_delay_steps)
        self.adapt_every = int(adapt_every)
        self.monitor = TrackingMonitor(rig.dt)
        self.params = dict(rig.plant.params)
        self.model_options = dict(rig.plant.model_options)
        self.reset()

    def reset(self):
        """Reset rig, actuator, compensator and monitor; the force queue holds 0 N."""
        self.rig.reset()
        self.rig.excitation.reset()
        if self.compensator is not None:
            self.compensator.reset()
        self.monitor.reset()
        self._queue = [0.0] * self.feedback_delay_steps
        self.current = float(self.rig.plant.current)
        self.last_command_m = 0.0
        self.last_measured_m = 0.0

    def step(self, dt, x, v, i_cmd):
        """
        One rig sample for the car's travel ``x`` [m], velocity ``v`` [m/s], current [A].

        Returns
        -------
        float
            Measured force [N] (resisting extension positive), ``feedback_delay_steps`` old.

        """
        if abs(dt - self.rig.dt) > 1e-9 * self.rig.dt:
            raise HilError(f'car step {dt} s differs from the rig sample interval {self.rig.dt} s')
        if self.compensator is None:
            self.rig.excitation.command(x, v)        # velocity feed-forward of the travel
            u = x
        else:
            u = self.compensator(x)
            self.rig.excitation.command(u)
        self.last_command_m = u
        self.rig.command_current(i_cmd)
        _, xm, _, f, i = self.rig.sample()
        self.last_measured_m = xm
        mon = self.monitor
        mon.update(x, v, xm)
        if self.compensator is not None and mon.n % self.adapt_every == 0:
            self.compensator.adapt(mon.recent_delay_s, self.adapt_every * self.rig.dt)
        self.current = i
        q = self._queue
        q.append(f)
        return q.pop(0)


def make_hil_plant(plant='kwok-current', *, actuator='first', compensation='poly',
                   order=2, adapt_gain=0.0, dt=1e-3, feedback_delay_steps=1,
                   force_noise_n=2.0, daq_bits=16, rng=None, **actuator_options):
    """
    Build a :class:`HilPlant`: true damper on a virtual rig with a servo actuator.

    Parameters
    ----------
    plant : str
        True damper (``mr_damper_model.models.plant.make_plant``).
    actuator : {'first', 'second', 'ideal'}
        Actuator model (``mr_damper_rig.actuator.ServoActuator``).
    compensation : {'poly', 'none'}
        Delay compensation: polynomial extrapolation over the actuator's equivalent delay.
    order, adapt_gain :
        Options of :class:`quarter_car_sim.runtime.hil.DelayCompensator`.
    dt : float
        Rig sample interval = car (sub)step [s].
    feedback_delay_steps : int
        Force feedback delay [samples].
    force_noise_n, daq_bits, rng :
        Rig options (load-cell noise [N], DAQ resolution, noise seed).
    **actuator_options
        ``tau_s``, ``wn_rad_s``, ``zeta``, ``delay_s`` of the actuator.

    Returns
    -------
    HilPlant

    """
    act = ServoActuator(actuator, dt, **actuator_options)
    rig = VirtualRig(make_plant(plant), CommandedMotion(act), sample_rate_hz=1.0 / dt,
                     force_noise_n=force_noise_n, daq_bits=daq_bits, rng=rng)
    if compensation == 'poly':
        comp = DelayCompensator(dt, act.equivalent_delay_s, order=order, adapt_gain=adapt_gain)
    elif compensation == 'none':
        comp = None
    else:
        raise HilError(f"`compensation` must be 'poly' or 'none', got {compensation!r}")
    return HilPlant(rig, comp, feedback_delay_steps=feedback_delay_steps)


class SimulatedLink:
    """
    The car's :class:`quarter_car_sim.runtime.hil.RemoteRigPlant` and a guarded rig in one process.

    A message latency delays the measurements.

    What the ROS 2 nodes do, without ROS (tests and benches): each car step the command goes to
    the rig (:class:`mr_damper_rig.commands.CommandFollower`), the rig takes one sample and
    the measurement reaches the car ``latency_steps`` car steps later (0: before the next step,
    i.e. the force is one sample late as in :class:`HilPlant`).

    Parameters
    ----------
    remote : RemoteRigPlant
        The car's side.
    follower : mr_damper_rig.commands.CommandFollower
        The rig's side (its rig's sample interval should be the car's step).
    latency_steps : int
        Extra car steps a measurement is in flight (>= 0).

    """

    def __init__(self, remote, follower, latency_steps=0):
        if int(latency_steps) != latency_steps or latency_steps < 0:
            raise HilError(f'`latency_steps` must be an integer >= 0, got {latency_steps}')
        self.remote = remote
        self.follower = follower
        self.latency_steps = int(latency_steps)
        self.model_name = remote.model_name
        self.params, self.model_options = remote.params, remote.model_options
        self.reset()

    @property
    def current(self):
        """Coil current the car sees [A] (the latest measured one)."""
        return self.remote.current

    @property
    def monitor(self):
        """The car side's :class:`quarter_car_sim.runtime.hil.TrackingMonitor`."""
        return self.remote.monitor

    @property
    def last_command_m(self):
        """Displacement command of the last step [m]."""
        return self.remote.last_command_m

    @property
    def last_measured_m(self):
        """Latest measured displacement the car has [m]."""
        return self.remote.measured_m

    def reset(self):
        """Reset both sides; nothing in flight."""
        self.remote.reset()
        self.follower.rig.reset()
        self.follower.rig.excitation.reset()
        self._flight = []

    def step(self, dt, x, v, i_cmd):
        """One car step over the link; return the force the car uses [N]."""
        f = self.remote.step(dt, x, v, i_cmd)
        self.follower.rig.command_current(i_cmd)
        self.follower.command(self.remote.last_command_m)
        self._flight.append(self.follower.sample())
        while len(self._flight) > self.latency_steps:
            self.remote.receive(*self._flight.pop(0))
        return f


def make_simulated_link(plant='kwok-current', *, actuator='first', compensation='poly',
                        delay_s=None, order=2, adapt_gain=0.0, latency_steps=0, dt=1e-3,
                        force_noise_n=2.0, daq_bits=16, rng=None, stroke_m=0.08,
                        **actuator_options):
    """
    Build a :class:`SimulatedLink` (true damper ``plant`` on a virtual rig with an actuator).

    ``delay_s`` (initial horizon) defaults to the actuator's equivalent delay plus the latency
    and the one-sample feedback; the other arguments are those of :func:`make_hil_plant` and
    :func:`quarter_car_sim.runtime.hil.make_remote_plant`.
    """
    act = ServoActuator(actuator, dt, **actuator_options)
    rig = VirtualRig(make_plant(plant), CommandedMotion(act), sample_rate_hz=1.0 / dt,
                     force_noise_n=force_noise_n, daq_bits=daq_bits, rng=rng)
    if delay_s is None:
        delay_s = act.equivalent_delay_s + (latency_steps + 1) * dt
    remote = make_remote_plant(dt, compensation=compensation, delay_s=delay_s, order=order,
                               adapt_gain=adapt_gain)
    follower = CommandFollower(rig, DisplacementCommandGuard(stroke_m, center_m=act.x0_m))
    return SimulatedLink(remote, follower, latency_steps)


def _nrmse_percent(params, data):
    """NRMSE [%] (by the measured force range) of kwok-current ``params`` on ``data``."""
    from mr_damper_model.models.kwok_current import kwok_current_force
    with np.errstate(over='ignore', invalid='ignore'):
        f = kwok_current_force(params, data.x, data.v, data.i)
    rmse = float(np.sqrt(np.mean((f - data.f) ** 2)))
    return 100.0 * rmse / float(np.ptp(data.f)) if math.isfinite(rmse) else math.nan


def cam_rig_record(plant='kwok-current', truth_file='', *, levels_a=(0.0, 0.5, 1.0, 1.5, 2.0),
                   hold_s=4 / 1.1, seed=1, noise_n=2.0):
    """
    Record the true damper on the cam rig (1.1 Hz, 30 mm) over a current step schedule.

    Parameters
    ----------
    plant, truth_file : str
        True damper (``mr_damper_model.models.plant.make_plant``): the same as the HIL rig's.
    levels_a : sequence of float
        Coil current levels [A].
    hold_s : float
        Time at each level [s] (4 cam periods).
    seed : int
        Load-cell noise seed.
    noise_n : float
        Load-cell noise standard deviation [N].

    Returns
    -------
    mr_damper_model.io.data.DamperData

    """
    rig = VirtualRig(load_plant(plant, truth_file), CamSine(), StepSchedule(levels_a, hold_s),
                     force_noise_n=noise_n, rng=seed)
    return rig.run()


def cam_rig_comparison(hil_params, plant='kwok-current', truth_file='', *, seed=1,
                       budget_s=None, maxiter=None):
    """
    Identification quality of a HIL-identified model against the cam rig.

    The same true damper is recorded twice on the cam rig (different noise seeds): the first
    record identifies the cam-rig model (``mr_damper_model.identification.identify``,
    kwok-current), the second validates both it and the HIL-identified model.

    Parameters
    ----------
    hil_params : dict
        Kwok-current parameters by name (and ``i_ref_a``) the identifier learnt on the road.
    plant, truth_file : str
        True damper of the HIL run.
    seed : int
        Seed of the records and the swarm.
    budget_s, maxiter : float, int or None
        Compute budget [s] and swarm iterations of the cam-rig identification (None: the
        identifier's defaults; ``maxiter`` alone makes it deterministic).

    Returns
    -------
    dict
        ``hil_nrmse_percent``, ``cam_nrmse_percent`` (both on the validation record),
        ``ratio`` (HIL / cam), ``cam_parameters``, ``record_s``.

    """
    from mr_damper_model.identification.identify import identify
    train = cam_rig_record(plant, truth_file, seed=seed)
    valid = cam_rig_record(plant, truth_file, seed=seed + 1)
    res = identify(train, 'kwok-current', seed=seed, budget_s=budget_s, maxiter=maxiter)
    cam = dict(res.parameters, i_ref_a=float((res.model_options or {}).get('i_ref_a', 2.0)))
    e_hil = _nrmse_percent(hil_params, valid)
    e_cam = _nrmse_percent(cam, valid)
    return {'hil_nrmse_percent': e_hil, 'cam_nrmse_percent': e_cam,
            'ratio': e_hil / e_cam if e_cam > 0 else math.nan,
            'cam_parameters': res.parameters, 'record_s': float(valid.t[-1] - valid.t[0])}


def hil_summary(qc_status, rig_status, identified=None, *, plant='kwok-current',
                truth_file='', maxiter=None):
    """
    Build the hardware-in-the-loop part of a suite summary.

    Parameters
    ----------
    qc_status : dict
        Last status of the quarter-car node (its ``hil`` and ``probe`` entries).
    rig_status : dict
        Last status of the rig node (``displacement_commands``, ``samples_published``).
    identified : dict or None
        Final valid kwok-current parameters of the identifier (None: no comparison).
    plant, truth_file, maxiter :
        See :func:`cam_rig_comparison`.

    Returns
    -------
    dict
        ``tracking_rms_m``, ``tracking_peak_m``, ``travel_rms_m``, ``remaining_delay_s``,
        ``horizon_s``, ``link`` (counts), ``probe``, ``rig_commands``, ``rig_samples``,
        ``identification`` (:func:`cam_rig_comparison` or a note).

    """
    link = (qc_status or {}).get('hil') or {}
    tr = link.get('tracking') or {}
    out = {'tracking_rms_m': tr.get('rms_m'), 'tracking_peak_m': tr.get('peak_m'),
           'remaining_delay_s': tr.get('delay_s'), 'travel_rms_m': link.get('travel_rms_m'),
           'horizon_s': link.get('horizon_s'), 'link': link.get('counts'),
           'probe': (qc_status or {}).get('probe'),
           'rig_commands': (rig_status or {}).get('displacement_commands'),
           'rig_samples': (rig_status or {}).get('samples_published')}
    if identified:
        try:
            out['identification'] = cam_rig_comparison(identified, plant, truth_file,
                                                       maxiter=maxiter)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:
            out['identification'] = {'note': f'no comparison: {exc}'}
    else:
        out['identification'] = {'note': 'no valid identified parameters'}
    return out


def format_hil_summary(h):
    """Return the human-readable lines of :func:`hil_summary` (printed by the launcher)."""
    def mm(value):
        return 'n/a' if value is None else f'{1e3 * value:.2f} mm'
    lines = [f'hil: tracking RMS {mm(h.get("tracking_rms_m"))}, peak '
             f'{mm(h.get("tracking_peak_m"))} (travel RMS {mm(h.get("travel_rms_m"))}), '
             f'remaining delay {mm(h.get("remaining_delay_s")).replace(" mm", " ms")}, '
             f'horizon {mm(h.get("horizon_s")).replace(" mm", " ms")}',
             f'  link {h.get("link")}', f'  rig commands {h.get("rig_commands")}']
    probe = h.get('probe') or {}
    if probe:
        lines.append(f'  probe: {probe.get("covered")}/{probe.get("bins")} bins covered '
                     f'(at {probe.get("covered_s")} s), {probe.get("windows")} windows')
    ident = h.get('identification') or {}
    if 'hil_nrmse_percent' in ident:
        lines.append(f'  identification on a cam-rig record: HIL model NRMSE '
                     f'{ident["hil_nrmse_percent"]:.2f} %, cam-rig model '
                     f'{ident["cam_nrmse_percent"]:.2f} % (ratio {ident["ratio"]:.2f})')
    else:
        lines.append(f'  identification: {ident.get("note")}')
    return '\n'.join(lines)
