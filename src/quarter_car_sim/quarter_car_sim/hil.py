"""
Hardware-in-the-loop (real-time hybrid simulation) core: the car's damper force comes from a rig.

:class:`HilPlant` has the streaming damper-plant interface of
:class:`quarter_car_sim.dynamics.QuarterCar` (``step(dt, x, v, i_cmd) -> F``), so the one
closed loop (:class:`quarter_car_sim.live_loop.ClosedLoop`) runs unchanged with a rig in place
of the damper model. Per (sub)step of the car:

1. the car's suspension travel ``x_d`` [m] (desired piston displacement) goes through the delay
   compensator (:class:`DelayCompensator`) and is sent as the displacement command (without
   compensator: with the travel velocity as feed-forward, which only the ideal actuator uses);
2. the rig's actuator (``mr_damper_rig.actuator``) follows it, the true damper is moved by the
   actuator's actual motion and the rig measures force (load-cell noise, DAQ quantisation);
3. the measured force goes back to the car ``feedback_delay_steps`` samples late (1: as over a
   network), and :class:`TrackingMonitor` compares the desired and measured displacement.

Delay compensation: the command is the desired travel extrapolated ``delay_s`` ahead with a
polynomial through the last ``order + 1`` desired samples (Horiuchi et al. 1999). With
``adapt_gain > 0`` the horizon adapts: the tracking monitor's remaining delay (least-squares
``x_m(t) ~ x_d(t - tau)``, i.e. ``tau = sum((x_d - x_m) v_d) / sum(v_d**2)`` with forgetting) is
integrated into the horizon. DanielMaurelE/vRTHS_AMBC_MRdamper (adaptive model-based
compensation, AMBC) instead commands ``a0 x + a1 x' + a2 x'' + a3 x'''`` of the desired
displacement (the inverse of its identified all-pole actuator model, derivatives by backward
differences) and adapts the ``a_i`` online; for a first-order lag that inverse is
``x + tau x'``, which is the first-order extrapolation over ``tau`` used here, and the adapted
horizon plays the role of the adapted ``a1``.
"""
import math

import numpy as np


class HilError(ValueError):
    """Invalid hybrid-simulation settings."""


def _lagrange_weights(order, ahead):
    """Weights ``w``: ``sum(w[j] * x[n - j])`` is the polynomial value ``ahead`` steps on."""
    nodes = -np.arange(order + 1, dtype=float)
    w = np.ones(order + 1)
    for j in range(order + 1):
        for m in range(order + 1):
            if m != j:
                w[j] *= (ahead - nodes[m]) / (nodes[j] - nodes[m])
    return w


class DelayCompensator:
    """
    Polynomial extrapolation of the displacement command over the actuator delay.

    Parameters
    ----------
    dt : float
        Sample interval [s].
    delay_s : float
        Initial compensation horizon [s] (e.g. ``ServoActuator.equivalent_delay_s``).
    order : int
        Polynomial order 0..3 (0: no compensation).
    adapt_gain : float
        Adaptation gain [-] of the horizon per second of data (0: fixed horizon).
    max_delay_s : float
        Cap of the adapted horizon [s].

    """

    def __init__(self, dt, delay_s, *, order=2, adapt_gain=0.0, max_delay_s=0.1):
        if not (math.isfinite(dt) and dt > 0):
            raise HilError(f'`dt` must be > 0 s, got {dt}')
        if int(order) != order or not 0 <= order <= 3:
            raise HilError(f'`order` must be an integer 0..3, got {order}')
        if not (math.isfinite(delay_s) and 0 <= delay_s <= max_delay_s):
            raise HilError(f'`delay_s` must be in [0, max_delay_s], got {delay_s}')
        if not (math.isfinite(adapt_gain) and adapt_gain >= 0):
            raise HilError(f'`adapt_gain` must be >= 0, got {adapt_gain}')
        self.dt = float(dt)
        self.order = int(order)
        self.adapt_gain = float(adapt_gain)
        self.max_delay_s = float(max_delay_s)
        self.delay0_s = float(delay_s)
        self.reset()

    def reset(self):
        """Forget the history and return to the initial horizon."""
        self._hist = []
        self._set_delay(self.delay0_s)

    def _set_delay(self, delay_s):
        self.delay_s = min(max(float(delay_s), 0.0), self.max_delay_s)
        self._w = _lagrange_weights(self.order, self.delay_s / self.dt).tolist()

    def adapt(self, remaining_delay_s, span_s):
        """Move the horizon by ``adapt_gain * span_s * remaining_delay_s`` (span_s [s] of data)."""
        if self.adapt_gain > 0 and math.isfinite(remaining_delay_s):
            self._set_delay(self.delay_s + self.adapt_gain * span_s * remaining_delay_s)

    def __call__(self, x_desired_m):
        """Return the command [m] for the desired displacement ``x_desired_m`` [m] of now."""
        h = self._hist
        h.insert(0, float(x_desired_m))
        if len(h) > self.order + 1:
            h.pop()
        if len(h) <= self.order:
            return h[0]       # start-up: not enough history yet
        return sum(w * x for w, x in zip(self._w, h))


class TrackingMonitor:
    """
    Running tracking error of the rig: desired vs measured displacement.

    Parameters
    ----------
    dt : float
        Sample interval [s].
    forgetting_s : float
        Time constant [s] of the recent remaining-delay estimate.

    """

    def __init__(self, dt, forgetting_s=1.0):
        self.dt = float(dt)
        self._lam = math.exp(-self.dt / float(forgetting_s))
        self.reset()

    def reset(self):
        """Clear the sums."""
        self.n = 0
        self._e2 = 0.0
        self.peak_m = 0.0
        self._ev = 0.0
        self._vv = 0.0
        self._rev = 0.0
        self._rvv = 0.0

    def update(self, x_desired_m, v_desired_m_s, x_measured_m):
        """Add one sample (desired displacement [m] and velocity [m/s], measured [m])."""
        e = x_desired_m - x_measured_m
        self.n += 1
        self._e2 += e * e
        if abs(e) > self.peak_m:
            self.peak_m = abs(e)
        ev = e * v_desired_m_s
        vv = v_desired_m_s * v_desired_m_s
        self._ev += ev
        self._vv += vv
        lam = self._lam
        self._rev = lam * self._rev + ev
        self._rvv = lam * self._rvv + vv

    @property
    def recent_delay_s(self):
        """Remaining delay [s] over the last ``forgetting_s`` (nan without motion)."""
        return self._rev / self._rvv if self._rvv > 0 else math.nan

    def as_dict(self):
        """Return ``rms_m``, ``peak_m``, ``delay_s`` (whole run) and ``n``."""
        return {'rms_m': math.sqrt(self._e2 / self.n) if self.n else math.nan,
                'peak_m': self.peak_m if self.n else math.nan,
                'delay_s': self._ev / self._vv if self._vv > 0 else math.nan,
                'n': self.n}


def tracking_error(x_desired_m, x_measured_m, dt):
    """
    Tracking error of recorded arrays (same definitions as :class:`TrackingMonitor`).

    Parameters
    ----------
    x_desired_m, x_measured_m : array_like with shape (n,)
        Desired and measured displacement [m], same instants.
    dt : float
        Sample interval [s].

    Returns
    -------
    dict
        ``rms_m``, ``peak_m``, ``delay_s`` (least-squares remaining delay), ``n``.

    """
    xd = np.asarray(x_desired_m, dtype=float)
    xm = np.asarray(x_measured_m, dtype=float)
    if xd.shape != xm.shape or xd.ndim != 1 or xd.size < 3:
        raise HilError('`x_desired_m` and `x_measured_m` must be 1-D, same length >= 3')
    mon = TrackingMonitor(dt)
    for a, v, b in zip(xd.tolist(), np.gradient(xd, dt).tolist(), xm.tolist()):
        mon.update(a, v, b)
    return mon.as_dict()


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
        from mr_damper_rig.actuator import CommandedMotion
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
        True damper (``quarter_car_sim.live_loop.make_plant``).
    actuator : {'first', 'second', 'ideal'}
        Actuator model (``mr_damper_rig.actuator.ServoActuator``).
    compensation : {'poly', 'none'}
        Delay compensation: polynomial extrapolation over the actuator's equivalent delay.
    order, adapt_gain :
        Options of :class:`DelayCompensator`.
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
    from mr_damper_rig.actuator import CommandedMotion, ServoActuator
    from mr_damper_rig.virtual_rig import VirtualRig
    from quarter_car_sim.live_loop import make_plant
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


def run_loop(loop, seconds, *, probe=None, t_clock=0.0):
    """
    Run a :class:`quarter_car_sim.live_loop.ClosedLoop` for ``seconds``, optionally probed.

    Parameters
    ----------
    loop : quarter_car_sim.live_loop.ClosedLoop
        The loop (its car has either the damper model or a :class:`HilPlant`).
    seconds : float
        Simulated time [s] (whole steps of ``loop.dt``).
    probe : quarter_car_sim.probing.CurrentProbe or None
        Overrides the law's current inside its probe windows and counts the coil current.
    t_clock : float
        Supervisor clock [s] passed to every step.

    Returns
    -------
    dict of numpy.ndarray
        Per step: ``t`` [s], ``travel`` [m], ``z_s`` [m], ``a_s`` [m/s^2], ``damper_force``
        [N], ``coil_current`` [A], ``i_cmd`` [A]; with a :class:`HilPlant`, also
        ``command`` [m] (the rig's displacement command) and ``measured`` [m] (its measured
        displacement).

    """
    n = int(round(seconds / loop.dt))
    car = loop.car
    hil_plant = car.plant if isinstance(car.plant, HilPlant) else None
    keys = ('t', 'travel', 'z_s', 'a_s', 'damper_force', 'coil_current')
    rows = np.full((n, len(keys) + 3), math.nan)
    for k in range(n):
        i_law = loop.command(car.state, t_clock)
        if probe is not None:
            loop.i_cmd = probe(i_law, car.t)
        s = loop.advance()
        if probe is not None:
            probe.observe(s.coil_current)
        rows[k, :len(keys)] = (s.t, s.travel, s.z_s, s.a_s, s.damper_force, s.coil_current)
        rows[k, -3] = loop.i_cmd
        if hil_plant is not None:
            rows[k, -2] = hil_plant.last_command_m
            rows[k, -1] = hil_plant.last_measured_m
    out = {key: rows[:, j] for j, key in enumerate(keys)}
    out['i_cmd'] = rows[:, -3]
    if hil_plant is not None:
        out['command'] = rows[:, -2]
        out['measured'] = rows[:, -1]
    return out
