"""
Full-car node: the 7-DOF car on four MR dampers it only knows through four identifiers.

``ros2 run quarter_car_sim full_car_node --ros-args --params-file suite_full_car.yaml``

A control thread (:class:`quarter_car_sim.runtime.control_thread.ControlThread`) steps the ROS-free
:class:`quarter_car_sim.runtime.full_car.FullCarRuntime` at ``rate_hz``, paced against the
monotonic wall clock (real time times ``real_time_factor``; 0 = as fast as possible): the
full-car law (modal skyhook by default) chooses four corner forces, each corner's supervisor and
the inverse of that corner's identified model turn them into four coil currents (a corner
without a valid, fresh model gets ``safe_current_a``; the others go on controlling), and the car
with its four "true" damper plants advances one period on the two-track road. Parameter
messages and ``/diagnostics`` go through the executor in the main thread; ages and timeouts of
parameter sets are on the node's clock (ROS time).

Topics (relative; ``<c>`` is each of ``fl``, ``fr``, ``rl``, ``rr``, the namespaces of the four
rig / identifier pairs of ``mr-damper-suite --config full-car``)
-------------------------------------------------------------------------------------------
- sub ``<c>/mr_damper/kwok_parameters`` (mr_damper_interfaces/KwokParameters; reliable,
  transient local, depth 1): that corner's identified model;
- pub ``<c>/quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState at
  ``state_rate_hz``): the corner as a quarter car (body point above the wheel, wheel, travel,
  damper force, tyre load, road, current command, that corner's fail-safe mode and reason);
- pub ``<c>/mr_damper/current_command`` (std_msgs/Float64 [A] at ``state_rate_hz``): the
  corner's current command (applied inside the node; published for the record);
- pub ``full_car/body_state`` (sensor_msgs/JointState at ``state_rate_hz``; header.stamp =
  sim time): joints ``heave``, ``pitch``, ``roll`` with position z [m], theta [rad], phi [rad],
  velocity their rates and effort their accelerations [m/s^2, rad/s^2] (the quarter car's
  JointState convention: a standard message of named generalised coordinates and their rates,
  readable by any tool, no new interface type);
- pub ``/diagnostics`` (status name ``full_car_node``): OK with four corners normal, WARN
  naming the corners in fail-safe, ERROR when the control thread died; values: controller,
  steps, t_sim, corners_normal, corners.<c>.* (mode, reason, failsafe_s, params_accepted,
  params_rejected.<reason>, normal_steps, current_a, ...), iso2631.* (a_wz, a_w_pitch,
  a_w_roll, a_v, VDVs, crest factors of the body centre since t = 0), loop.*,
  late_reanchors, dropped.<reason>.

External controller (``controller:=external``): the node is the plant only, as the car is to
a vehicle computer (docs/vehicle.md), without the sensors and the bus: every ``cycle_s`` it
publishes its true state as one ``vehicle/state`` (mr_damper_interfaces/FullCarState, valid,
numbered from 1, stamped on the node's clock: the clock the controller's deadlines are on) and
applies the four currents of the latest ``vehicle/command`` (mr_damper_interfaces/FullCarCommand;
:class:`quarter_car_sim.runtime.command_input.VehicleCommandInput`: a corner without a fresh
command for ``command_timeout_s`` gets ``safe_current_a``, counted; a corner is normal while the
controller has it on the law), e.g. for ``vehicle_controller_node``. It does not subscribe the
parameters (the controller does); the corner states and current commands it publishes at
``state_rate_hz`` are for the record. The look-ahead frames (``road_preview``) are stamped on the
same clock. With ``lockstep:=true`` step 0 waits for the two topics to be matched both ways and
each cycle waits for the command answering its state (at most ``lockstep_timeout_s``, each
expiry counted in ``lockstep_timeouts``).

At the end the node publishes a final status and, with ``log_file``, writes the body's
recorded time and accelerations (``t``, ``acc`` with columns heave, pitch, roll) as a NumPy
``.npz`` file for the suite's report.
"""
import sys
import threading
import time

import numpy as np
from mr_damper_interfaces.msg import (FullCarCommand, FullCarState, KwokParameters,
                                      QuarterCarState, RoadPreview)
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from mr_damper_common import messages
from mr_damper_common.health import ERROR, WARN, worst
from mr_damper_common.node_utils import (CONTROL_QOS, declare_parameters, DiagnosticsPublisher,
                                         DropCounter, FastLane, LATCHED_QOS, node_time_s, Param,
                                         set_cpu_affinity, set_realtime_priority, VEHICLE_QOS)
from mr_damper_model.io.params_file import load_plant
from quarter_car_sim.nodes.car_process import end_on_control_error, run_car_node
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.runtime.command_input import VehicleCommandInput
from quarter_car_sim.runtime.control_thread import ControlThread
from quarter_car_sim.runtime.full_car import BODY_JOINTS, FullCarRuntime
from quarter_car_sim.runtime.look_ahead import simulated_look_ahead
from quarter_car_sim.simulate import live_loop
from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
from semi_active_control.estimation.vehicle_estimator import VehicleEstimate
from semi_active_control.nodes.common import CORNER_SUPERVISOR_PARAMETERS, offer_parameters

#: The node's parameters (the one place they are declared; docs/nodes.md shows this table).
PARAMETERS = (
    Param('rate_hz', 1000.0, 'Control rate [Hz]', 10.0, 10000.0),
    Param('real_time_factor', 1.0, 'Simulated seconds per wall second (0 = as fast as '
          'possible) [-]', 0.0, 1000.0),
    Param('controller', 'modal-skyhook', 'Full-car law: modal-skyhook, '
          'full-car-clipped-optimal(-wk), per-corner-<law> (e.g. per-corner-skyhook), '
          'passive@<I>A, external (plant only: vehicle/state out every cycle_s, '
          'vehicle/command in, e.g. vehicle_controller_node) or can (plant only: its sensor '
          'cluster and four damper drivers on a CAN bus, for a vehicle computer: '
          'docs/vehicle.md)'),
    Param('cycle_s', 0.002, 'External controller: the control cycle, one vehicle/state per '
          'cycle [s, car time; a multiple of the step]', 1e-4, 1.0),
    Param('command_timeout_s', 0.05, 'External controller: a corner\'s safe current when no '
          'command came for it for this long [s, node clock]', 0.001, 3600.0),
    Param('lockstep', False, 'External controller: each cycle waits for the command '
          'answering its state'),
    Param('lockstep_timeout_s', 1.0, 'Lock-step: longest wait for the command [s, wall '
          'clock]', 0.001, 3600.0),
) + CORNER_SUPERVISOR_PARAMETERS + (
    Param('road', 'iso8608-C', 'Two-track road: iso8608-<class> (A..H) or an event of '
          'quarter_car_sim.plant.two_track_road.EVENTS'),
    Param('speed_m_s', 20.0, 'Vehicle speed [m/s]', 0.1, 100.0),
    Param('road_seed', 1, 'Seed of the random road [-]', 0, 2 ** 31 - 1),
    Param('road_duration_s', 300.0, 'Road length in time (then held flat) [s]', 1.0, 3600.0),
    Param('settle_s', live_loop.SETTLE_S, 'Time run before the road starts (settling) [s]',
          0.0, 60.0),
    Param('plant', 'spencer', 'True damper plant of every corner (same as the rigs): spencer '
          'or kwok-current'),
    Param('truth_file', '', 'JSON parameter file of the true dampers, as the rigs (default: '
          'preset)'),
    Param('truth_files', ['', '', '', ''], 'Per corner (fl, fr, rl, rr) the true damper\'s '
          'parameter file ("" = truth_file)'),
    Param('can_interface', 'udp_loopback', 'controller can: python-can interface of the car\'s '
          'bus (udp_loopback: this host only)'),
    Param('can_channel', '239.74.163.2:43113', 'controller can: bus channel'),
    Param('can_cycle_s', 0.002, 'controller can: sensor frame cycle [s, car time]', 1e-4, 1.0),
    Param('driver_status_period_s', 0.01, 'controller can: driver status period [s, car time]',
          1e-4, 1.0),
    Param('driver_command_timeout_s', 0.05, 'controller can: a driver without a valid command '
          'for this long takes its own safe current [s, car time]', 1e-3, 3600.0),
    Param('driver_safe_current_a', 0.5, 'controller can: the drivers\' own safe current [A]',
          0.0, 2.55),
    Param('sensor_noise', True, 'controller can: the sensors\' automotive errors (seeded), '
          'else exact readings'),
    Param('sensor_seed', 1, 'controller can: sensor seed [-]', 0, 2 ** 31 - 1),
    Param('road_preview', False, 'Publish full_car/road_preview: a look-ahead sensor\'s frames '
          'of the road ahead with the car\'s speed signal (docs/preview.md)'),
    Param('preview_near_m', 0.5, 'Look-ahead sensor: nearest distance ahead of the front axle '
          '[m]', 0.0, 100.0),
    Param('preview_far_m', 15.0, 'Look-ahead sensor: farthest distance ahead [m]', 0.1, 200.0),
    Param('preview_point_spacing_m', 0.1, 'Look-ahead sensor: spacing of the profile\'s points '
          '[m]', 0.01, 10.0),
    Param('preview_rate_hz', 18.0, 'Look-ahead sensor: frames per second [Hz]', 0.1, 1000.0),
    Param('preview_latency_s', 0.02, 'Look-ahead sensor: delay from measurement (the stamp) to '
          'publication [s]', 0.0, 1.0),
    Param('preview_height_noise_m', 0.003, 'Look-ahead sensor: RMS white noise of each height '
          '[m]', 0.0, 1.0),
    Param('preview_height_bias_m', 0.0, 'Look-ahead sensor: constant height offset [m]',
          -1.0, 1.0),
    Param('preview_pitch_error_gain', 0.0, 'Look-ahead sensor: fraction of the body pitch it '
          'does not compensate [-]', -10.0, 10.0),
    Param('preview_dropout_prob', 0.0, 'Look-ahead sensor: probability that a frame is lost '
          '[-]', 0.0, 1.0),
    Param('preview_outage_start_s', 0.0, 'Look-ahead sensor: start of an outage (invalid '
          'frames) [s, simulated time]', 0.0, 1e6),
    Param('preview_outage_s', 0.0, 'Look-ahead sensor: length of that outage (0 = none) [s]',
          0.0, 1e6),
    Param('preview_seed', 1, 'Look-ahead sensor: seed of its noise and dropouts [-]', 0,
          2 ** 31 - 1),
    Param('speed_error', 0.02, 'Scale error of the speed signal sent with the frames [-]',
          -0.5, 0.5),
    Param('state_rate_hz', 100.0, 'Rate of the corner states, current commands and body state '
          '(0 = none) [Hz]', 0.0, 10000.0),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the control thread (with controller '
          'external: of every thread; can: the bus reader at one below) (1..99; 0 = normal '
          'scheduling); only with '
          'real_time_factor > 0, needs CAP_SYS_NICE [-]', 0, 99),
    Param('cpu_affinity', '', 'CPUs every thread of the node is pinned to once it runs, a Linux '
          'CPU list as taskset -c takes it ("0", "2-3"; "" = any)'),
    Param('log_max_s', 600.0, 'Longest body history kept for the ISO 2631-1 figures [s]',
          0.0, 3600.0),
    Param('log_file', '', 'At the end write the body accelerations (t, acc) to this .npz file '
          '("" = none)'),
)


class FullCarNode(Node):
    """
    Thin ROS adapter over :class:`~quarter_car_sim.runtime.full_car.FullCarRuntime`.

    Topics and status: see the module docstring. Keyword arguments (e.g. ``context``,
    ``parameter_overrides``) go to ``rclpy.node.Node``.
    """

    def __init__(self, **node_kwargs):
        super().__init__('full_car_node', **node_kwargs)
        self.lock = threading.Lock()
        p = self.p = declare_parameters(self, PARAMETERS)
        self.rate_hz = p['rate_hz']
        self.rtf = p['real_time_factor']
        self.log_file = p['log_file']
        dt = 1.0 / self.rate_hz
        road = make_two_track_road(p['road'], PASSENGER_CAR, speed_m_s=p['speed_m_s'],
                                   duration_s=p['road_duration_s'], dt=dt,
                                   rng=int(p['road_seed']))
        plants = [load_plant(p['plant'], f or p['truth_file']) for f in p['truth_files']]
        self.external = p['controller'].strip().lower() == 'external'
        self.can = p['controller'].strip().lower() == 'can'
        self.lockstep = self.external and p['lockstep']
        self.lockstep_timeout_s = p['lockstep_timeout_s']
        self.lockstep_timeouts = 0
        law = f'passive@{p["safe_current_a"]:g}A' if self.external or self.can \
            else p['controller']
        self.rt = FullCarRuntime(
            PASSENGER_CAR, road, plants, law, dt=dt,
            timeout_s=p['param_timeout_s'], safe_current_a=p['safe_current_a'],
            i_min_a=p['i_min_a'], i_max_a=p['i_max_a'],
            min_current_span_a=p['min_current_span_a'], hold_on_reject=p['hold_on_reject'],
            settle_s=p['settle_s'], log_max_s=p['log_max_s'])
        self.drops = DropCounter(self.get_logger())
        self.link = self.can_bus = None
        if self.can:
            from mr_damper_can.bus import make_bus
            from quarter_car_sim.runtime.can_link import CanCarLink
            self.can_bus = make_bus(p['can_interface'], p['can_channel'])
            self.link = CanCarLink(self.can_bus, dt=dt, cycle_s=p['can_cycle_s'],
                                   status_period_s=p['driver_status_period_s'],
                                   driver_timeout_s=p['driver_command_timeout_s'],
                                   driver_safe_current_a=p['driver_safe_current_a'],
                                   sensor_noise=p['sensor_noise'], seed=p['sensor_seed'])
        self.state_pubs, self.cmd_pubs, self.state_msgs = [], [], []
        # the external controller's commands on a lane of their own: the node's executor
        # would rebuild its whole wait set for each command (docs/hil.md, Timing)
        self.lane = FastLane(self, 'commands') if self.external else None
        self.answered = threading.Condition(self.lock)     # lock-step: the answer came
        if self.external:
            self.cmd_in = VehicleCommandInput(p['command_timeout_s'], p['safe_current_a'],
                                              p['i_min_a'], p['i_max_a'], CORNERS)
            self.cycle_steps = max(1, int(round(p['cycle_s'] * self.rate_hz)))
            self.vehicle_states = 0
            self.vstate_pub = self.create_publisher(FullCarState, 'vehicle/state', VEHICLE_QOS)
            self.vstate_msg = FullCarState()
            self.cmd_sub = self.drops.subscribe(self.lane.node, FullCarCommand,
                                                'vehicle/command', self.on_command, VEHICLE_QOS)
        for i, c in enumerate(CORNERS):
            self.state_pubs.append(self.create_publisher(
                QuarterCarState, f'{c}/quarter_car/car_state', CONTROL_QOS))
            msg = QuarterCarState()
            msg.header.frame_id = f'{c}/quarter_car'
            self.state_msgs.append(msg)
            if self.can:
                continue
            self.cmd_pubs.append(self.create_publisher(Float64, f'{c}/mr_damper/current_command',
                                                       10))
            if self.external:
                continue
            self.drops.subscribe(self, KwokParameters, f'{c}/mr_damper/kwok_parameters',
                                 lambda m, i=i: self.on_params(i, m), LATCHED_QOS)
        self.body_pub = self.create_publisher(JointState, 'full_car/body_state', 10)
        self.look_ahead = self.preview_pub = None
        if p['road_preview']:
            self.look_ahead = simulated_look_ahead(p, road)
            self.preview_pub = self.create_publisher(RoadPreview, 'full_car/road_preview',
                                                     CONTROL_QOS)
            self.preview_msg = RoadPreview()
        self.body_msg = JointState()
        self.body_msg.header.frame_id = 'full_car'
        self.body_msg.name = list(BODY_JOINTS)
        self.cmd_msg = Float64()
        self.every = (max(1, int(round(self.rate_hz / p['state_rate_hz'])))
                      if p['state_rate_hz'] > 0 else 0)
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='full_car', drops=self.drops)
        self.control = ControlThread(
            self._step_can if self.can else self._step_external if self.external else self._step,
            live_loop.Pacer(dt, self.rtf),
            live_loop.LoopTiming(dt / self.rtf if self.rtf > 0 else None),
            before_first=self._wait_for_controller if self.lockstep else None,
            on_error=lambda failed: end_on_control_error(self, failed),
            priority=int(p['realtime_priority']) if self.rtf > 0 else 0)
        if self.lane is not None:
            self.lane.start()
        if self.link is not None:
            # the bus reader just below the control thread (with every thread of the car at
            # the control thread's priority, the car froze: docs/vehicle.md)
            self.link.start(reader_priority=max(int(p['realtime_priority']) - 1, 0)
                            if self.rtf > 0 else 0)
        self.control.start()
        if self.external and p['realtime_priority'] > 0 and self.rtf > 0:
            # the commands arrive in the lane's and the middleware's threads and every thread
            # shares the GIL: a normal-priority thread preempted while it holds the GIL would
            # stall the control thread (as the quarter car's external and HIL modes)
            set_realtime_priority(int(p['realtime_priority']), self.get_logger())
        set_cpu_affinity(p['cpu_affinity'], self.get_logger())
        name = ('external controller' if self.external else 'vehicle computer on CAN '
                f'{p["can_interface"]} {p["can_channel"]}' if self.can
                else self.rt.controller.name)
        self.get_logger().info(
            f'{name} at {self.rate_hz:g} Hz (x{self.rtf:g} real time) on '
            f'{road.name}, plants {p["plant"]}; fail-safe {p["safe_current_a"]:g} A, timeout '
            f'{p["param_timeout_s"]:g} s')

    def on_params(self, i, msg):
        """Offer a parameter message to corner ``i``'s supervisor (at the node clock's now)."""
        now = node_time_s(self)
        with self.lock:
            offer_parameters(self.rt.supervisor(i), msg, now, self.get_logger())

    def _wait_for_controller(self):
        """Lock-step: hold step 0 until the controller's topics are matched both ways."""
        self.get_logger().info('lock-step: waiting for the controller to connect')
        while self.control.running and not (self.vstate_pub.get_subscription_count() > 0
                                            and self.cmd_sub.get_publisher_count() > 0):
            time.sleep(0.005)

    def on_command(self, msg):
        """Take one command of the vehicle controller (the lane's thread)."""
        now = node_time_s(self)
        with self.answered:
            outcomes = self.cmd_in.offer(msg.sequence, msg.state_sequence, msg.current_a,
                                         msg.mode, msg.reason, now)
            self.answered.notify_all()
        bad = [f'{c} {o}' for c, o in zip(CORNERS, outcomes or ()) if o != 'accepted']
        if bad:
            self.get_logger().warning(f'command {msg.sequence}: ' + ', '.join(bad),
                                      throttle_duration_sec=1.0)

    def _step_external(self, wall):
        """Plant step: each cycle publish the state (lock-step: wait for its answer); apply."""
        state = self.rt.state
        now = node_time_s(self)
        self._publish_preview(state, now - state.t)
        if self.rt.steps % self.cycle_steps == 0:
            self.vehicle_states += 1
            seq = self.vehicle_states
            est = VehicleEstimate.exact(state, seq, t=now)
            self.drops.publish(self.vstate_pub, messages.full_car_state_msg(
                est, self.vstate_msg))
            if self.lockstep:
                with self.answered:
                    answered = self.answered.wait_for(
                        lambda: self.cmd_in.answered_sequence >= seq, self.lockstep_timeout_s)
                if not answered:
                    self.lockstep_timeouts += 1
                    self.get_logger().warning(
                        f'no command within {self.lockstep_timeout_s:g} s of state {seq} '
                        f'(t = {state.t:.3f} s; {self.lockstep_timeouts} in all)',
                        throttle_duration_sec=1.0)
                now = node_time_s(self)
        with self.lock:
            currents = self.cmd_in.currents(now, state.t)
            _, _, new = self.rt.step(now, currents)
            modes = [self.cmd_in.mode_reason(i) for i in range(4)]
        self.control.command_sent()
        if self.every and not self.rt.steps % self.every:
            self._publish_corners(new, currents, modes)

    def _step_can(self, wall):
        """Plant step: the sensors and drivers on the bus, the drivers' currents, advance."""
        now = node_time_s(self)
        state = self.rt.state
        self._publish_preview(state, now - state.t)     # on the vehicle's (the bus's) clock
        with self.lock:
            currents = self.link.step(self.rt.state)
            _, _, new = self.rt.step(now, currents)
        self.control.command_sent()
        if self.every and not self.rt.steps % self.every:
            self._publish_body(new)

    def _step(self, wall):
        """One control step (control thread): command, advance, publish at the state rate."""
        now = node_time_s(self)
        with self.lock:
            _, currents, new = self.rt.step(now)
            modes = [core.mode_reason() for core in self.rt.controller.cores]
        self.control.command_sent()
        self._publish_preview(new)
        if self.every and not self.rt.steps % self.every:
            self._publish_corners(new, currents, modes)

    def _publish_corners(self, new, currents, modes):
        """Publish each corner's state and current command, and the body (the record)."""
        for i in range(4):
            mode, reason = modes[i]
            self.drops.publish_next(self.state_pubs[i], messages.corner_state_to_msg(
                new.corner(i), currents[i], mode == 'normal', reason,
                self.state_msgs[i]))
            self.cmd_msg.data = float(currents[i])
            self.drops.publish(self.cmd_pubs[i], self.cmd_msg)
        self._publish_body(new)

    def _publish_preview(self, state, clock_offset_s=0.0):
        """
        Publish the look-ahead frames delivered by ``state.t`` (with the speed signal).

        Stamps are the car's time plus ``clock_offset_s`` [s] (external: the node clock's).
        """
        if self.look_ahead is None:
            return
        with self.lock:                         # status() reads the sensor's counters
            frames = self.look_ahead.frames(state.t, float(state.q[1]))
        for seq, frame in frames:
            self.drops.publish(self.preview_pub, messages.road_preview_msg(
                frame.stamp + clock_offset_s, frame.distance_m, frame.heights_m, sequence=seq,
                speed_m_s=self.look_ahead.speed_m_s, valid=frame.valid,
                reason='' if frame.valid else 'outage', msg=self.preview_msg))

    def _publish_body(self, new):
        messages.seconds_to_stamp(max(new.t, 0.0), self.body_msg.header.stamp)
        self.body_msg.position = [float(x) for x in new.q[:3]]
        self.body_msg.velocity = [float(x) for x in new.v[:3]]
        self.body_msg.effort = [float(x) for x in new.acc[:3]]
        self.drops.publish(self.body_pub, self.body_msg)

    @property
    def failed(self):
        """Why the control thread died (None while it did not)."""
        return self.control.failed

    def status(self):
        """Return the status dict (the values of the diagnostics)."""
        with self.lock:
            st = self.rt.status()
            if self.external:
                st['controller'] = 'external'
                ext = self.cmd_in.status()
                for i, c in enumerate(CORNERS):
                    st['corners'][c] = dict(ext['corners'][c],
                                            current_a=float(self.rt.currents[i]))
                st['corners_normal'] = sum(d['mode'] == 'normal'
                                           for d in ext['corners'].values())
                st.update(lockstep=self.lockstep, lockstep_timeouts=self.lockstep_timeouts,
                          vehicle_states=self.vehicle_states, commands=ext['commands'],
                          command_sequence=ext['command_sequence'],
                          answered_sequence=ext['answered_sequence'])
            if self.look_ahead is not None:
                st['road_preview'] = self.look_ahead.status()
            if self.can:
                st['controller'] = 'can'
                st['can'] = self.link.status()
                for i, c in enumerate(CORNERS):
                    ch = st['can']['corners'][c]
                    reason = ('driver_fault' if ch['fault'] else 'driver_timeout'
                              if ch['timed_out'] else 'commanded_safe' if ch['failsafe_bit']
                              else 'ok')
                    st['corners'][c] = dict(ch, current_a=float(self.rt.currents[i]),
                                            mode='normal' if reason == 'ok' else 'failsafe',
                                            reason=reason)
                st['corners_normal'] = sum(d['mode'] == 'normal'
                                           for d in st['corners'].values())
        iso = self.rt.body_metrics()      # outside the lock: the samples recorded so far
        if iso:
            st['iso2631'] = iso
        loop = self.control.status()
        st.update(rate_hz=self.rate_hz, real_time_factor=self.rtf,
                  late_reanchors=loop.pop('late_reanchors'), loop=loop,
                  dropped=self.drops.counts())
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        problems = []
        if self.control.failed:
            problems.append((ERROR, f'control loop stopped: {self.control.failed}'))
        safe = [c for c, d in st['corners'].items() if d['mode'] != 'normal']
        if safe:
            problems.append((WARN, 'fail-safe at ' + ', '.join(
                f'{c} ({st["corners"][c]["reason"]})' for c in safe)))
        return worst(problems, st)

    def stop(self):
        """Stop the control thread, publish the final status, write the body log."""
        self.control.stop(2.0)
        if self.lane is not None:
            self.lane.close()
        if self.link is not None:
            self.link.stop()
            self.can_bus.shutdown()
        try:
            self.diagnostics.publish_final()
        except Exception as exc:  # noqa: B902 - the context may be gone after Ctrl-C
            print(f'full_car_node: no final status: {exc}', file=sys.stderr)
        if self.log_file:
            with self.lock:
                t, acc = self.rt.body_log()
            try:
                np.savez(self.log_file, t=t, acc=acc, joints=np.array(BODY_JOINTS))
                print(f'full_car_node: wrote {len(t)} body samples to {self.log_file}',
                      file=sys.stderr)
            except OSError as exc:
                print(f'full_car_node: cannot write {self.log_file}: {exc}', file=sys.stderr)


def main(args=None):
    """Entry point of ``full_car_node``."""
    return run_car_node(FullCarNode, 'full_car_node', args)


if __name__ == '__main__':
    sys.exit(main())
