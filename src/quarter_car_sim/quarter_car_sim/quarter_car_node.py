"""
Quarter-car node: a simulated car corner on an MR damper it only knows through the identifier.

``ros2 run quarter_car_sim quarter_car_node --ros-args --params-file suite.yaml``

A control thread runs the ROS-free :class:`quarter_car_sim.live_loop.ClosedLoop` at ``rate_hz``
(1 kHz), paced against the monotonic clock (real time times ``real_time_factor``; 0 = as fast as
possible). Each step: the supervisor (:mod:`quarter_car_sim.failsafe`) says whether the latest
identified parameters may be used; the controller's force goes through their inverse to a coil
current (or the safe current in fail-safe), published on ``current_command``; then the car and
its "true" damper plant advance 1 ms. A dedicated thread with its own deadlines keeps the period
jitter low (an rclpy timer at 1 kHz only delivers 850-990 Hz here); parameter messages, status
and metrics go through the executor in the main thread.

Topics (defaults)
-----------------
- sub ``/mr_damper/kwok_parameters`` (std_msgs/Float64MultiArray, decoded by label;
  reliable, transient local, depth 1);
- pub ``/mr_damper/current_command`` (std_msgs/Float64, A, every control step; reliable, 10);
- pub ``/quarter_car/state`` (sensor_msgs/JointState at ``state_rate_hz``; header.stamp = sim
  time). Joints and fields (SI, positive up, see quarter_car_sim.params):

  ============  ======================  ======================  ==============================
  joint         position                velocity                effort
  ============  ======================  ======================  ==============================
  body          z_s [m]                 v_s [m/s]               a_s body acceleration [m/s^2]
  wheel         z_u [m]                 v_u [m/s]               a_u wheel acceleration [m/s^2]
  suspension    travel z_s - z_u [m]    v_rel [m/s]             damper force on body [N]
  tyre          road height z_r [m]     coil current [A]        tyre load (total, >= 0) [N]
  ============  ======================  ======================  ==============================

- pub ``/quarter_car/ride_metrics`` (std_msgs/String JSON, running ride metrics);
- pub ``/quarter_car/status`` (std_msgs/String JSON: mode normal|failsafe, reason, failsafe_s,
  params accepted / rejected by reason, loop timing, current, sim time, ``dropped`` by reason).

External controller (``controller:=external``): the car is the plant only. It does not take
parameters; each control step it publishes its state on ``car_state_topic``
(mr_damper_interfaces/QuarterCarState; reliable, depth 10), applies the latest current received
on ``command_topic`` (std_msgs/Float64; clamped / refused and counted like the rig's commands,
:class:`quarter_car_sim.controller_core.CommandInput`) and falls back to ``safe_current_a`` when
no command came for ``command_timeout_s`` (counted, logged with throttle, ``mode`` failsafe with
reason ``no_command_yet`` / ``command_timeout`` in the status). With ``lockstep:=true`` it waits
after publishing state k for the first command received after it (at most
``lockstep_timeout_s``, counted) and applies it to step k: the loop is then step for step the
built-in one (docs/controller-node.md).

Hardware in the loop (``plant:=rig``, docs/hil.md): the car has no damper model of its own. Each
control step it publishes the (delay-compensated) suspension travel as the displacement command
on ``displacement_command_topic`` (std_msgs/Float64 [m], reliable, depth 10) and uses the latest
force of the rig's measurement stream (``measurement_topic``, sensor_msgs/JointState as the rig
publishes it; best effort, depth 10: only the newest matters) through
:class:`quarter_car_sim.hil.RemoteRigPlant`; the status carries ``hil`` (tracking RMS / peak of
desired vs measured displacement, link counts). With ``hil_wait_s > 0`` each step first waits (at
most that long, timeouts counted) for the rig's answer to the previous command, so an overloaded
machine slows the loop down instead of letting the car run on stale forces. ``probe:=true`` runs
:class:`quarter_car_sim.probing.CurrentProbe` over the law's current (also in fail-safe, so
the identifier sees every current bin); the status carries ``probe``.

Every publisher is KEEP_LAST (depth 10, latest value topics), so a dead or stalled reader never
blocks the control loop; a ``publish()`` that fails anyway is counted
(``dropped.publish_failed``) and logged, throttled, and the loop goes on. Parameter sets the
middleware reports lost before this node took them count as ``dropped.parameters_lost``.
"""
import json
import math
import os
import sys
import threading
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, String

from mr_damper_model import messages
from mr_damper_model.node_utils import (DropCounter, run_node, set_realtime_priority,
                                        spin_node)
from mr_damper_model.plant import make_plant
from quarter_car_sim import hil, live_loop
from quarter_car_sim.controllers import make_controller
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.probing import CurrentProbe
from quarter_car_sim.road import make_road

STATE_JOINTS = ('body', 'wheel', 'suspension', 'tyre')


def _fmt(state):
    """Return (position, velocity, effort) lists of the state message."""
    return ([state.z_s, state.z_u, state.travel, state.z_r],
            [state.v_s, state.v_u, state.v_rel, state.coil_current],
            [state.a_s, state.a_u, state.damper_force, state.tyre_force])


class QuarterCarNode(Node):
    """
    The quarter-car node (see the module docstring).

    Keyword arguments (e.g. ``context``, ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('quarter_car_node', **node_kwargs)
        d = self._declare
        self.rate_hz = d('rate_hz', 1000.0, 'Control rate [Hz]', (10.0, 10000.0))
        self.rtf = d('real_time_factor', 1.0,
                     'Simulated seconds per wall second (0 = as fast as possible)', (0.0, 1000.0))
        controller = d('controller', 'skyhook', 'Controller name (skyhook, skyhook-onoff, '
                       'groundhook, hybrid, add, passive@<I>A; external = commands from '
                       'command_topic, e.g. semi_active_controller_node)')
        ctrl_opts = d('controller_options', '{}',
                      'JSON keyword options of the controller, e.g. {"c_sky": 3000.0}')
        road_kind = d('road', 'iso8608', 'Road: iso8608, bump, sine, step or file')
        road_class = d('road_class', 'C', 'ISO 8608 class A..H')
        speed = d('speed_m_s', 20.0, 'Vehicle speed [m/s]', (0.1, 100.0))
        seed = d('road_seed', 1, 'Seed of the random road')
        road_repeat = d('road_repeat', False,
                        'Drive the road again and again after its end instead of holding it '
                        'flat (ISO 8608 roads repeat seamlessly; memory stays one road length)')
        road_s = d('road_duration_s', 300.0,
                   'Road length in time [s] (then held flat, or repeated with road_repeat)',
                   (1.0, 36000.0))
        road_file = d('road_file', '', 'CSV road profile (road = file)')
        settle = d('settle_s', live_loop.SETTLE_S,
                   'Time [s] run before the road starts (settling)', (0.0, 60.0))
        plant = d('plant', 'spencer', 'True damper plant (same as the rig): spencer or '
                  'kwok-current; rig = hardware in the loop (the rig node\'s measured force)')
        plant_file = d('truth_file', '',
                       'JSON parameter file of the true damper, as the rig (default: preset)')
        safe = d('safe_current_a', 0.5, 'Coil current in fail-safe [A]', (0.0, 10.0))
        timeout = d('param_timeout_s', 1.0,
                    'Identified parameters older than this [s, wall clock] are stale',
                    (0.01, 3600.0))
        i_min = d('i_min_a', 0.0, 'Coil current minimum [A]', (0.0, 10.0))
        i_max = d('i_max_a', 2.0, 'Coil current maximum [A]', (0.0, 10.0))
        span = d('min_current_span_a', 1.0,
                 'Refuse models identified over a narrower current range [A]', (0.0, 10.0))
        hold = d('hold_on_reject', False,
                 'Keep the model in use when a later message is refused (until stale)')
        self.state_rate_hz = d('state_rate_hz', 100.0, 'State publication rate [Hz]',
                               (0.0, 10000.0))
        status_rate = d('status_rate_hz', 5.0, 'Status and metrics rate [Hz]', (0.1, 100.0))
        self.rt_priority = d('realtime_priority', 0,
                             'SCHED_FIFO priority of the control thread (1..99; 0 = normal '
                             'scheduling); only with real_time_factor > 0, needs CAP_SYS_NICE')
        self.external = controller.strip().lower() == 'external'
        cmd_timeout = d('command_timeout_s', 0.05,
                        'External controller: safe current when no command came for this long '
                        '[s, wall clock]', (0.001, 3600.0))
        self.lockstep = d('lockstep', False,
                          'External controller: wait for the command answering each state')
        self.lockstep_timeout_s = d('lockstep_timeout_s', 1.0,
                                    'Lock-step: longest wait for a command [s, wall clock]',
                                    (0.001, 3600.0))
        self.log_file = d('log_file', '',
                          'Stream every control step to this column log (LOG.f64 rows + '
                          'LOG.json header, mr_damper_model.columnlog; "" = no log)')
        car = {k: d(k, v, doc) for k, v, doc in (
            ('m_s', 300.0, 'Sprung mass [kg]'), ('m_u', 60.0, 'Unsprung mass [kg]'),
            ('k_s', 16000.0, 'Suspension spring [N/m]'),
            ('k_t', 190000.0, 'Tyre stiffness [N/m]'))}
        topics = {k: d(k, v, 'Topic name') for k, v in (
            ('params_topic', '/mr_damper/kwok_parameters'),
            ('command_topic', '/mr_damper/current_command'),
            ('state_topic', '/quarter_car/state'),
            ('car_state_topic', '/quarter_car/car_state'),
            ('status_topic', '/quarter_car/status'),
            ('metrics_topic', '/quarter_car/ride_metrics'))}

        # hardware in the loop (plant rig) and current probing
        hil_topics = {k: d(k, v, 'Topic name (plant rig)') for k, v in (
            ('displacement_command_topic', '/mr_damper/displacement_command'),
            ('measurement_topic', '/mr_damper/measurement'))}
        hil_opts = dict(
            compensation=d('hil_compensation', 'poly', 'plant rig: delay compensation of the '
                           'displacement command, poly (extrapolation) or none'),
            delay_s=d('hil_delay_s', 0.014, 'plant rig: initial compensation horizon [s] '
                      '(actuator lag + transport delay + latency)', (0.0, 0.1)),
            order=d('hil_order', 2, 'plant rig: extrapolation polynomial order 0..3'),
            adapt_gain=d('hil_adapt_gain', 0.0, 'plant rig: adaptation gain of the horizon '
                         '[1/s] (0 = fixed)', (0.0, 100.0)),
            stale_after_s=d('hil_stale_s', 0.05, 'plant rig: measurements older than this [s] '
                            'count the step as stale (the last force is kept)', (0.001, 10.0)))
        self.hil_wait_s = d('hil_wait_s', 0.0, 'plant rig: wait up to this long [s, wall] for '
                            'the rig\'s answer to the last command before the next step (0 = '
                            'never wait: hard real time; > 0: the loop slows down to the rig '
                            'instead of running on stale forces)', (0.0, 1.0))
        probe_on = d('probe', False, 'Probe the least-filled current bin now and then so the '
                     'identifier sees every current (quarter_car_sim.probing)')
        probe_opts = dict(
            bin_a=d('probe_bin_a', 0.1, 'Probe bin width [A] (the identifier\'s current_bin_a)',
                    (0.001, 10.0)),
            period_s=d('probe_period_s', 1.0, 'Time between probe windows [s]', (0.01, 3600.0)),
            hold_s=d('probe_hold_s', 0.1, 'Probe window length [s]', (0.001, 3600.0)),
            min_samples=d('probe_min_samples', 500, 'Samples a bin needs to count as covered'),
            max_duty=d('probe_max_duty', 0.2, 'Cap of probe_hold_s / probe_period_s',
                       (0.001, 1.0)))

        self.dt = 1.0 / self.rate_hz
        self.car_params = QuarterCarParams(**car)
        self.sup = ModelSupervisor(timeout_s=timeout, safe_current_a=safe, i_min_a=i_min,
                                   i_max_a=i_max, hold_on_reject=hold,
                                   min_current_span_a=span)
        road = make_road(road_kind, road_class=road_class, speed_m_s=speed, rng=int(seed),
                         duration_s=road_s, dt=self.dt, file=road_file, repeat=road_repeat)
        self.remote = (hil.make_remote_plant(self.dt, **hil_opts) if plant == 'rig' else None)
        true_plant = self.remote or make_plant(plant, plant_file)
        self.probe = CurrentProbe(i_min, i_max, **probe_opts) if probe_on else None
        self.car = QuarterCar(self.car_params, true_plant, road, t0=-settle)
        self.controller = None if self.external else make_controller(
            controller, params=self.car_params, damper_only=True, **json.loads(ctrl_opts or '{}'))
        self.metrics = live_loop.make_running_metrics(self.car_params, self.dt)
        self.loop = live_loop.ClosedLoop(self.car, self.controller, self.sup, self.dt,
                                         metrics=self.metrics)
        self.trace = live_loop.TraceLog(self.log_file, self.dt) if self.log_file else None
        self.timing = live_loop.LoopTiming(self.dt / self.rtf if self.rtf > 0 else None)
        self.lock = threading.Lock()
        self.answered = threading.Condition(self.lock)   # plant rig: a measurement came
        self.first_normal_t = math.nan

        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.drops = DropCounter(self.get_logger())
        if self.external:
            self._init_external(topics, cmd_timeout, safe, i_min, i_max)
        else:
            self.cmd_pub = self.create_publisher(Float64, topics['command_topic'], 10)
        self.state_pub = self.create_publisher(JointState, topics['state_topic'], 10)
        self.status_pub = self.create_publisher(String, topics['status_topic'], 10)
        self.metrics_pub = self.create_publisher(String, topics['metrics_topic'], 10)
        if not self.external:
            self.drops.subscribe(self, Float64MultiArray, topics['params_topic'],
                                 self.on_params, latched, 'parameters_lost')
        if self.remote is not None:
            self.disp_pub = self.create_publisher(Float64,
                                                  hil_topics['displacement_command_topic'], 10)
            self.drops.subscribe(self, JointState, hil_topics['measurement_topic'],
                                 self.on_measurement, QoSProfile(
                                     depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
                                 'measurements_lost')
        self.create_timer(1.0 / status_rate, self.publish_status)
        self.running = True
        self.failed = None
        self.thread = threading.Thread(target=self.control_loop, name='control', daemon=True)
        self.thread.start()
        if self.external and self.rt_priority > 0 and self.rtf > 0:
            # the commands arrive in the executor and middleware threads: they wake the
            # control thread, so they get its priority too
            set_realtime_priority(int(self.rt_priority), self.get_logger())
        name = self.controller.name if self.controller else 'external controller'
        self.get_logger().info(
            f'{name} at {self.rate_hz:g} Hz (x{self.rtf:g} real time) on {road.name}, plant '
            f'{plant}; fail-safe {safe:g} A, timeout {timeout:g} s')

    def _declare(self, name, default, description, fp_range=None):
        desc = ParameterDescriptor(description=description)
        if fp_range is not None and isinstance(default, float):
            desc.floating_point_range = [FloatingPointRange(
                from_value=fp_range[0], to_value=fp_range[1], step=0.0)]
        return self.declare_parameter(name, default, desc).value

    def _init_external(self, topics, timeout_s, safe_a, i_min_a, i_max_a):
        """Plant only: publish the typed state, take commands (``controller:=external``)."""
        from mr_damper_interfaces.msg import QuarterCarState
        from quarter_car_sim.controller_core import CommandInput
        from quarter_car_sim.semi_active_controller_node import car_state_to_msg, CONTROL_QOS
        self._car_state_to_msg = car_state_to_msg
        self.cmd_in = CommandInput(timeout_s, safe_a, i_min_a, i_max_a)
        self.answered = threading.Event()
        self.lockstep_timeouts = 0
        self.car_state_msg = QuarterCarState()
        self.car_state_msg.header.frame_id = 'quarter_car'
        self.car_state_pub = self.create_publisher(QuarterCarState, topics['car_state_topic'],
                                                   CONTROL_QOS)
        self.cmd_sub = self.drops.subscribe(self, Float64, topics['command_topic'],
                                            self.on_command, CONTROL_QOS, 'commands_lost')

    def _wait_for_controller(self):
        """Lock-step: hold step 0 until the controller's topics are matched both ways."""
        logged = False
        while self.running and not (self.car_state_pub.get_subscription_count() > 0
                                    and self.cmd_sub.get_publisher_count() > 0):
            if not logged:
                self.get_logger().info('lock-step: waiting for the controller to connect')
                logged = True
            time.sleep(0.005)

    def on_command(self, msg):
        """Take one current command of the external controller (checked and counted)."""
        with self.lock:
            outcome = self.cmd_in.offer(msg.data, time.monotonic())
        self.answered.set()
        if outcome != 'accepted':
            self.get_logger().warning(f'current command {msg.data!r} {outcome}',
                                      throttle_duration_sec=1.0)

    def _external_command(self, state, wall):
        """Publish the state, (lock-step: wait for its answer) and return the current [A]."""
        cmd_in = self.cmd_in
        with self.lock:
            normal = not cmd_in.timed_out
            reason = self._external_reason()
        self.answered.clear()
        msg = self._car_state_to_msg(state, self.loop.i_cmd, normal, reason, self.car_state_msg)
        self.drops.publish(self.car_state_pub, msg)
        if self.lockstep and not self.answered.wait(self.lockstep_timeout_s):
            self.lockstep_timeouts += 1
            self.get_logger().warning(
                f'no command within {self.lockstep_timeout_s:g} s of state t = {state.t:.3f} s '
                f'({self.lockstep_timeouts} in all)', throttle_duration_sec=1.0)
        with self.lock:
            was = cmd_in.timeouts
            current = cmd_in.current(time.monotonic() if self.lockstep else wall)
            if cmd_in.timeouts > was:
                self.get_logger().warning(
                    f'no current command for {cmd_in.timeout_s:g} s: safe current '
                    f'{cmd_in.safe_current_a:g} A ({cmd_in.timeouts} time(s))',
                    throttle_duration_sec=1.0)
            return current, not cmd_in.timed_out

    def _external_reason(self):
        if not self.cmd_in.timed_out:
            return 'ok'
        return 'no_command_yet' if self.cmd_in.received_at is None else 'command_timeout'

    # ------------------------------------------------------------------ callbacks
    def on_params(self, msg):
        """Offer a parameter message to the supervisor (decoded by label)."""
        now = time.monotonic()
        try:
            values = messages.array_msg_to_dict(msg)
        except ValueError as exc:
            with self.lock:
                self.sup.refuse('undecodable', str(exc), now)
            self.get_logger().warning(f'undecodable parameters: {exc}',
                                      throttle_duration_sec=1.0)
            return
        with self.lock:
            verdict = self.sup.offer(values, now)
        if not verdict.accepted:
            self.get_logger().warning(f'parameters refused ({verdict.reason}): {verdict.detail}',
                                      throttle_duration_sec=1.0)

    def on_measurement(self, msg):
        """Hand a rig measurement to the remote-rig plant (plant rig)."""
        try:
            sample = messages.measurement_from_msg(msg)
        except ValueError as exc:
            self.drops.count('undecodable_measurement', detail=str(exc))
            return
        with self.answered:
            self.remote.receive(*sample)
            self.answered.notify()

    def control_loop(self):
        """Run the paced control steps until shutdown (control thread)."""
        if self.rt_priority > 0 and self.rtf > 0:
            # the loop sleeps ~95 % of each period, so a real-time priority costs the others
            # nothing but lets it preempt them at its deadlines (jitter on a loaded machine)
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(self.rt_priority)))
            except (AttributeError, OSError) as exc:
                self.get_logger().warning(f'realtime_priority not applied: {exc}')
        every = max(1, int(round(self.rate_hz / self.state_rate_hz))) \
            if self.state_rate_hz > 0 else 0
        cmd = Float64()
        disp = Float64()
        state_msg = JointState()
        state_msg.name = list(STATE_JOINTS)
        loop = self.loop
        try:
            if self.external and self.lockstep:
                self._wait_for_controller()
            pacer = live_loop.Pacer(self.dt, self.rtf)
            while self.running:
                wall = pacer.wait()
                t0 = time.perf_counter()
                if self.external:
                    state = self.car.state
                    cmd.data, normal = self._external_command(state, wall)
                    loop.i_cmd = cmd.data
                else:
                    with self.lock:
                        state = self.car.state
                        cmd.data = loop.command(state, wall)
                        if self.probe is not None:
                            cmd.data = loop.i_cmd = self.probe(cmd.data, state.t)
                        normal = self.sup.mode == 'normal'
                    self.drops.publish(self.cmd_pub, cmd)
                latency = time.perf_counter() - t0
                if self.remote is None:
                    new = loop.advance()
                else:
                    with self.answered:
                        if self.hil_wait_s > 0 and loop.steps > 0:
                            self.remote.count_wait(self.answered.wait_for(
                                lambda: self.remote.answered, self.hil_wait_s))
                        new = loop.advance()
                    disp.data = self.remote.last_command_m
                    self.drops.publish(self.disp_pub, disp)
                if self.probe is not None:
                    self.probe.observe(new.coil_current)
                if normal and math.isnan(self.first_normal_t):
                    self.first_normal_t = state.t
                if every and loop.steps % every == 0:
                    messages.seconds_to_stamp(max(new.t, 0.0), state_msg.header.stamp)
                    state_msg.position, state_msg.velocity, state_msg.effort = _fmt(new)
                    self.drops.publish(self.state_pub, state_msg)
                step_s = time.perf_counter() - t0
                self.timing.add(wall, latency, step_s, pacer.lateness)
                if self.trace is not None:
                    self.trace.append(new, cmd.data, loop.f_demand, normal, wall, latency,
                                      pacer.lateness)
        except Exception as exc:  # noqa: B902 - a publish after shutdown ends the loop
            if self.running and rclpy.ok(context=self.context):
                # a dead control loop must not leave a node that looks alive: end the process
                self.failed = f'{type(exc).__name__}: {exc}'
                self.get_logger().error(f'control loop stopped: {self.failed}')
                rclpy.try_shutdown(context=self.context)

    def status(self):
        """Return the status dict."""
        with self.lock:
            st = self.sup.status()
            st['param_age_s'] = self.sup.age(time.monotonic())
        if self.external:
            with self.lock:
                st.update(self.cmd_in.status(), mode='normal' if not self.cmd_in.timed_out
                          else 'failsafe', reason=self._external_reason(),
                          failsafe_s=self.cmd_in.timeout_s_total,
                          failsafe_entries=self.cmd_in.timeouts, lockstep=self.lockstep,
                          lockstep_timeouts=self.lockstep_timeouts)
        st.update({
            'controller': self.controller.name if self.controller else 'external',
            'current_a': self.loop.i_cmd,
            'coil_current_a': self.car.state.coil_current,
            't_sim': self.car.state.t,
            'steps': self.loop.steps,
            'first_normal_t_sim': self.first_normal_t,
            'saturated_steps': self.loop.saturated,
            'rate_hz': self.rate_hz,
            'real_time_factor': self.rtf,
            'loop': self.timing.stats(),
            'dropped': self.drops.counts(),
        })
        if self.remote is not None:
            with self.lock:
                st['hil'] = self.remote.as_dict()
        if self.probe is not None:
            st['probe'] = self.probe.as_dict()
        return st

    def publish_status(self):
        """Publish status and running ride metrics (executor timer)."""
        self.drops.publish(self.status_pub, messages.status_msg(self.status()))
        if self.metrics is not None:
            self.drops.publish(self.metrics_pub,
                               messages.status_msg(live_loop.metrics_dict(self.metrics)))

    def stop(self):
        """Stop the control thread and write the log file."""
        self.running = False
        self.thread.join(2.0)
        if self.trace is not None:
            try:
                self.trace.close(status=self.status())
                # plain print: after Ctrl-C the context (and /rosout) is already shut down
                print(f'quarter_car_node: wrote {len(self.trace)} steps to {self.log_file}',
                      file=sys.stderr)
            except (OSError, ValueError) as exc:
                print(f'quarter_car_node: cannot write {self.log_file}: {exc}', file=sys.stderr)


def main(args=None):
    """Entry point of ``quarter_car_node``."""
    # short GIL switch interval: the control thread waits at most ~0.5 ms for the executor
    sys.setswitchinterval(0.0005)
    # ValueError, OSError: bad parameter, road or truth file
    # SingleThreadedExecutor: the control thread publishes, the executor only takes parameter
    # sets and runs the status timer (with plant rig also the rig's measurements; with the
    # EventsExecutor here the rig received a fifth of the commands the control thread sent)
    return run_node(QuarterCarNode, 'quarter_car_node', (ValueError, OSError),
                    run=lambda node: spin_node(node, events=False), finish=_finish, args=args)


def _finish(node):
    """Stop the control thread; exit status 1 if the model supervisor failed."""
    node.stop()
    return 1 if node.failed else None


if __name__ == '__main__':
    sys.exit(main())
