"""
The quarter-car control loop, without ROS: car + controller + (supervised) inverse.

:class:`ClosedLoop` is the car's one closed loop: the ROS node runs it supervised, offline
studies (:mod:`quarter_car_sim.simulate.quarter_car`) with a fixed identified inverse. One control
step (period ``dt``, 1 ms by default) of the supervised loop (steps 1-2 are
:class:`semi_active_control.runtime.controller_core.ControllerCore`, shared with the stand-alone
``semi_active_controller_node``):

1. the supervisor (:class:`semi_active_control.supervision.failsafe.ModelSupervisor`) is advanced
to the caller's
   clock; it holds the latest valid, fresh identified Kwok-current parameters or none;
2. with a model: the controller's demanded body force (positive up) is turned into a coil
   current by the inverse of the identified model (the damper model
   force resisting extension is the negative of the body force: the scalar inverse
   ``mr_damper_model.models.inverse.KwokCurrentInverse`` with ``sign_convention='body'``),
   saturated to the coil range;
   without one: the safe current (fail-safe). A passive controller gives a current directly;
3. the quarter car (its plant is the "true" damper, never the identified model) advances by
   ``dt`` with that current held, and the running ride metrics take the new state.

:class:`Pacer` schedules steps against a monotonic clock (real time times a factor, or as fast
as possible) and :class:`TraceLog` streams every step to the run's log file.
"""
from collections import deque
import math
import time

import numpy as np

from mr_damper_common.recording.columnlog import ColumnReader, ColumnWriter
from quarter_car_sim.metrics.quarter_car import RunningRideMetrics
from semi_active_control.runtime.controller_core import ControllerCore


#: time [s] the car runs before the road starts (t = -SETTLE_S .. 0) so that it settles on the
#: damper's static force, as ``quarter_car_sim.simulate.quarter_car.simulate(settle_s=0.5)`` does
SETTLE_S = 0.5

#: columns of the trace log, in order (SI units; ``mode`` 1 = normal, 0 = fail-safe)
TRACE_COLUMNS = ('t', 'z_s', 'v_s', 'a_s', 'z_u', 'v_u', 'a_u', 'z_r', 'travel', 'v_rel',
                 'tyre_force', 'damper_force', 'coil_current', 'i_cmd', 'f_demand', 'mode',
                 'wall', 'compute_s', 'late_s')


class ClosedLoop:
    """
    Controller -> inverse model -> quarter car, one control period of ``dt`` per :meth:`step`.

    The one closed loop of the car (the node, the offline simulation
    ``quarter_car_sim.simulate.quarter_car``, hardware in the loop, benches). Timing of one period:
    the command is computed from the state at ``t_k``, and the car (plant) advances to
    ``t_k + dt`` with that command held. The command stage is one of two cores:

    - with a ``supervisor``: :class:`semi_active_control.runtime.controller_core.ControllerCore`
    (law +
      inverse of the supervisor's active identified parameters + fail-safe, shared with the
      stand-alone controller node), as the car node runs;
    - without: :class:`quarter_car_sim.simulate.live_loop.FixedModelCore` (law + the fixed
      ``inverse``; active laws apply their force directly), as offline studies run.

    Parameters
    ----------
    car : quarter_car_sim.plant.quarter_car.QuarterCar
        Car with its "true" damper plant.
    controller : semi_active_control.laws.Controller or None
        Kind ``'current'`` (commanded as is) or ``'semi-active'`` (body force through the
        inverse model); ``'active'`` only without a supervisor. None (with a supervisor) when
        the command comes from outside (an external controller node): set :attr:`i_cmd` before
        :meth:`advance`.
    supervisor : semi_active_control.supervision.failsafe.ModelSupervisor or None
        Gatekeeper of the identified parameters; holds the safe current and coil range.
    dt : float
        Control period [s].
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse, optional
        Fixed inverse (``sign_convention='body'``) without a supervisor; the car's current
        range ``car.params.i_min`` .. ``i_max`` clips passive currents.
    metrics : object, optional
        Running ride metrics with ``update(state, current, saturated)``.
    inverse_tol_a : float
        Current tolerance [A] of the supervised inverse model.

    Notes
    -----
    A passive controller still reports the supervisor's mode, but its current does not depend
    on the model, so it is commanded in both modes.

    """

    def __init__(self, car, controller, supervisor=None, dt=1e-3, *, inverse=None,
                 metrics=None, inverse_tol_a=1e-4):
        if not dt > 0:
            raise ValueError(f'`dt` must be > 0 s, got {dt}')
        self.car = car
        self.sup = supervisor
        if supervisor is not None:
            self.core = (ControllerCore(controller, supervisor, inverse_tol_a=inverse_tol_a)
                         if controller is not None else None)
            self.i_cmd = supervisor.safe_current_a
        else:
            if controller is None:
                raise ValueError('an external controller needs a `supervisor`')
            self.core = FixedModelCore(controller, inverse, i_min=car.params.i_min,
                                       i_max=car.params.i_max)
            self.i_cmd = math.nan
        self.dt = float(dt)
        self.metrics = metrics
        self.steps = 0

    @property
    def controller(self):
        """Return the control law; None with an external one."""
        return self.core.controller if self.core is not None else None

    @property
    def inverse(self):
        """Fixed inverse model without a supervisor (settable, e.g. on new parameters)."""
        return getattr(self.core, 'inverse', None)

    @inverse.setter
    def inverse(self, value):
        if self.sup is not None:
            raise ValueError('a supervised loop takes its inverse from the supervisor')
        self.core.inverse = value

    @property
    def f_demand(self):
        """Last demanded body force [N] (NaN without a model, passive or external)."""
        return self.core.f_demand if self.core is not None else math.nan

    @property
    def saturated(self):
        """Commands the inverse could not deliver exactly."""
        return self.core.saturated if self.core is not None else 0

    @property
    def last_saturated(self):
        """Whether the last command was saturated (None without a model or external)."""
        return self.core.last_saturated if self.core is not None else None

    def command(self, state, t_clock=0.0):
        """Set and return the next step's coil current [A] (NaN: force applied directly)."""
        self.i_cmd = self.core.command(state, t_clock)
        return self.i_cmd

    def advance(self):
        """Advance the car by ``dt`` with the last command held; return the new state."""
        i = self.i_cmd
        if i == i or self.sup is not None:
            new = self.car.step(self.dt, i)
        else:
            new = self.car.step_force(self.dt, self.core.f_demand)
        self.steps += 1
        if self.metrics is not None:
            self.metrics.update(new, i, self.last_saturated)
        return new

    def step(self, t_clock=0.0):
        """
        Run one control step: command from the current state, then advance the car by ``dt``.

        Parameters
        ----------
        t_clock : float
            Supervisor clock [s] (not used without a supervisor).

        Returns
        -------
        mr_damper_common.contract.CornerState
            State at the end of the step.

        """
        self.command(self.car.state, t_clock)
        return self.advance()


class FixedModelCore:
    """
    One control step with a fixed identified inverse and no supervisor (offline studies).

    The command stage of :class:`quarter_car_sim.simulate.live_loop.ClosedLoop` in
    ``quarter_car_sim.simulate.quarter_car``: a semi-active law's body force goes through
    ``inverse`` (``mr_damper_model.models.inverse.KwokCurrentInverse`` with
    ``sign_convention='body'``) to a current, a passive law's current is clipped to ``[i_min,
    i_max]``, and an active law's force is applied directly (command NaN).

    Parameters
    ----------
    controller : semi_active_control.laws.Controller
        Any kind (``'current'``, ``'semi-active'``, ``'active'``).
    inverse : mr_damper_model.models.inverse.KwokCurrentInverse or None
        Needed for semi-active controllers. May be replaced at any time (``core.inverse``).
    i_min, i_max : float
        Coil current range [A] (passive currents are clipped to it).

    Attributes
    ----------
    i_cmd : float
        Last command [A] (NaN for force-applying controllers and before the first).
    demand : float
        Last controller output: body force [N], or current [A] for a passive law.
    f_demand : float
        Last demanded body force [N] (NaN with a passive law).
    saturated : int
        Commands that could not be delivered exactly.
    last_saturated : bool or None
        Whether the last command was saturated.

    """

    def __init__(self, controller, inverse=None, *, i_min=0.0, i_max=2.0):
        if controller.kind == 'semi-active' and inverse is None:
            raise ValueError(f'controller {controller.name!r} needs an inverse model')
        self.controller = controller
        self.inverse = inverse
        self.i_min, self.i_max = float(i_min), float(i_max)
        self.i_cmd = self.demand = self.f_demand = math.nan
        self.saturated = 0
        self.last_saturated = None

    def demand_command(self, state):
        """
        Demand and command for a state (no bookkeeping: the offline simulation's hot path).

        Returns
        -------
        demand : float
            Controller output (force [N] on the body, or current [A]).
        current_cmd : float
            Current command [A] (NaN for force-applying controllers).
        saturated : bool

        """
        ctl = self.controller
        d = ctl.demand(state)
        kind = ctl.kind
        if kind == 'semi-active':
            i, flag = self.inverse.current(d, state.travel, state.v_rel)
            return d, i, flag != 0
        if kind == 'current':
            i = min(max(d, self.i_min), self.i_max)
            return d, i, i != d
        return d, math.nan, False

    def command(self, state, t_clock=None):
        """Set and return the command [A] for ``state`` (``t_clock`` is not used)."""
        d, i, sat = self.demand_command(state)
        self.demand, self.i_cmd, self.last_saturated = d, i, sat
        self.f_demand = math.nan if self.controller.kind == 'current' else d
        self.saturated += sat
        return i


class Pacer:
    """
    Schedule control steps against a monotonic clock.

    Step ``k`` is due at ``t_start + k * dt / factor``; ``factor = 0`` means as fast as
    possible. After :meth:`wait`, :attr:`lateness` is how late [s] the step started against its
    deadline (a late step is followed by shorter periods until the schedule is caught up).
    More than ``max_burst`` periods behind (machine overloaded), the schedule is re-anchored and
    counted in :attr:`late`: the simulation then falls behind wall time, it never skips physics.

    Parameters
    ----------
    dt : float
        Control period [s] of simulated time.
    factor : float
        Simulated seconds per wall second (1 = real time, 0 = as fast as possible).
    clock : callable
        Monotonic clock [s] (default ``time.monotonic``).

    """

    def __init__(self, dt, factor=1.0, clock=time.monotonic, max_burst=50):
        if not dt > 0:
            raise ValueError(f'`dt` must be > 0 s, got {dt}')
        if not factor >= 0:
            raise ValueError(f'`factor` must be >= 0, got {factor}')
        self.dt = float(dt)
        self.factor = float(factor)
        self.clock = clock
        self.max_burst = int(max_burst)
        self.t_start = clock()
        self.k = 0
        self.late = 0
        self.lateness = 0.0

    def period(self):
        """Return the wall period [s] of one step (0 when as fast as possible)."""
        return self.dt / self.factor if self.factor > 0 else 0.0

    def next_deadline(self):
        """Return the wall time the next step is due."""
        return self.t_start + self.k * self.period()

    def wait(self):
        """Sleep until the next step is due; return the wall time at wake-up."""
        if self.factor > 0:
            delay = self.next_deadline() - self.clock()
            if delay > 0:
                time.sleep(delay)
        now = self.clock()
        self.lateness = now - self.next_deadline() if self.factor > 0 else 0.0
        if self.factor > 0 and now - self.next_deadline() > self.max_burst * self.period():
            # hopelessly behind (machine overloaded): re-anchor instead of bursting forever
            self.late += 1
            self.t_start = now - self.k * self.period()
        self.k += 1
        return now


class TraceLog:
    """
    Per-step log of the loop, streamed to a column log on disk as it runs (flat memory).

    Columns are :data:`TRACE_COLUMNS` (``mr_damper_common.recording.columnlog`` format:
    ``PATH.f64`` rows and ``PATH.json`` header); rows are written in chunks of ``chunk_rows``
    steps, so memory does not grow with the run. :meth:`close` writes the final header (``dt``
    and ``extra``).

    Parameters
    ----------
    path : path
        Log name (``run/quarter_car_log`` -> ``quarter_car_log.f64`` + ``.json``).
    dt : float
        Control period [s], stored in the header.
    chunk_rows : int
        Steps buffered before a write (1,000 steps = 152 kB at 1 kHz: one write a second).

    """

    def __init__(self, path, dt=1e-3, chunk_rows=1000):
        self.path = path
        self._w = ColumnWriter(path, TRACE_COLUMNS, chunk_rows=chunk_rows, meta={'dt': dt})
        self._n_state = TRACE_COLUMNS.index('i_cmd')

    def append(self, state, i_cmd, f_demand, normal, wall, compute_s, late_s=0.0):
        """Append one step."""
        row = [getattr(state, name) for name in TRACE_COLUMNS[:self._n_state]]
        row += (i_cmd, f_demand, 1.0 if normal else 0.0, wall, compute_s, late_s)
        self._w.append(row)

    def __len__(self):
        return len(self._w)

    def close(self, **extra):
        """Write the last rows and the header (with ``extra`` JSON values); idempotent."""
        self._w.close(**extra)

    def arrays(self):
        """Return the columns written so far (short logs: tests, tools)."""
        self._w.flush()
        return ColumnReader(self.path).read()


def timing_stats(values, nominal=None):
    """
    Summarise loop periods or compute times.

    Parameters
    ----------
    values : array_like
        Samples [s].
    nominal : float, optional
        Nominal period [s]; if given, the jitter ``|value - nominal|`` is summarised too.

    Returns
    -------
    dict
        ``n``, ``mean_ms``, ``p50_ms``, ``p99_ms``, ``max_ms`` (and ``jitter_p99_ms``,
        ``jitter_max_ms`` with ``nominal``); NaN when there are no samples.

    """
    a = np.asarray(values, dtype=float)
    out = {'n': int(a.size)}
    if a.size == 0:
        keys = ['mean_ms', 'p50_ms', 'p99_ms', 'max_ms']
        if nominal is not None:
            keys += ['jitter_p99_ms', 'jitter_max_ms']
        out.update({k: math.nan for k in keys})
        return out
    out.update({'mean_ms': 1e3 * float(a.mean()), 'p50_ms': 1e3 * float(np.percentile(a, 50)),
                'p99_ms': 1e3 * float(np.percentile(a, 99)), 'max_ms': 1e3 * float(a.max())})
    if nominal is not None:
        j = np.abs(a - nominal)
        out['jitter_p99_ms'] = 1e3 * float(np.percentile(j, 99))
        out['jitter_max_ms'] = 1e3 * float(j.max())
    return out


def make_running_metrics(car_params, dt=1e-3):
    """Return the core's running ride metrics for this car sampled every ``dt`` [s]."""
    return RunningRideMetrics(1.0 / dt, car_params.static_tyre_load)


def metrics_dict(metrics):
    """Return the running metrics as a plain dict."""
    return dict(metrics.as_dict())


class LoopTiming:
    """
    Rolling statistics of the control loop for the status message.

    Parameters
    ----------
    nominal : float or None
        Nominal wall period [s] (None when running as fast as possible).
    keep : int
        Number of most recent steps summarised.

    """

    def __init__(self, nominal, keep=5000):
        self.nominal = nominal
        self.periods = deque(maxlen=keep)
        self.lateness = deque(maxlen=keep)
        self.latency = deque(maxlen=keep)
        self.step = deque(maxlen=keep)
        self.last = None
        self.n = 0
        self.over_2ms = 0

    def add(self, wall, latency_s, step_s, lateness_s=0.0):
        """
        Add one step.

        Parameters
        ----------
        wall : float
            Wake-up time [s].
        latency_s : float
            Wake-up (state read) -> command published [s].
        step_s : float
            Whole step (command, publish, car step, logging) [s].
        lateness_s : float
            Wake-up time minus the step's deadline [s].

        """
        self.lateness.append(lateness_s)
        if self.last is not None:
            p = wall - self.last
            self.periods.append(p)
            if self.nominal is not None and abs(p - self.nominal) > 2e-3:
                self.over_2ms += 1
        self.last = wall
        self.latency.append(latency_s)
        self.step.append(step_s)
        self.n += 1

    def stats(self):
        """Return ``period`` (with jitter), ``latency`` and ``step`` statistics [ms]."""
        return {'period': timing_stats(list(self.periods), self.nominal),
                'lateness': timing_stats(list(self.lateness)),
                'latency': timing_stats(list(self.latency)),
                'step': timing_stats(list(self.step)),
                'jitter_over_2ms': self.over_2ms, 'steps': self.n}
