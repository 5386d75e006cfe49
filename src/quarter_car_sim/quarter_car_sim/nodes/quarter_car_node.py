"""
Quarter-car node: a simulated car corner on an MR damper it only knows through the identifier.

``ros2 run quarter_car_sim quarter_car_node --ros-args --params-file suite.yaml``

The node declares its parameters, converts messages and calls one ROS-free
:class:`quarter_car_sim.runtime.quarter_car.CarRuntime` (the control logic, its status and health).
Its control thread runs :class:`quarter_car_sim.simulate.live_loop.ClosedLoop` at ``rate_hz`` (1
kHz), paced against the monotonic wall clock (real time times ``real_time_factor``; 0 = as fast as
possible): a real-time simulation keeps pace with the wall clock by nature, even under
``use_sim_time``. Each step: the supervisor (:mod:`semi_active_control.supervision.failsafe`) says
whether the latest identified parameters may be used; the controller's force goes through their
inverse to a coil current (or the safe current in fail-safe), published on
``mr_damper/current_command``; then the car and its "true" damper plant advance 1 ms. Parameter
messages and ``/diagnostics`` go through the executor in the main thread. Ages and timeouts of
messages (parameter age and timeout, command timeout) are on the node's clock: ROS time, so they
follow ``/clock`` under ``use_sim_time``.

Topics (relative: remap with ``--ros-args -r old:=new`` or run in a namespace)
-----------------------------------------------------------------------------
- sub ``mr_damper/kwok_parameters`` (mr_damper_interfaces/KwokParameters; reliable,
  transient local, depth 1);
- pub ``mr_damper/current_command`` (std_msgs/Float64, A, every control step; reliable, 10);
- pub ``quarter_car/state`` (sensor_msgs/JointState at ``state_rate_hz``; header.stamp = sim
  time). Joints and fields (SI, positive up, see semi_active_control.car.quarter_car):

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
  :class:`quarter_car_sim.runtime.car_health.CarHealth` (OK normal; WARN fail-safe and why, loop
  late, drops; ERROR control thread died, commands refused persistently); values: mode, reason,
  failsafe_s, failsafe_entries, params_accepted, params_rejected.<reason>, param_age_s,
  current_a, saturated_steps, loop.period / lateness / latency / step statistics [ms],
  late_reanchors, dropped.<reason>, ride_metrics.* (running Wk RMS body acceleration, RMS tyre
  load ratio, travel, ...), hil.* (plant rig: tracking error), probe.* (probe on).

External controller (``controller:=external``): the car is the plant only. It does not take
parameters; each control step it publishes its state on ``quarter_car/car_state``
(mr_damper_interfaces/QuarterCarState; reliable, depth 10) and applies the latest current
received on ``mr_damper/current_command`` (std_msgs/Float64; clamped / refused and counted),
``safe_current_a`` when none came for ``command_timeout_s`` (``mode`` failsafe, reason
``no_command_yet`` / ``command_timeout``). With ``lockstep:=true`` it applies to step k the
first command received after state k (waiting at most ``lockstep_timeout_s``, counted): the loop
is then step for step the built-in one (docs/controller-node.md).

Vehicle sensing (``sensing:=vehicle``, with ``controller:=external``): each control step the car
also publishes what a vehicle's sensors give
(:class:`quarter_car_sim.plant.sensors.VehicleSensors`): the body accelerometer on
``quarter_car/body_imu`` (sensor_msgs/Imu, ``linear_acceleration.z`` specific force) and the
suspension position on ``quarter_car/suspension_position`` (sensor_msgs/JointState, joint
``suspension``), NaN for a lost sample; its true state moves to ``quarter_car/true_state``
(``state_estimator_node`` publishes ``quarter_car/car_state`` for the controller). An injected body
accelerometer dropout (``sensor_dropout_start_s``, ``sensor_dropout_s``) tests the fail-safe.

Hardware in the loop (``plant:=rig``, docs/hil.md): the car has no damper model of its own. Each
control step it publishes the (delay-compensated) suspension travel on
``mr_damper/displacement_command`` (std_msgs/Float64 [m], reliable, depth 10) and uses the
latest force of the rig's lockstep link (``mr_damper/hil_measurement``, one DamperSamples sample
per command; best effort, depth 10: only the newest matters); the diagnostics carry ``hil``
(tracking RMS / peak of desired vs measured displacement, link counts). With ``hil_wait_s > 0``
each step first waits (at most that long, counted) for the rig's answer to the previous command.
``probe:=true`` overrides the law's current now and then with a starving current bin, the one
farthest from the covered ones first (also in fail-safe, so the identifier sees every current
bin); the diagnostics carry ``probe``.

Every publisher is KEEP_LAST (depth 10, latest value topics), so a dead or stalled reader never
blocks the control loop; a ``publish()`` that fails anyway is counted
(``dropped.publish_failed``) and logged, throttled, and the loop goes on. The car state is
numbered (``sequence``, +1 per message) so its readers count the states they never got; the
parameter reader keeps the newest set only (docs/faults.md, Lost messages).
"""
import sys

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from mr_damper_interfaces.msg import DamperSamples, KwokParameters, QuarterCarState
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from mr_damper_common import messages
from mr_damper_common.node_utils import (CONTROL_QOS, declare_parameters, DiagnosticsPublisher,
                                         DropCounter, FastLane, LATCHED_QOS, node_time_s, Param,
                                         set_realtime_priority)
from quarter_car_sim.nodes.car_process import end_on_control_error, run_car_node
from quarter_car_sim.simulate import live_loop
from quarter_car_sim.runtime.quarter_car import CarOutputs, make_car_runtime
from semi_active_control.laws import DAMPER_LAW_NAMES
from semi_active_control.nodes.common import offer_parameters, SUPERVISED_LAW_PARAMETERS

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
          'LOG.json header, mr_damper_common.recording.columnlog; "" = no log)'),
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
    Param('probe', False, 'Probe a starving current bin (the farthest from the covered ones '
          'first) now and then so the identifier sees every current '
          '(quarter_car_sim.runtime.probing)'),
    Param('probe_bin_a', 0.1, 'Probe bin width (the identifier\'s current_bin_a) [A]',
          0.001, 10.0),
    Param('probe_period_s', 1.0, 'Time between probe windows [s]', 0.01, 3600.0),
    Param('probe_hold_s', 0.1, 'Probe window length [s]', 0.001, 3600.0),
    Param('probe_min_samples', 500, 'Samples a bin needs to count as covered [-]', 1,
          10 ** 9),
    Param('probe_max_duty', 0.2, 'Cap of probe_hold_s / probe_period_s [-]', 0.001, 1.0),
    Param('sensing', 'ideal', 'External controller: ideal (the true state on '
          'quarter_car/car_state) or vehicle (body accelerometer on quarter_car/body_imu, '
          'suspension position on quarter_car/suspension_position, '
          'quarter_car_sim.plant.sensors; the true state on quarter_car/true_state, the '
          'estimator publishes car_state)'),
    Param('sensor_seed', 1, 'sensing vehicle: seed of the sensor errors [-]', 0, 2 ** 31 - 1),
    Param('sensor_dropout_start_s', 0.0, 'sensing vehicle: start of an injected body '
          'accelerometer dropout [s, car time]', 0.0, 36000.0),
    Param('sensor_dropout_s', 0.0, 'sensing vehicle: length of the injected dropout (0 = '
          'none) [s]', 0.0, 3600.0),
)


def _fmt(state):
    """Return (position, velocity, effort) lists of the state message."""
    return ([state.z_s, state.z_u, state.travel, state.z_r],
            [state.v_s, state.v_u, state.v_rel, state.coil_current],
            [state.a_s, state.a_u, state.damper_force, state.tyre_force])


class QuarterCarNode(Node, CarOutputs):
    """
    Thin ROS adapter over, and outputs of, :class:`quarter_car_sim.runtime.CarRuntime`.

    Keyword arguments (e.g. ``context``, ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('quarter_car_node', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS,
                                        lambda changes: self.rt.reconfigure(changes))
        self.rate_hz, self.log_file = p['rate_hz'], p['log_file']
        # the settings shared with the controller node, as its parameters name them
        supervisor = dict(timeout_s=p['param_timeout_s'], safe_current_a=p['safe_current_a'],
                          i_min_a=p['i_min_a'], i_max_a=p['i_max_a'],
                          hold_on_reject=p['hold_on_reject'],
                          min_current_span_a=p['min_current_span_a'])
        rt = self.rt = make_car_runtime(p, self._now, self, supervisor=supervisor,
                                        controller_options=p['controller_options'])
        # the cores (tests and tools look at them)
        self.sup, self.loop, self.car = rt.sup, rt.loop, rt.car
        self.cmd_in, self.health_rules = rt.cmd_in, rt.health_rules
        self.drops = DropCounter(self.get_logger())
        self.cmd, self.disp = Float64(), Float64()
        self.state_msg = JointState()
        self.state_msg.name = list(STATE_JOINTS)
        self.car_state_msg = QuarterCarState()
        self.car_state_msg.header.frame_id = 'quarter_car'
        if rt.sensors is not None:
            self._init_sensing()
        # the typed state (controller:=external: every step, the controller's input; sensing
        # vehicle: the true state, the estimator publishes car_state)
        self.car_state_pub = self.create_publisher(
            QuarterCarState, 'quarter_car/true_state' if rt.sensors else 'quarter_car/car_state',
            CONTROL_QOS)
        self.state_pub = self.create_publisher(JointState, 'quarter_car/state', 10)
        # the 1 kHz inputs of the control thread (the external controller's commands, the
        # rig's answers) on a lane of their own: the node's executor would rebuild its whole
        # wait set for each one (docs/hil.md, Timing)
        self.lane = None
        if rt.external or rt.remote is not None:
            self.lane = FastLane(self, 'link')   # its thread: realtime_priority below
        if rt.external:
            self.cmd_sub = self.drops.subscribe(self.lane.node, Float64,
                                                'mr_damper/current_command', self.on_command,
                                                CONTROL_QOS)
        else:
            self.cmd_pub = self.create_publisher(Float64, 'mr_damper/current_command', 10)
            self.drops.subscribe(self, KwokParameters, 'mr_damper/kwok_parameters',
                                 self.on_params, LATCHED_QOS)
        if rt.remote is not None:
            self.disp_pub = self.create_publisher(Float64, 'mr_damper/displacement_command', 10)
            self.hil_sub = self.drops.subscribe(
                self.lane.node, DamperSamples, 'mr_damper/hil_measurement', self.on_measurement,
                QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
                'measurements_lost')
        if self.lane is not None:
            self.lane.start()
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='quarter_car', drops=self.drops)
        rt.start(on_error=lambda failed: end_on_control_error(self, failed))
        if (rt.external or rt.remote is not None) and p['realtime_priority'] > 0 and rt.rtf > 0:
            # the commands (the rig's answers) arrive in the executor and middleware threads:
            # they wake the control thread, so they get its priority too; and every thread of
            # the process shares the GIL: a normal-priority thread preempted while it holds the
            # GIL would stall the control thread for a time slice (priority inversion: 10-50 ms
            # stalls of the HIL car before)
            set_realtime_priority(int(p['realtime_priority']), self.get_logger())
        self.get_logger().info(rt.summary)

    def _now(self):
        """Node clock [s] (ROS time), for message ages and timeouts."""
        return node_time_s(self)

    def _init_sensing(self):
        """``sensing:=vehicle``: the publishers of the vehicle sensors' readings."""
        self.imu_msg = Imu()
        self.imu_msg.header.frame_id = 'body'
        self.imu_msg.orientation_covariance[0] = -1.0       # no orientation (REP 145)
        self.position_msg = JointState()
        self.position_msg.name = ['suspension']
        self.imu_pub = self.create_publisher(Imu, 'quarter_car/body_imu', CONTROL_QOS)
        self.position_pub = self.create_publisher(JointState, 'quarter_car/suspension_position',
                                                  CONTROL_QOS)

    def on_command(self, msg):
        """Take one current command of the external controller (checked and counted)."""
        outcome = self.rt.offer_command(msg.data)
        if outcome != 'accepted':
            self.get_logger().warning(f'current command {msg.data!r} {outcome}',
                                      throttle_duration_sec=1.0)

    def on_params(self, msg):
        """Offer a parameter message to the supervisor (received at the node clock's now)."""
        now = self._now()
        with self.rt.lock:
            offer_parameters(self.rt.sup, msg, now, self.get_logger())

    def on_measurement(self, msg):
        """Hand a rig measurement batch to the remote-rig plant (plant rig), in order."""
        try:
            columns = messages.samples_from_msg(msg)
        except ValueError as exc:
            self.drops.count('undecodable_measurement', detail=str(exc))
            return
        self.rt.receive_measurements(columns)

    def publish_command(self, current_a):
        """Publish the coil current command [A]."""
        self.cmd.data = current_a
        self.drops.publish(self.cmd_pub, self.cmd)

    def publish_car_state(self, state, current_a, normal, reason):
        """Publish the typed state."""
        self.drops.publish_next(self.car_state_pub, messages.corner_state_to_msg(
            state, current_a, normal, reason, self.car_state_msg))

    def publish_state(self, state):
        """Publish the joint state."""
        messages.seconds_to_stamp(max(state.t, 0.0), self.state_msg.header.stamp)
        self.state_msg.position, self.state_msg.velocity, self.state_msg.effort = _fmt(state)
        self.drops.publish(self.state_pub, self.state_msg)

    def publish_displacement(self, command_m):
        """Publish the rig's displacement command [m]."""
        self.disp.data = command_m
        self.drops.publish(self.disp_pub, self.disp)

    def publish_sensors(self, t, readings):
        """Publish the readings the sensors deliver at this step (NaN: a lost sample)."""
        if 'body_accel' in readings:
            messages.seconds_to_stamp(t, self.imu_msg.header.stamp)
            self.imu_msg.linear_acceleration.z = readings['body_accel']
            self.drops.publish(self.imu_pub, self.imu_msg)
        if 'travel' in readings:
            messages.seconds_to_stamp(t, self.position_msg.header.stamp)
            self.position_msg.position = [readings['travel']]
            self.drops.publish(self.position_pub, self.position_msg)

    def controller_connected(self):
        """Lock-step: True once the controller's topics are matched both ways."""
        return (self.car_state_pub.get_subscription_count() > 0
                and self.cmd_sub.get_publisher_count() > 0)

    def rig_connected(self):
        """Hardware in the loop: True once the rig's link is matched both ways."""
        return (self.disp_pub.get_subscription_count() > 0
                and self.hil_sub.get_publisher_count() > 0)

    def warn(self, text):
        """Log a warning of the runtime (it throttles them)."""
        self.get_logger().warning(text)

    def info(self, text):
        """Log an information line of the runtime."""
        self.get_logger().info(text)

    @property
    def failed(self):
        """Why the control thread died (None while it did not)."""
        return self.rt.failed

    def status(self):
        """Return the status dict (the values of the diagnostics, the log file's header)."""
        return self.rt.status(self.drops.counts())

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        return self.rt.health(self.drops.counts())

    def stop(self):
        """Stop the control thread and write the log file."""
        self.rt.stop(2.0)
        if self.lane is not None:
            self.lane.close()
        try:
            steps = self.rt.close_log(self.drops.counts())
        except (OSError, ValueError) as exc:
            print(f'quarter_car_node: cannot write {self.log_file}: {exc}', file=sys.stderr)
            return
        if steps is not None:
            # plain print: after Ctrl-C the context (and /rosout) is already shut down
            print(f'quarter_car_node: wrote {steps} steps to {self.log_file}', file=sys.stderr)


def main(args=None):
    """Entry point of ``quarter_car_node``."""
    return run_car_node(QuarterCarNode, 'quarter_car_node', args)


if __name__ == '__main__':
    sys.exit(main())
