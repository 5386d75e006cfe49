"""
Hardware-in-the-loop (real-time hybrid simulation), the car's side: its damper force from a rig.

The car sends its suspension travel as the rig's displacement command and takes the rig's
measured force; per (sub)step of the car:

1. the car's suspension travel ``x_d`` [m] (desired piston displacement) goes through the delay
   compensator (:class:`DelayCompensator`) and is sent as the displacement command (without
   compensator: with the travel velocity as feed-forward, which only the ideal actuator uses);
2. the rig's actuator follows it, the true damper is moved by the actuator's actual motion and
   the rig measures force (load-cell noise, DAQ quantisation);
3. the measured force goes back to the car (at least one sample late), and
   :class:`TrackingMonitor` compares the desired and measured displacement.

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

Over ROS 2 (``plant:=rig``, docs/hil.md) the rig is another process: :class:`RemoteRigPlant` has
the damper-plant interface of :class:`quarter_car_sim.plant.quarter_car.QuarterCar`, takes the
rig's measurements as they arrive (:meth:`RemoteRigPlant.receive`) and leaves the (compensated)
displacement command for the node to publish after each step; the force the car uses is the
latest measured one, at least one rig sample old. The rig's clock and the car's are both paced
in real time, so the compensator's horizon (adapted online) covers the actuator's lag plus the
message latency. A rig in the same process (``HilPlant``, ``SimulatedLink``), the cam-rig
comparison and the suite's HIL summary are the rig's side, ``mr_damper_bringup.car_in_the_loop``:
the car does not import the rig.
"""
import math

import numpy as np

from mr_damper_common.stamps import REBASED, STAMP_REFUSALS, StampGuard
from mr_damper_common.tracking import TrackingMonitor


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
        :meth:`TrackingMonitor.as_dict`: ``rms_m``, ``peak_m``, ``delay_s`` (least-squares
        remaining delay), ``n``, ``non_finite``, ``last_m``.

    """
    xd = np.asarray(x_desired_m, dtype=float)
    xm = np.asarray(x_measured_m, dtype=float)
    if xd.shape != xm.shape or xd.ndim != 1 or xd.size < 3:
        raise HilError('`x_desired_m` and `x_measured_m` must be 1-D, same length >= 3')
    mon = TrackingMonitor(dt)
    for a, v, b in zip(xd.tolist(), np.gradient(xd, dt).tolist(), xm.tolist()):
        mon.update(a, v, b)
    return mon.as_dict()


def run_loop(loop, seconds, *, probe=None, t_clock=0.0):
    """
    Run a :class:`~quarter_car_sim.simulate.live_loop.ClosedLoop` for ``seconds`` (maybe probed).

    Parameters
    ----------
    loop : quarter_car_sim.simulate.live_loop.ClosedLoop
        The loop (its car has the damper model or a rig in the loop:
        ``mr_damper_bringup.car_in_the_loop.HilPlant`` or ``SimulatedLink``).
    seconds : float
        Simulated time [s] (whole steps of ``loop.dt``).
    probe : quarter_car_sim.runtime.probing.CurrentProbe or None
        Overrides the law's current inside its probe windows and counts the coil current.
    t_clock : float
        Supervisor clock [s] passed to every step.

    Returns
    -------
    dict of numpy.ndarray
        Per step: ``t`` [s], ``travel`` [m], ``z_s`` [m], ``a_s`` [m/s^2], ``damper_force``
        [N], ``coil_current`` [A], ``i_cmd`` [A]; with a rig in the loop, also
        ``command`` [m] (the rig's displacement command) and ``measured`` [m] (its measured
        displacement).

    """
    n = int(round(seconds / loop.dt))
    car = loop.car
    # a rig in the same process reports its last command and measured displacement
    hil_plant = car.plant if hasattr(car.plant, 'last_measured_m') else None
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


#: Counter keys of :attr:`RemoteRigPlant.counts`.
REMOTE_COUNTS = ('measurements', 'gaps', 'out_of_order', 'duplicate', 'future_stamp',
                 'stamp_rebases', 'non_finite', 'no_measurement_steps', 'stale_steps',
                 'wait_timeouts')


class RemoteRigPlant:
    """
    Damper-plant interface over a rig in another process (measurements in, commands out).

    Parameters
    ----------
    dt : float
        Car step [s] (also the expected rig sample interval, for gap counting).
    compensator : DelayCompensator or None
        Delay compensation of the displacement command (None: the travel is sent as is).
    stale_after_s : float
        A measurement older than this [s of car time] counts the step as stale
        (``stale_steps``); the car keeps using the last measured force.
    adapt_every : int
        Car steps between horizon adaptations of the compensator.
    forgetting_s : float
        Time constant [s] of the tracking monitor's recent-delay estimate.
    max_future_s, rebase_after :
        Stamp checks of the measurements (:class:`mr_damper_common.stamps.StampGuard`): a
        measurement stamped more than ``max_future_s`` [s] ahead of the car's clock is refused
        (``future_stamp``); ``rebase_after`` consecutive out-of-order (or future) ones
        increasing among themselves re-base the stamps (a rig clock jump, ``stamp_rebases``).

    Attributes
    ----------
    current : float
        Latest measured coil current [A] (0 before the first measurement).
    last_command_m : float
        Displacement command [m] of the last step: what the node publishes.
    monitor : TrackingMonitor
        Desired displacement (the car's travel) vs the latest measured one, every step after
        the first measurement.
    counts : dict
        :data:`REMOTE_COUNTS`: measurements taken, stamp gaps (missing samples), measurements
        refused for their stamp (out of order, duplicate, in the future) or a non-finite value,
        stamp re-bases, steps without any measurement yet (force 0 N),
        steps with a stale one, and waits for the rig that timed out (:meth:`count_wait`).

    """

    model_name = 'hil-remote'
    params = {}
    model_options = {}

    def __init__(self, dt, compensator=None, *, stale_after_s=0.05, adapt_every=100,
                 forgetting_s=1.0, max_future_s=1.0, rebase_after=50):
        if not (math.isfinite(dt) and dt > 0):
            raise HilError(f'`dt` must be > 0 s, got {dt}')
        if not (math.isfinite(stale_after_s) and stale_after_s > 0):
            raise HilError(f'`stale_after_s` must be > 0 s, got {stale_after_s}')
        if int(adapt_every) != adapt_every or adapt_every < 1:
            raise HilError(f'`adapt_every` must be an integer >= 1, got {adapt_every}')
        self.dt = float(dt)
        self.compensator = compensator
        self.stale_steps = max(1, int(round(stale_after_s / self.dt)))
        self.adapt_every = int(adapt_every)
        self.monitor = TrackingMonitor(self.dt, forgetting_s)
        self._stamp_settings = dict(max_future_s=max_future_s, rebase_after=rebase_after)
        StampGuard(**self._stamp_settings)          # validates
        self.reset()

    def reset(self):
        """Forget measurements, counts, compensator history and tracking sums."""
        if self.compensator is not None:
            self.compensator.reset()
        self.monitor.reset()
        self.counts = dict.fromkeys(REMOTE_COUNTS, 0)
        self.stamps = StampGuard(**self._stamp_settings)
        self.current = 0.0
        self.last_command_m = 0.0
        self.measured_m = math.nan
        self.force_n = math.nan
        self.stamp_s = None
        self._age = 0
        self._travel2 = 0.0

    def receive(self, t_s, x_m, v_m_s, f_n, i_a, now=None):
        """
        Take one rig measurement (stamp [s], displacement [m], velocity [m/s], force [N], A).

        ``now``: the car's clock [s] at receipt (the stamp horizon; None: no horizon).

        Returns
        -------
        bool
            False if refused (a non-finite value, or the stamp: out of order, duplicate, in
            the future; counted by reason).

        """
        if not all(math.isfinite(float(a)) for a in (t_s, x_m, v_m_s, f_n, i_a)):
            self.counts['non_finite'] += 1
            return False
        t_s = float(t_s)
        verdict = self.stamps.offer(t_s, now)
        if verdict in STAMP_REFUSALS:
            self.counts[verdict] += 1
            return False
        if verdict == REBASED:
            self.counts['stamp_rebases'] += 1
        elif self.stamp_s is not None:
            step = t_s - self.stamp_s
            missing = int(round(step / self.dt)) - 1
            if missing > 0:
                self.counts['gaps'] += missing
        self.stamp_s = t_s
        self.measured_m = float(x_m)
        self.force_n = float(f_n)
        self.current = float(i_a)
        self.counts['measurements'] += 1
        self._age = 0
        return True

    @property
    def answered(self):
        """True once a measurement came in after the last step (the rig took the command)."""
        return self.stamp_s is not None and self._age == 0

    def count_wait(self, answered):
        """Count the outcome of a bounded wait for :attr:`answered` (False: timed out)."""
        if not answered:
            self.counts['wait_timeouts'] += 1

    def step(self, dt, x, v, i_cmd):
        """
        One car step: set the command for travel ``x`` [m] (velocity ``v`` [m/s]).

        ``i_cmd`` [A] goes to the rig on its own topic (the node's current command); it is not
        used here.

        Returns
        -------
        float
            The latest measured force [N] (resisting extension positive), 0 N before any.

        """
        u = float(x) if self.compensator is None else self.compensator(x)
        self.last_command_m = u
        if self.stamp_s is None:
            self.counts['no_measurement_steps'] += 1
            return 0.0
        self._age += 1
        if self._age > self.stale_steps:
            self.counts['stale_steps'] += 1
        mon = self.monitor
        mon.update(x, v, self.measured_m)
        self._travel2 += float(x) * float(x)
        if self.compensator is not None and mon.n % self.adapt_every == 0:
            self.compensator.adapt(mon.recent_delay_s, self.adapt_every * self.dt)
        return self.force_n

    def as_dict(self):
        """
        Status of the link.

        Returns
        -------
        dict
            ``tracking`` (:meth:`TrackingMonitor.as_dict`), ``travel_rms_m`` (RMS of the
            desired displacement over the same steps), ``horizon_s`` (compensation horizon,
            nan without compensator), ``last_command_m``, ``counts``.

        """
        n = self.monitor.n
        return {'tracking': self.monitor.as_dict(),
                'travel_rms_m': math.sqrt(self._travel2 / n) if n else math.nan,
                'horizon_s': (self.compensator.delay_s if self.compensator is not None
                              else math.nan),
                'last_command_m': self.last_command_m,
                'counts': dict(self.counts)}


def make_remote_plant(dt=1e-3, *, compensation='poly', delay_s=0.014, order=2, adapt_gain=0.0,
                      stale_after_s=0.05):
    """
    Build a :class:`RemoteRigPlant` with polynomial delay compensation (or none).

    Parameters
    ----------
    dt : float
        Car step [s].
    compensation : {'poly', 'none'}
        Polynomial extrapolation of the command, or the travel as is.
    delay_s : float
        Initial horizon [s]: the actuator's equivalent delay (first order: ``tau_s`` +
        transport delay) plus the expected message latency.
    order, adapt_gain :
        Options of :class:`DelayCompensator`.
    stale_after_s : float
        See :class:`RemoteRigPlant`.

    Returns
    -------
    RemoteRigPlant

    """
    if compensation == 'poly':
        comp = DelayCompensator(dt, delay_s, order=order, adapt_gain=adapt_gain)
    elif compensation == 'none':
        comp = None
    else:
        raise HilError(f"`compensation` must be 'poly' or 'none', got {compensation!r}")
    return RemoteRigPlant(dt, comp, stale_after_s=stale_after_s)
