"""
The quarter-car node's runtime without ROS: one control step of the simulated car at a time.

The quarter-car node (``quarter_car_node``) declares parameters, converts messages and calls
one :class:`CarRuntime`, as the identifier node calls
:class:`mr_damper_model.live.worker.IdentifierRuntime`. The runtime holds:

- the closed loop (:class:`quarter_car_sim.simulate.live_loop.ClosedLoop`: the car with its "true"
  damper plant, the built-in law, the supervisor of the identified parameters, the running ride
  metrics) and the control thread that steps it
  (:class:`quarter_car_sim.runtime.control_thread.ControlThread`, paced by
  :class:`quarter_car_sim.simulate.live_loop.Pacer`);
- where each step's coil current comes from, one of two:

  - the built-in law through the supervised inverse (fail-safe: the safe current), optionally
    overridden by the current probe (:class:`quarter_car_sim.runtime.probing.CurrentProbe`, also in
    fail-safe, so the identifier sees every current bin);
  - an external controller (:class:`quarter_car_sim.runtime.command_input.CommandInput`: the latest
    command received, or the safe current after ``command_timeout_s``); with ``lockstep`` each
    step publishes its state and waits (at most ``lockstep_timeout_s``, counted) for the first
    command received after it, so the loop is step for step the built-in one;

- the plant: the car's own damper model, or the rig in another process
  (:class:`quarter_car_sim.runtime.hil.RemoteRigPlant`, hardware in the loop; with ``hil_wait_s >
  0`` each step first waits, at most that long, for the rig's answer to the previous command);
- the vehicle sensors of ``sensing:=vehicle``
(:class:`quarter_car_sim.plant.sensors.VehicleSensors`);
- the per-step trace log, the status dict (the values of ``/diagnostics`` and the log file's
  header) and the health rules (:class:`quarter_car_sim.runtime.car_health.CarHealth`).

What goes out goes through the node's :class:`CarOutputs` (command, typed state, joint state,
displacement command, sensor readings, log lines): the runtime says what and when, the node
turns it into messages. Time: ``clock()`` is the node clock (ROS time, so message ages and
timeouts follow ``/clock`` under ``use_sim_time``); the pacing and the bounded waits of
lock-step and hardware in the loop are wall time by nature.
"""
import json
import math
import threading
import time

from quarter_car_sim.runtime import hil
from quarter_car_sim.simulate import live_loop
from semi_active_control.runtime import controller_core
from quarter_car_sim.runtime.control_thread import ControlThread
from quarter_car_sim.runtime.command_input import CommandInput

#: Dynamic parameters applied to the health rules rather than the controller cores.
HEALTH_PARAMETERS = ('lateness_warn_ms',)

#: Shortest time between two warnings of one kind [s, wall clock] (the rest are not logged).
WARN_EVERY_S = 1.0


class CarOutputs:
    """
    What a :class:`CarRuntime` sends out; the node implements it with publishers and its logger.

    Every method is a no-op here (a test records what it needs).
    """

    def publish_command(self, current_a):
        """Publish the coil current command [A] of a step (built-in law)."""

    def publish_car_state(self, state, current_a, normal, reason):
        """Publish the typed state (a ``CornerState``) with its command [A], mode and reason."""

    def publish_state(self, state):
        """Publish the joint state of ``state`` (at the state rate)."""

    def publish_displacement(self, command_m):
        """Publish the rig's displacement command [m] (``plant:=rig``)."""

    def publish_sensors(self, t, readings):
        """Publish the vehicle sensors' readings at car time ``t`` >= 0 [s] (NaN: lost)."""

    def controller_connected(self):
        """Return True once the external controller is matched both ways (lock-step start)."""
        return True

    def rig_connected(self):
        """Return True once the rig's link is matched both ways (``plant:=rig`` start)."""
        return True

    def warn(self, text):
        """Log a warning (the runtime throttles repeated ones: :data:`WARN_EVERY_S`)."""

    def info(self, text):
        """Log an information line."""


class CarRuntime:
    """
    The simulated car of the quarter-car node, one control step per :meth:`step`.

    Parameters
    ----------
    loop : quarter_car_sim.simulate.live_loop.ClosedLoop
        The car, its law (None with an external controller) and the supervisor.
    clock : callable
        ``clock()`` -> now [s] on the node clock (parameter and command ages).
    outputs : CarOutputs
        Where commands, states and log lines go.
    rate_hz : float, optional
        Control rate [Hz] as configured (status; default ``1 / loop.dt``).
    real_time_factor : float
        Simulated seconds per wall second of the pacing (0: as fast as possible).
    priority : int
        SCHED_FIFO priority of the control thread (0: normal; only with a real-time factor).
    command_input : quarter_car_sim.runtime.command_input.CommandInput, optional
        The external controller's commands (``controller:=external``; the loop has no law).
    lockstep : bool
        External controller: wait for the command answering each state.
    lockstep_timeout_s : float
        Longest lock-step wait [s, wall clock].
    probe : quarter_car_sim.runtime.probing.CurrentProbe, optional
        Overrides the law's current in its windows (built-in law).
    remote : quarter_car_sim.runtime.hil.RemoteRigPlant, optional
        The car's plant when it is the rig in another process (hardware in the loop).
    hil_wait_s : float
        With ``remote``: longest wait for the rig's answer before a step [s, wall clock].
    sensors : quarter_car_sim.plant.sensors.VehicleSensors, optional
        Vehicle sensors sampled every step (external controller only).
    state_every : int
        Publish the state every this many steps (0: never).
    trace : quarter_car_sim.simulate.live_loop.TraceLog, optional
        Per-step log.
    health_rules : quarter_car_sim.runtime.car_health.CarHealth, optional
        Level and message of the status.
    make_law : callable, optional
        ``make_law(options)`` -> law of the built-in controller with new options.
    summary : str
        One line saying what runs (logged by the node at start).

    Attributes
    ----------
    lock : threading.Lock
        Held around the supervisor, the command input and the rig link (the executor's
        callbacks and the control thread share them).
    current_a : float
        Coil current command of the last step [A].
    first_normal_t : float
        Car time of the first step in normal mode [s] (nan: none yet).
    lockstep_timeouts : int
        Lock-step waits that ended without a command.

    """

    def __init__(self, loop, clock, outputs, *, rate_hz=None, real_time_factor=1.0, priority=0,
                 command_input=None, lockstep=False, lockstep_timeout_s=1.0, probe=None,
                 remote=None, hil_wait_s=0.0, sensors=None, state_every=0, trace=None,
                 health_rules=None, make_law=None, summary=''):
        if (command_input is None) == (loop.core is None):
            raise ValueError('a car runtime needs a built-in law or a `command_input`, '
                             'not both')
        if sensors is not None and command_input is None:
            raise ValueError('sensing:=vehicle needs controller:=external (the law runs on the '
                             'estimated state, state_estimator_node + '
                             'semi_active_controller_node)')
        self.loop = loop
        self.car = loop.car
        self.sup = loop.sup
        self.metrics = loop.metrics
        self.clock = clock
        self.out = outputs
        self.cmd_in = command_input
        self.external = command_input is not None
        self.lockstep = bool(lockstep)
        self.lockstep_timeout_s = float(lockstep_timeout_s)
        self.probe = probe
        self.remote = remote
        self.hil_wait_s = float(hil_wait_s)
        self.sensors = sensors
        self.every = int(state_every)
        self.trace = trace
        self.health_rules = health_rules
        self.make_law = make_law
        self.summary = summary
        self.rate_hz = 1.0 / loop.dt if rate_hz is None else rate_hz
        self.rtf = float(real_time_factor)
        self.lock = threading.Lock()
        self.answered = threading.Condition(self.lock)   # plant rig: a measurement came
        self._command_came = threading.Event()          # lock-step: the state's command came
        self.lockstep_timeouts = 0
        self.first_normal_t = math.nan
        self.current_a = self.loop.i_cmd
        self.normal = False
        self.new_state = self.car.state
        self._priority_error_logged = False
        self._warned_at = {}
        dt = loop.dt
        # pacing and loop timing: wall clock by nature (keeping pace with real time; jitter)
        self.control = ControlThread(
            self.step, live_loop.Pacer(dt, self.rtf),
            live_loop.LoopTiming(dt / self.rtf if self.rtf > 0 else None),
            after_step=self._after_step,
            before_first=(self._wait_for_controller if self.external and self.lockstep
                          else self._wait_for_rig if remote is not None else None),
            priority=int(priority) if self.rtf > 0 else 0)

    @property
    def dt(self):
        """Control period [s]."""
        return self.loop.dt

    @property
    def failed(self):
        """Why the control thread died (None while it did not)."""
        return self.control.failed

    def start(self, on_error=None):
        """Start the control thread; ``on_error(text)`` when a step raised."""
        self.control.on_error = on_error
        self.control.start()
        return self

    def stop(self, timeout_s=2.0):
        """Stop the control thread (wait up to ``timeout_s`` [s])."""
        self.control.stop(timeout_s)

    # ------------------------------------------------------------------ inputs
    def offer_command(self, current_a):
        """Take one current command of the external controller; return its outcome."""
        now = self.clock()
        with self.lock:
            outcome = self.cmd_in.offer(current_a, now)
        self._command_came.set()
        return outcome

    def receive_measurements(self, columns):
        """Hand rig measurement columns ``(t, x, v, f, i)`` to the remote plant, in order."""
        now = self.clock()
        with self.answered:
            for sample in zip(*columns):   # lockstep: batches of one sample
                self.remote.receive(*sample, now=now)
            self.answered.notify()

    def reconfigure(self, changes):
        """Apply changed dynamic parameters (validated by the cores); '' or the reason."""
        core_changes = {k: v for k, v in changes.items() if k not in HEALTH_PARAMETERS}
        # the new law is built and checked outside the lock the control thread takes every
        # step; only applying it holds the lock
        reason = controller_core.reconfigure(
            core_changes, self.sup, core=self.loop.core,
            make_law=None if self.external else self.make_law,
            command_input=self.cmd_in, lock=self.lock) if core_changes else ''
        if not reason and 'lateness_warn_ms' in changes:
            self.health_rules.lateness_warn_ms = float(changes['lateness_warn_ms'])
        return reason

    # ------------------------------------------------------------------ the step
    def _wait_connected(self, connected, text):
        """Hold step 0 until ``connected()`` (polled every 5 ms); log ``text`` once if not."""
        logged = False
        while self.control.running and not connected():
            if not logged:
                self.out.info(text)
                logged = True
            time.sleep(0.005)

    def _wait_for_controller(self):
        """Lock-step: hold step 0 until the controller's topics are matched both ways."""
        self._wait_connected(self.out.controller_connected,
                             'lock-step: waiting for the controller to connect')

    def _wait_for_rig(self):
        """
        Hardware in the loop: hold step 0 until the rig answered a command.

        The rig opens its command input only once its measurement readers (identifier,
        recorder) matched, so they see the stream from its first sample. Once the link is
        matched both ways, the car sends its neutral command every 5 ms until the rig's first
        answer comes back (a command sent before the rig's reader matched the car's writer is
        not delivered): the first steps then do not wait in vain.
        """
        self._wait_connected(self.out.rig_connected,
                             'hardware in the loop: waiting for the rig to take commands')
        while self.control.running and not self.remote.answered:
            self.out.publish_displacement(self.remote.last_command_m)
            with self.answered:
                self.answered.wait_for(lambda: self.remote.answered, 0.005)

    def _warn(self, kind, text):
        """Log a warning unless one of this kind was logged less than WARN_EVERY_S ago."""
        now = time.monotonic()
        last = self._warned_at.get(kind)
        if last is None or now - last >= WARN_EVERY_S:
            self._warned_at[kind] = now
            self.out.warn(text)

    def _external_reason(self):
        if not self.cmd_in.timed_out:
            return 'ok'
        return 'no_command_yet' if self.cmd_in.received_at is None else 'command_timeout'

    def _external_command(self, state, answered=True):
        """
        Publish the state, (lock-step: wait for its answer) and return the current [A].

        ``answered``: False when nothing the controller acts on went out at this step (the
        sensors before the road starts): lock-step does not wait then.
        """
        cmd_in = self.cmd_in
        with self.lock:
            normal = not cmd_in.timed_out
            reason = self._external_reason()
        self._command_came.clear()
        self.out.publish_car_state(state, self.loop.i_cmd, normal, reason)
        if (self.lockstep and answered
                and not self._command_came.wait(self.lockstep_timeout_s)):
            self.lockstep_timeouts += 1
            self._warn(
                'lockstep',
                f'no command within {self.lockstep_timeout_s:g} s of state t = {state.t:.3f} s '
                f'({self.lockstep_timeouts} in all)')
        now = self.clock()
        with self.lock:
            was = cmd_in.timeouts
            current = cmd_in.current(now)
            timed_out = cmd_in.timeouts > was
            normal = not cmd_in.timed_out
        if timed_out:
            self._warn('command_timeout',
                       f'no current command for {cmd_in.timeout_s:g} s: safe current '
                       f'{cmd_in.safe_current_a:g} A ({cmd_in.timeouts} time(s))')
        return current, normal

    def _command(self):
        """Return (state, current [A], normal, reason) of this step; publish as it goes."""
        loop = self.loop
        if self.external:
            state = self.car.state
            answered = True
            if self.sensors is not None:
                # the estimator's estimate of the readings is what the controller answers
                # (under the lock: a status read in between sees both sensors' counts alike)
                with self.lock:
                    readings = self.sensors.step(state.t, state)
                answered = state.t >= 0.0   # settling before the road: stamps start at 0
                if answered:
                    self.out.publish_sensors(state.t, readings)
            current, normal = self._external_command(state, answered)
            loop.i_cmd = current
            # the car state message is the controller's (not published with the state)
            return state, current, normal, None
        now = self.clock()
        with self.lock:
            state = self.car.state
            current = loop.command(state, now)
            if self.probe is not None:
                current = loop.i_cmd = self.probe(current, state.t)
            # read with the mode: one consistent pair (a refused state wins)
            mode, reason = loop.core.mode_reason()
        self.out.publish_command(current)
        return state, current, mode == 'normal', reason

    def _advance(self):
        """Advance the car one period (plant rig: after the rig's answer, bounded wait)."""
        loop = self.loop
        if self.remote is None:
            return loop.advance()
        with self.answered:
            if self.hil_wait_s > 0 and loop.steps > 0:
                self.remote.count_wait(self.answered.wait_for(
                    lambda: self.remote.answered, self.hil_wait_s))
            new = loop.advance()
        self.out.publish_displacement(self.remote.last_command_m)
        return new

    def step(self, wall=None):
        """
        Run one control period in the control thread: command, publish, advance the car.

        ``wall`` is the pacer's wake-up time [s] (not used). Returns the new ``CornerState``.
        """
        state, current, normal, reason = self._command()
        self.current_a = current
        self.control.command_sent()
        new = self._advance()
        if self.probe is not None:
            self.probe.observe(new.coil_current)
        if normal and math.isnan(self.first_normal_t):
            self.first_normal_t = state.t
        if self.every and self.loop.steps % self.every == 0:
            self.out.publish_state(new)
            if not self.external:
                self.out.publish_car_state(new, current, normal, reason)
        self.normal, self.new_state = normal, new
        return new

    def _after_step(self, wall, latency, lateness):
        if self.trace is not None:
            self.trace.append(self.new_state, self.current_a, self.loop.f_demand, self.normal,
                              wall, latency, lateness)

    # ------------------------------------------------------------------ status
    def status(self, dropped=None):
        """
        Return the status dict (the values of the diagnostics, the log file's header).

        Parameters
        ----------
        dropped : dict, optional
            The node's drop counts (``dropped``).

        Returns
        -------
        dict
            The supervisor's status with ``param_age_s``, ``param_timeout_s``; ``mode``,
            ``reason`` (external: of the command input, with its counts and ``lockstep``,
            ``lockstep_timeouts``; built-in: of the core, with ``state_rejected``);
            ``controller``, ``current_a``, ``coil_current_a``, ``t_sim``, ``steps``,
            ``first_normal_t_sim``, ``saturated_steps``, ``rate_hz``,
            ``realtime_priority_error``, ``real_time_factor``, ``late_reanchors``, ``loop``,
            ``dropped``; ``hil``, ``probe``, ``sensing`` when present.

        """
        now = self.clock()
        priority_error = self.control.priority_error
        if priority_error and not self._priority_error_logged:
            self._priority_error_logged = True
            self.out.warn(f'realtime_priority not applied: {priority_error}')
        with self.lock:
            st = self.sup.status()
            st['param_age_s'] = self.sup.age(now)
            st['param_timeout_s'] = self.sup.timeout_s
            if self.external:
                st.update(self.cmd_in.status(), mode='normal' if not self.cmd_in.timed_out
                          else 'failsafe', reason=self._external_reason(),
                          failsafe_s=self.cmd_in.timeout_s_total,
                          failsafe_entries=self.cmd_in.timeouts, lockstep=self.lockstep,
                          lockstep_timeouts=self.lockstep_timeouts,
                          command_timeout_s=self.cmd_in.timeout_s)
            else:
                st['mode'], st['reason'] = self.loop.core.mode_reason()
                st['state_rejected'] = dict(self.loop.core.state_rejected)
        loop = self.control.status()
        st.update({
            'controller': self.loop.controller.name if self.loop.controller else 'external',
            'current_a': self.loop.i_cmd,
            'coil_current_a': self.car.state.coil_current,
            't_sim': self.car.state.t,
            'steps': self.loop.steps,
            'first_normal_t_sim': self.first_normal_t,
            'saturated_steps': self.loop.saturated,
            'rate_hz': self.rate_hz,
            'realtime_priority_error': priority_error or '',
            'real_time_factor': self.rtf,
            'late_reanchors': loop.pop('late_reanchors'),
            'loop': loop,
            'dropped': dict(dropped or {}),
        })
        if self.remote is not None:
            with self.lock:
                st['hil'] = self.remote.as_dict()
        if self.probe is not None:
            st['probe'] = self.probe.as_dict()
        if self.sensors is not None:
            with self.lock:
                st['sensing'] = self.sensors.status()
        return st

    def health(self, dropped=None):
        """Return the :class:`~mr_damper_common.health.Health` of :meth:`status`."""
        metrics = live_loop.metrics_dict(self.metrics) if self.metrics is not None else None
        return self.health_rules(self.status(dropped), metrics, failed=self.control.failed,
                                 alive=self.control.alive() or not self.control.running)

    def close_log(self, dropped=None):
        """Write the trace log's last rows and its header (the status); return its steps."""
        if self.trace is None:
            return None
        self.trace.close(status=self.status(dropped))
        return len(self.trace)


def make_car_runtime(p, clock, outputs, *, supervisor, controller_options=''):
    """
    Build the car runtime of the quarter-car node from its parameter values.

    Parameters
    ----------
    p : dict
        Parameter values by name (``quarter_car_node.PARAMETERS``).
    clock : callable
        ``clock()`` -> node clock [s].
    outputs : CarOutputs
        The node's outputs.
    supervisor : dict
        Keyword settings of the :class:`~semi_active_control.supervision.failsafe.ModelSupervisor`
        (``timeout_s``, ``safe_current_a``, ``i_min_a``, ``i_max_a``, ``hold_on_reject``,
        ``min_current_span_a``); ``safe_current_a``, ``i_min_a`` and ``i_max_a`` also apply to
        the external controller's commands and the probe.
    controller_options : str
        JSON object of the built-in law's keyword options (gains); not read with an external
        controller.

    Returns
    -------
    CarRuntime

    Raises
    ------
    ValueError
        Bad parameter values (road, law, plant, sensing, probe, command settings).
    OSError
        Unreadable road or truth file.

    """
    from mr_damper_model.io.params_file import load_plant
    from quarter_car_sim.plant.quarter_car import QuarterCar
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from quarter_car_sim.runtime.car_health import CarHealth
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.runtime.probing import CurrentProbe
    from quarter_car_sim.plant.road import make_road
    from quarter_car_sim.plant.sensors import VehicleSensors

    rate_hz = p['rate_hz']
    dt = 1.0 / rate_hz
    external = p['controller'].strip().lower() == 'external'
    car_params = QuarterCarParams(**{k: p[k] for k in ('m_s', 'm_u', 'k_s', 'k_t')})
    sup = ModelSupervisor(**supervisor)
    road = make_road(p['road'], road_class=p['road_class'], speed_m_s=p['speed_m_s'],
                     rng=int(p['road_seed']), duration_s=p['road_duration_s'], dt=dt,
                     file=p['road_file'], repeat=p['road_repeat'])
    plant = p['plant']
    remote = (hil.make_remote_plant(
        dt, compensation=p['hil_compensation'], delay_s=p['hil_delay_s'], order=p['hil_order'],
        adapt_gain=p['hil_adapt_gain'], stale_after_s=p['hil_stale_s'])
        if plant == 'rig' else None)
    true_plant = remote or load_plant(plant, p['truth_file'])
    probe = (CurrentProbe(sup.i_min_a, sup.i_max_a, bin_a=p['probe_bin_a'],
                          period_s=p['probe_period_s'], hold_s=p['probe_hold_s'],
                          min_samples=p['probe_min_samples'], max_duty=p['probe_max_duty'])
             if p['probe'] else None)
    car = QuarterCar(car_params, true_plant, road, t0=-p['settle_s'])

    def make_law(options):
        return controller_core.make_node_law(p['controller'], car_params, rate_hz, options)

    law = None if external else make_law(json.loads(controller_options or '{}'))
    loop = live_loop.ClosedLoop(car, law, sup, dt,
                                metrics=live_loop.make_running_metrics(car_params, dt))
    trace = live_loop.TraceLog(p['log_file'], dt) if p['log_file'] else None
    health_rules = CarHealth(lateness_warn_ms=p['lateness_warn_ms'])
    sensing = p['sensing'].strip().lower()
    if sensing not in ('ideal', 'vehicle'):
        raise ValueError(f"sensing must be 'ideal' or 'vehicle', got {p['sensing']!r}")
    sensors = (VehicleSensors(dt, int(p['sensor_seed']), dropout=(
        p['sensor_dropout_start_s'], p['sensor_dropout_s'])) if sensing == 'vehicle' else None)
    command_input = (CommandInput(
        p['command_timeout_s'], sup.safe_current_a, sup.i_min_a, sup.i_max_a)
        if external else None)
    state_rate_hz = p['state_rate_hz']
    name = law.name if law else 'external controller'
    rtf = p['real_time_factor']
    return CarRuntime(
        loop, clock, outputs, rate_hz=rate_hz, real_time_factor=rtf,
        priority=p['realtime_priority'],
        command_input=command_input, lockstep=p['lockstep'],
        lockstep_timeout_s=p['lockstep_timeout_s'], probe=probe, remote=remote,
        hil_wait_s=p['hil_wait_s'], sensors=sensors,
        state_every=max(1, int(round(rate_hz / state_rate_hz))) if state_rate_hz > 0 else 0,
        trace=trace, health_rules=health_rules, make_law=None if external else make_law,
        summary=f'{name} at {rate_hz:g} Hz (x{rtf:g} real time) on {road.name}, plant '
                f'{plant}; fail-safe {sup.safe_current_a:g} A, timeout {sup.timeout_s:g} s')
