"""
Quarter-car node: a simulated car corner on an MR damper it only knows through the identifier.

``ros2 run quarter_car_sim quarter_car_node --ros-args --params-file suite.yaml``

A control thread (:class:`quarter_car_sim.control_thread.ControlThread`) runs the ROS-free
:class:`quarter_car_sim.live_loop.ClosedLoop` at ``rate_hz`` (1 kHz), paced against the
monotonic wall clock (real time times ``real_time_factor``; 0 = as fast as possible): a
real-time simulation keeps pace with the wall clock by nature, even under ``use_sim_time``.
Each step: the supervisor (:mod:`quarter_car_sim.failsafe`) says whether the latest identified
parameters may be used; the controller's force goes through their inverse to a coil current (or
the safe current in fail-safe), published on ``mr_damper/current_command``; then the car and its
"true" damper plant advance 1 ms. Parameter messages and ``/diagnostics`` go through the
executor in the main thread. Ages and timeouts of messages (parameter age and timeout, command
timeout) are on the node's clock: ROS time, so they follow ``/clock`` under ``use_sim_time``.

Topics (relative: remap with ``--ros-args -r old:=new`` or run in a namespace)
-----------------------------------------------------------------------------
- sub ``mr_damper/kwok_parameters`` (mr_damper_interfaces/KwokParameters; reliable,
  transient local, depth 1);
- pub ``mr_damper/current_command`` (std_msgs/Float64, A, every control step; reliable, 10);
- pub ``quarter_car/state`` (sensor_msgs/JointState at ``state_rate_hz``; header.stamp = sim
  time). Joints and fields (SI, positive up, see quarter_car_sim.params):

  ============  ======================  ======================  ==============================
  joint         position                velocity                effort
  ============  ======================  ======================  ==============================
  body          z_s [m]                 v_s [m/s]               a_s body acceleration [m/s^2]
  wheel         z_u [m]                 v_u [m/s]               a_u wheel acceleration [m/s^2]
  suspension    travel z_s - z_u [m]    v_rel [m/s]             damper force on body [N]
  tyre          road height z_r [m]     coil current [A]        tyre load (total, >= 0) [N]
  ============  ======================  ======================  ==============================

- pub ``quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState, the same state with
  named fields, current command and fail-safe mode and reason; at ``state_rate_hz``, every
  control step with ``controller:=external``; reliable, depth 10);
- pub ``/diagnostics`` (diagnostic_msgs/DiagnosticArray every ``diagnostics_period_s``, status
  name ``quarter_car_node`` or ``<ns>/quarter_car_node``): level and message from
  :class:`quarter_car_sim.health.CarHealth` (OK normal; WARN fail-safe and why, loop late,
  drops; ERROR control thread died, commands refused persistently); values: mode, reason,
  failsafe_s, failsafe_entries, params_accepted, params_rejected.<reason>, param_age_s,
  current_a, saturated_steps, loop.period / lateness / latency / step statistics [ms],
  late_reanchors, dropped.<reason>, ride_metrics.* (running Wk RMS body acceleration, RMS tyre
  load ratio, travel, ...), hil.* (plant rig: tracking error), probe.* (probe on).

External controller (``controller:=external``): the car is the plant only. It does not take
parameters; each control step it publishes its state on ``quarter_car/car_state``
(mr_damper_interfaces/QuarterCarState; reliable, depth 10), applies the latest current received
on ``mr_damper/current_command`` (std_msgs/Float64; clamped / refused and counted,
:class:`quarter_car_sim.controller_core.CommandInput`) and falls back to ``safe_current_a`` when
no command came for ``command_timeout_s`` (counted, logged with throttle, ``mode`` failsafe with
reason ``no_command_yet`` / ``command_timeout``). With ``lockstep:=true`` it waits after
publishing state k for the first command received after it (at most ``lockstep_timeout_s``,
counted) and applies it to step k: the loop is then step for step the built-in one
(docs/controller-node.md).

Vehicle sensing (``sensing:=vehicle``, with ``controller:=external``): each control step the car
also publishes what a vehicle's sensors give, with the error models of
:class:`quarter_car_sim.sensors.VehicleSensors` (ROS-free): the body accelerometer on
``quarter_car/body_imu`` (sensor_msgs/Imu, ``linear_acceleration.z`` specific force) and the
suspension position on ``quarter_car/suspension_position`` (sensor_msgs/JointState, joint
``suspension``), NaN for a lost sample; its true state moves to ``quarter_car/true_state``
(``state_estimator_node`` publishes ``quarter_car/car_state`` for the controller). An injected
body accelerometer dropout (``sensor_dropout_start_s``, ``sensor_dropout_s``) tests the fail-safe.

Hardware in the loop (``plant:=rig``, docs/hil.md): the car has no damper model of its own. Each
control step it publishes the (delay-compensated) suspension travel as the displacement command
on ``mr_damper/displacement_command`` (std_msgs/Float64 [m], reliable, depth 10) and uses the
latest force of the rig's lockstep link (``mr_damper/hil_measurement``, one DamperSamples sample
per command; best effort, depth 10: only the newest matters) through
:class:`quarter_car_sim.hil.RemoteRigPlant`; the diagnostics carry ``hil`` (tracking RMS / peak
of desired vs measured displacement, link counts). With ``hil_wait_s > 0`` each step first waits
(at most that long, timeouts counted) for the rig's answer to the previous command, so an
overloaded machine slows the loop down instead of letting the car run on stale forces.
``probe:=true`` runs :class:`quarter_car_sim.probing.CurrentProbe` over the law's current (also
in fail-safe, so the identifier sees every current bin); the diagnostics carry ``probe``.

Every publisher is KEEP_LAST (depth 10, latest value topics), so a dead or stalled reader never
blocks the control loop; a ``publish()`` that fails anyway is counted
(``dropped.publish_failed``) and logged, throttled, and the loop goes on. Parameter sets the
middleware reports lost before this node took them count as ``dropped.parameters_lost``.
"""
import json
import math
import sys
import threading
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from mr_damper_interfaces.msg import DamperSamples, KwokParameters, QuarterCarState
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from mr_damper_common import messages
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, DropCounter,
                                         LATCHED_QOS, node_time_s, Param, run_node,
                                         set_realtime_priority, spin_node)
from mr_damper_model.models.plant import make_plant
from quarter_car_sim import controller_core, hil, live_loop
from quarter_car_sim.control_thread import ControlThread
from quarter_car_sim.controllers import DAMPER_LAW_NAMES
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.health import CarHealth
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.probing import CurrentProbe
from quarter_car_sim.road import make_road
from quarter_car_sim.semi_active_controller_node import (
    car_state_to_msg, CONTROL_QOS, offer_parameters, SUPERVISED_LAW_PARAMETERS)
from quarter_car_sim.sensors import VehicleSensors

STATE_JOINTS = ('body', 'wheel', 'suspension', 'tyre')

#: The node's parameters (the one place they are declared; docs/nodes.md shows this table).
PARAMETERS = (
    Param('rate_hz', 1000.0, 'Control rate [Hz]', 10.0, 10000.0),
    Param('real_time_factor', 1.0, 'Simulated seconds per wall second (0 = as fast as '
          'possible) [-]', 0.0, 1000.0),
    Param('controller', 'skyhook', f'Controller name ({", ".join(DAMPER_LAW_NAMES)}; '
          'external = commands on mr_damper/current_command, e.g. semi_active_controller_node)'),
) + SUPERVISED_LAW_PARAMETERS + (
    Param('road', 'iso8608', 'Road: iso8608, bump, sine, step or file'),
    Param('road_class', 'C', 'ISO 8608 class A..H'),
    Param('speed_m_s', 20.0, 'Vehicle speed [m/s]', 0.1, 100.0),
    Param('road_seed', 1, 'Seed of the random road [-]', 0, 2 ** 31 - 1),
    Param('road_repeat', False, 'Drive the road again and again after its end instead of '
          'holding it flat (ISO 8608 roads repeat seamlessly; memory stays one road length)'),
    Param('road_duration_s', 300.0, 'Road length in time (then held flat, or repeated with '
          'road_repeat) [s]', 1.0, 36000.0),
    Param('road_file', '', 'CSV road profile (road = file)'),
    Param('settle_s', live_loop.SETTLE_S, 'Time run before the road starts (settling) [s]',
          0.0, 60.0),
    Param('plant', 'spencer', 'True damper plant (same as the rig): spencer or kwok-current; '
          'rig = hardware in the loop (the rig node\'s measured force)'),
    Param('truth_file', '', 'JSON parameter file of the true damper, as the rig (default: '
          'preset)'),
    Param('state_rate_hz', 100.0, 'State publication rate (0 = none) [Hz]', 0.0, 10000.0),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('lateness_warn_ms', 5.0, 'Diagnostics WARN when the control loop\'s lateness p99 '
          'exceeds this [ms, wall clock]', 0.0, 10000.0, dynamic=True),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the control thread (1..99; 0 = normal '
          'scheduling); only with real_time_factor > 0, needs CAP_SYS_NICE [-]', 0, 99),
    Param('command_timeout_s', 0.05, 'External controller: safe current when no command came '
          'for this long [s, node clock]', 0.001, 3600.0, dynamic=True),
    Param('lockstep', False, 'External controller: wait for the command answering each state'),
    Param('lockstep_timeout_s', 1.0, 'Lock-step: longest wait for a command [s, wall clock]',
          0.001, 3600.0),
    Param('log_file', '', 'Stream every control step to this column log (LOG.f64 rows + '
          'LOG.json header, mr_damper_model.io.columnlog; "" = no log)'),
    Param('m_s', 300.0, 'Sprung mass [kg]', 1.0, 1e5),
    Param('m_u', 60.0, 'Unsprung mass [kg]', 0.1, 1e4),
    Param('k_s', 16000.0, 'Suspension spring [N/m]', 1.0, 1e8),
    Param('k_t', 190000.0, 'Tyre stiffness [N/m]', 1.0, 1e9),
    Param('hil_compensation', 'poly', 'plant rig: delay compensation of the displacement '
          'command, poly (extrapolation) or none'),
    Param('hil_delay_s', 0.014, 'plant rig: initial compensation horizon (actuator lag + '
          'transport delay + latency) [s]', 0.0, 0.1),
    Param('hil_order', 2, 'plant rig: extrapolation polynomial order [-]', 0, 3),
    Param('hil_adapt_gain', 0.0, 'plant rig: adaptation gain of the horizon (0 = fixed) '
          '[1/s]', 0.0, 100.0),
    Param('hil_stale_s', 0.05, 'plant rig: measurements older than this count the step as '
          'stale (the last force is kept) [s]', 0.001, 10.0),
    Param('hil_wait_s', 0.0, 'plant rig: wait up to this long for the rig\'s answer to the '
          'last command before the next step (0 = never wait: hard real time; > 0: the loop '
          'slows down to the rig instead of running on stale forces) [s, wall clock]',
          0.0, 1.0),
    Param('probe', False, 'Probe the least-filled current bin now and then so the identifier '
          'sees every current (quarter_car_sim.probing)'),
    Param('probe_bin_a', 0.1, 'Probe bin width (the identifier\'s current_bin_a) [A]',
          0.001, 10.0),
    Param('probe_period_s', 1.0, 'Time between probe windows [s]', 0.01, 3600.0),
    Param('probe_hold_s', 0.1, 'Probe window length [s]', 0.001, 3600.0),
    Param('probe_min_samples', 500, 'Samples a bin needs to count as covered [-]', 1,
          10 ** 9),
    Param('probe_max_duty', 0.2, 'Cap of probe_hold_s / probe_period_s [-]', 0.001, 1.0),
    Param('sensing', 'ideal', 'External controller: ideal (the true state on '
          'quarter_car/car_state) or vehicle (body accelerometer on quarter_car/body_imu, '
          'suspension position on quarter_car/suspension_position, quarter_car_sim.sensors; the '
          'true state on quarter_car/true_state, the estimator publishes car_state)'),
    Param('sensor_seed', 1, 'sensing vehicle: seed of the sensor errors [-]', 0, 2 ** 31 - 1),
    Param('sensor_dropout_start_s', 0.0, 'sensing vehicle: start of an injected body '
          'accelerometer dropout [s, car time]', 0.0, 36000.0),
    Param('sensor_dropout_s', 0.0, 'sensing vehicle: length of the injected dropout (0 = '
          'none) [s]', 0.0, 3600.0),
)

#: Dynamic parameters applied to the health rules rather than the controller cores.
_HEALTH_PARAMETERS = ('lateness_warn_ms',)


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
        self.lock = threading.Lock()
        p = self.p = declare_parameters(self, PARAMETERS, self._on_set)
        self.rate_hz = p['rate_hz']
        self.rtf = p['real_time_factor']
        self.state_rate_hz = p['state_rate_hz']
        self.rt_priority = p['realtime_priority']
        self.external = p['controller'].strip().lower() == 'external'
        self.lockstep = p['lockstep']
        self.lockstep_timeout_s = p['lockstep_timeout_s']
        self.log_file = p['log_file']
        self.hil_wait_s = p['hil_wait_s']
        hil_opts = dict(compensation=p['hil_compensation'], delay_s=p['hil_delay_s'],
                        order=p['hil_order'], adapt_gain=p['hil_adapt_gain'],
                        stale_after_s=p['hil_stale_s'])
        probe_opts = dict(bin_a=p['probe_bin_a'], period_s=p['probe_period_s'],
                          hold_s=p['probe_hold_s'], min_samples=p['probe_min_samples'],
                          max_duty=p['probe_max_duty'])

        self.dt = 1.0 / self.rate_hz
        self.car_params = QuarterCarParams(**{k: p[k] for k in ('m_s', 'm_u', 'k_s', 'k_t')})
        self.sup = ModelSupervisor(timeout_s=p['param_timeout_s'],
                                   safe_current_a=p['safe_current_a'], i_min_a=p['i_min_a'],
                                   i_max_a=p['i_max_a'], hold_on_reject=p['hold_on_reject'],
                                   min_current_span_a=p['min_current_span_a'])
        road = make_road(p['road'], road_class=p['road_class'], speed_m_s=p['speed_m_s'],
                         rng=int(p['road_seed']), duration_s=p['road_duration_s'], dt=self.dt,
                         file=p['road_file'], repeat=p['road_repeat'])
        plant = p['plant']
        self.remote = (hil.make_remote_plant(self.dt, **hil_opts) if plant == 'rig' else None)
        true_plant = self.remote or make_plant(plant, p['truth_file'])
        self.probe = (CurrentProbe(p['i_min_a'], p['i_max_a'], **probe_opts)
                      if p['probe'] else None)
        self.car = QuarterCar(self.car_params, true_plant, road, t0=-p['settle_s'])
        self.controller = None if self.external else self._make_law(
            json.loads(p['controller_options'] or '{}'))
        self.metrics = live_loop.make_running_metrics(self.car_params, self.dt)
        self.loop = live_loop.ClosedLoop(self.car, self.controller, self.sup, self.dt,
                                         metrics=self.metrics)
        self.trace = live_loop.TraceLog(self.log_file, self.dt) if self.log_file else None
        self.answered = threading.Condition(self.lock)   # plant rig: a measurement came
        self.first_normal_t = math.nan
        self.health_rules = CarHealth(lateness_warn_ms=p['lateness_warn_ms'])

        self.drops = DropCounter(self.get_logger())
        self.cmd_in = None
        self.sensors = self._init_sensing(p)
        if self.external:
            self._init_external(p['command_timeout_s'], p['safe_current_a'], p['i_min_a'],
                                p['i_max_a'])
        else:
            self.cmd_pub = self.create_publisher(Float64, 'mr_damper/current_command', 10)
            # the typed state at the state rate (controller:=external: every step, the
            # controller's input, see _init_external)
            self.car_state_msg = QuarterCarState()
            self.car_state_msg.header.frame_id = 'quarter_car'
            self.car_state_pub = self.create_publisher(QuarterCarState, 'quarter_car/car_state',
                                                       10)
        self.state_pub = self.create_publisher(JointState, 'quarter_car/state', 10)
        if not self.external:
            self.drops.subscribe(self, KwokParameters, 'mr_damper/kwok_parameters',
                                 self.on_params, LATCHED_QOS, 'parameters_lost')
        if self.remote is not None:
            self.disp_pub = self.create_publisher(Float64, 'mr_damper/displacement_command', 10)
            self.drops.subscribe(self, DamperSamples, 'mr_damper/hil_measurement',
                                 self.on_measurement, QoSProfile(
                                     depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
                                 'measurements_lost')
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='quarter_car', drops=self.drops)
        self._init_control_thread()
        if self.external and self.rt_priority > 0 and self.rtf > 0:
            # the commands arrive in the executor and middleware threads: they wake the
            # control thread, so they get its priority too
            set_realtime_priority(int(self.rt_priority), self.get_logger())
        name = self.controller.name if self.controller else 'external controller'
        self.get_logger().info(
            f'{name} at {self.rate_hz:g} Hz (x{self.rtf:g} real time) on {road.name}, plant '
            f'{plant}; fail-safe {p["safe_current_a"]:g} A, timeout '
            f'{p["param_timeout_s"]:g} s')

    def _make_law(self, options):
        return controller_core.make_node_law(self.p['controller'], self.car_params,
                                             self.p['rate_hz'], options)

    def _now(self):
        """Node clock [s] (ROS time), for message ages and timeouts."""
        return node_time_s(self)

    def _on_set(self, changes):
        """Apply changed dynamic parameters (validated by the cores); '' or the reason."""
        core_changes = {k: v for k, v in changes.items() if k not in _HEALTH_PARAMETERS}
        # the new law is built and checked outside the lock the control thread takes every
        # step; only applying it holds the lock
        reason = controller_core.reconfigure(
            core_changes, self.sup, core=self.loop.core,
            make_law=None if self.external else self._make_law,
            command_input=self.cmd_in, lock=self.lock) if core_changes else ''
        if not reason and 'lateness_warn_ms' in changes:
            self.health_rules.lateness_warn_ms = float(changes['lateness_warn_ms'])
        return reason

    def _init_external(self, timeout_s, safe_a, i_min_a, i_max_a):
        """Plant only: publish the typed state, take commands (``controller:=external``)."""
        self.cmd_in = controller_core.CommandInput(timeout_s, safe_a, i_min_a, i_max_a)
        self.command_answered = threading.Event()    # lock-step: the state's command came
        self.lockstep_timeouts = 0
        self.car_state_msg = QuarterCarState()
        self.car_state_msg.header.frame_id = 'quarter_car'
        self.car_state_pub = self.create_publisher(
            QuarterCarState, 'quarter_car/true_state' if self.sensors else 'quarter_car/car_state',
            CONTROL_QOS)
        self.cmd_sub = self.drops.subscribe(self, Float64, 'mr_damper/current_command',
                                            self.on_command, CONTROL_QOS, 'commands_lost')

    def _init_sensing(self, p):
        """``sensing:=vehicle``: the sensor publishers and their ROS-free sampler (or None)."""
        sensing = p['sensing'].strip().lower()
        if sensing not in ('ideal', 'vehicle'):
            raise ValueError(f"sensing must be 'ideal' or 'vehicle', got {p['sensing']!r}")
        if sensing == 'ideal':
            return None
        if not self.external:
            raise ValueError('sensing:=vehicle needs controller:=external (the law runs on the '
                             'estimated state, state_estimator_node + '
                             'semi_active_controller_node)')
        sensors = VehicleSensors(self.dt, int(p['sensor_seed']), dropout=(
            p['sensor_dropout_start_s'], p['sensor_dropout_s']))
        self.imu_msg = Imu()
        self.imu_msg.header.frame_id = 'body'
        self.imu_msg.orientation_covariance[0] = -1.0       # no orientation (REP 145)
        self.position_msg = JointState()
        self.position_msg.name = ['suspension']
        self.imu_pub = self.create_publisher(Imu, 'quarter_car/body_imu', CONTROL_QOS)
        self.position_pub = self.create_publisher(JointState, 'quarter_car/suspension_position',
                                                  CONTROL_QOS)
        return sensors

    def _publish_sensors(self, state):
        """Publish the readings the sensors deliver at this step (NaN: a lost sample)."""
        readings = self.sensors.step(state.t, state)
        if state.t < 0.0:
            return          # settling before the road: the time stamps start at 0
        if 'body_accel' in readings:
            messages.seconds_to_stamp(max(state.t, 0.0), self.imu_msg.header.stamp)
            self.imu_msg.linear_acceleration.z = readings['body_accel']
            self.drops.publish(self.imu_pub, self.imu_msg)
        if 'travel' in readings:
            messages.seconds_to_stamp(max(state.t, 0.0), self.position_msg.header.stamp)
            self.position_msg.position = [readings['travel']]
            self.drops.publish(self.position_pub, self.position_msg)

    def _init_control_thread(self):
        self.every = (max(1, int(round(self.rate_hz / self.state_rate_hz)))
                      if self.state_rate_hz > 0 else 0)
        self.cmd = Float64()
        self.disp = Float64()
        self.state_msg = JointState()
        self.state_msg.name = list(STATE_JOINTS)
        self.normal = False
        self.new_state = self.car.state
        # pacing and loop timing: wall clock by nature (keeping pace with real time; jitter)
        self.control = ControlThread(
            self._step, live_loop.Pacer(self.dt, self.rtf),
            live_loop.LoopTiming(self.dt / self.rtf if self.rtf > 0 else None),
            after_step=self._after_step,
            before_first=self._wait_for_controller if self.external and self.lockstep
            else None,
            on_error=self._on_control_error,
            priority=int(self.rt_priority) if self.rtf > 0 else 0)
        self._priority_error_logged = False
        self.control.start()

    def _wait_for_controller(self):
        """Lock-step: hold step 0 until the controller's topics are matched both ways."""
        logged = False
        while self.control.running and not (self.car_state_pub.get_subscription_count() > 0
                                            and self.cmd_sub.get_publisher_count() > 0):
            if not logged:
                self.get_logger().info('lock-step: waiting for the controller to connect')
                logged = True
            time.sleep(0.005)

    def on_command(self, msg):
        """Take one current command of the external controller (checked and counted)."""
        now = self._now()
        with self.lock:
            outcome = self.cmd_in.offer(msg.data, now)
        self.command_answered.set()
        if outcome != 'accepted':
            self.get_logger().warning(f'current command {msg.data!r} {outcome}',
                                      throttle_duration_sec=1.0)

    def _external_command(self, state):
        """Publish the state, (lock-step: wait for its answer) and return the current [A]."""
        cmd_in = self.cmd_in
        with self.lock:
            normal = not cmd_in.timed_out
            reason = self._external_reason()
        self.command_answered.clear()
        msg = car_state_to_msg(state, self.loop.i_cmd, normal, reason, self.car_state_msg)
        self.drops.publish(self.car_state_pub, msg)
        if self.lockstep and not self.command_answered.wait(self.lockstep_timeout_s):
            self.lockstep_timeouts += 1
            self.get_logger().warning(
                f'no command within {self.lockstep_timeout_s:g} s of state t = {state.t:.3f} s '
                f'({self.lockstep_timeouts} in all)', throttle_duration_sec=1.0)
        now = self._now()
        with self.lock:
            was = cmd_in.timeouts
            current = cmd_in.current(now)
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
        """Offer a parameter message to the supervisor (received at the node clock's now)."""
        now = self._now()
        with self.lock:
            offer_parameters(self.sup, msg, now, self.get_logger())

    def on_measurement(self, msg):
        """Hand a rig measurement batch to the remote-rig plant (plant rig), in order."""
        try:
            columns = messages.samples_from_msg(msg)
        except ValueError as exc:
            self.drops.count('undecodable_measurement', detail=str(exc))
            return
        now = self._now()
        with self.answered:
            for sample in zip(*columns):   # lockstep: batches of one sample
                self.remote.receive(*sample, now=now)
            self.answered.notify()

    def _step(self, wall):
        """One control step (control thread): command, publish, advance the car."""
        loop = self.loop
        cmd = self.cmd
        if self.external:
            state = self.car.state
            if self.sensors is not None:
                self._publish_sensors(state)
            cmd.data, normal = self._external_command(state)
            loop.i_cmd = cmd.data
            reason = None       # the car state message is the controller's (not published)
        else:
            now = self._now()
            with self.lock:
                state = self.car.state
                cmd.data = loop.command(state, now)
                if self.probe is not None:
                    cmd.data = loop.i_cmd = self.probe(cmd.data, state.t)
                # read with the mode: one consistent pair (a refused state wins)
                mode, reason = loop.core.mode_reason()
                normal = mode == 'normal'
            self.drops.publish(self.cmd_pub, cmd)
        self.control.command_sent()
        if self.remote is None:
            new = loop.advance()
        else:
            with self.answered:
                if self.hil_wait_s > 0 and loop.steps > 0:
                    self.remote.count_wait(self.answered.wait_for(
                        lambda: self.remote.answered, self.hil_wait_s))
                new = loop.advance()
            self.disp.data = self.remote.last_command_m
            self.drops.publish(self.disp_pub, self.disp)
        if self.probe is not None:
            self.probe.observe(new.coil_current)
        if normal and math.isnan(self.first_normal_t):
            self.first_normal_t = state.t
        if self.every and loop.steps % self.every == 0:
            messages.seconds_to_stamp(max(new.t, 0.0), self.state_msg.header.stamp)
            self.state_msg.position, self.state_msg.velocity, self.state_msg.effort = _fmt(new)
            self.drops.publish(self.state_pub, self.state_msg)
            if not self.external:
                self.drops.publish(self.car_state_pub, car_state_to_msg(
                    new, cmd.data, normal, reason, self.car_state_msg))
        self.normal, self.new_state = normal, new

    def _after_step(self, wall, latency, lateness):
        if self.trace is not None:
            self.trace.append(self.new_state, self.cmd.data, self.loop.f_demand, self.normal,
                              wall, latency, lateness)

    def _on_control_error(self, failed):
        end_on_control_error(self, failed)

    @property
    def failed(self):
        """Why the control thread died (None while it did not)."""
        return self.control.failed

    def status(self):
        """Return the status dict (the values of the diagnostics, the log file's header)."""
        now = self._now()
        priority_error = getattr(getattr(self, 'control', None), 'priority_error', None)
        if priority_error and not self._priority_error_logged:
            self._priority_error_logged = True
            self.get_logger().warning(f'realtime_priority not applied: {priority_error}')
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
            'dropped': self.drops.counts(),
        })
        if self.remote is not None:
            with self.lock:
                st['hil'] = self.remote.as_dict()
        if self.probe is not None:
            st['probe'] = self.probe.as_dict()
        if self.sensors is not None:
            st['sensing'] = self.sensors.status()
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        metrics = live_loop.metrics_dict(self.metrics) if self.metrics is not None else None
        return self.health_rules(self.status(), metrics, failed=self.control.failed,
                                 alive=self.control.alive() or not self.control.running)

    def stop(self):
        """Stop the control thread and write the log file."""
        self.control.stop(2.0)
        if self.trace is not None:
            try:
                self.trace.close(status=self.status())
                # plain print: after Ctrl-C the context (and /rosout) is already shut down
                print(f'quarter_car_node: wrote {len(self.trace)} steps to {self.log_file}',
                      file=sys.stderr)
            except (OSError, ValueError) as exc:
                print(f'quarter_car_node: cannot write {self.log_file}: {exc}', file=sys.stderr)


def end_on_control_error(node, failed):
    """
    Say on ``/diagnostics`` that a car node's control loop died, then shut its context down.

    A dead control loop must not leave a node that looks alive: ERROR on ``/diagnostics``
    (``node.diagnostics``), then the process ends (exit status 1, :func:`run_car_node`).
    """
    if rclpy.ok(context=node.context):
        node.get_logger().error(f'control loop stopped: {failed}')
        try:
            node.diagnostics.publish()
        finally:
            rclpy.try_shutdown(context=node.context)


def run_car_node(node_class, name, args=None):
    """
    Run a car node with a control thread (``stop()``, ``failed``); return the exit status.

    A short GIL switch interval (the control thread waits at most ~0.5 ms for the executor);
    ValueError, OSError: bad parameter, road or truth file (exit status 2). A
    SingleThreadedExecutor: the control thread publishes, the executor only takes parameter
    sets and runs the diagnostics timer (with plant rig also the rig's measurements; with the
    EventsExecutor here the rig received a fifth of the commands the control thread sent).
    """
    sys.setswitchinterval(0.0005)
    return run_node(node_class, name, (ValueError, OSError),
                    run=lambda node: spin_node(node, events=False), finish=_finish, args=args)


def main(args=None):
    """Entry point of ``quarter_car_node``."""
    return run_car_node(QuarterCarNode, 'quarter_car_node', args)


def _finish(node):
    """Stop the control thread; exit status 1 if the control loop failed."""
    node.stop()
    return 1 if node.failed else None


if __name__ == '__main__':
    sys.exit(main())
