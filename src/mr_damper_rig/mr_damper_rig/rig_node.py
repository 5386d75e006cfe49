"""
Rig node: the virtual MR damper rig, or a replay of a recorded DAQ CSV file or rosbag2.

``ros2 run mr_damper_rig rig_node`` (console script ``rig_node``).  Publishes one
``sensor_msgs/JointState`` per DAQ sample on the measurement topic, paced in real time times
``rate_factor`` by publishing the samples that are due at every timer tick (so the effective rate
is exact even though a 1 kHz rclpy timer is not); ``rate_factor`` 0 publishes as fast as the
consumer takes the samples: it keeps at most ``flow_window`` samples ahead of the
``samples_received`` count the consumer reports on ``flow_topic`` (the identifier's status; DDS
acknowledgements are no use for this: they arrive with the writer's heartbeat, every ~3 s).
In ``sim`` mode the true damper parameters are published (latched) for comparison. A JSON
status is published on the status topic.

Faults elsewhere never stop the rig: when a dead or stopped reader has filled the reliable
measurement writer's history, the writer is replaced (``node_utils.ResettablePublisher``,
``writer_resets`` in the status) and the samples due meanwhile are published once the healthy
readers have matched the new writer; other failed ``publish()`` calls are counted
(``dropped.publish_failed``) and logged, throttled. With ``current_source:=command`` each
current command is checked by :class:`mr_damper_model.commands.CurrentCommandLimiter`: out of
``[current_min_a, current_max_a]`` clamped, non-finite refused, both counted (``commands``)
with a throttled warning.

Hardware-in-the-loop (``excitation:=commanded``, see docs/hil.md): the piston follows the
displacement commands [m] of ``displacement_command_topic`` (std_msgs/Float64, reliable, depth
10; the quarter car's suspension travel) through a servo-actuator model
(:class:`mr_damper_rig.actuator.ServoActuator`: ``actuator`` order first | second | ideal,
``actuator_tau_s``, ``actuator_wn_rad_s``, ``actuator_zeta``, ``actuator_delay_s``). The rig
runs in lockstep with the car: each command received steps the actuator and the damper by one
DAQ period (``1 / rate_hz``, the car's control period) and publishes that sample at once, so a
loaded machine delays the loop but never lets the two clocks drift apart. Commands are checked
by :class:`mr_damper_rig.commands.DisplacementCommandGuard`: out of ``+-stroke_m`` clamped,
non-finite refused (the sample is still taken, with the last command held). When the car falls
silent for longer than ``command_timeout_s`` (wall time times ``rate_factor``), the rig runs on
its own clock from the last command on: it holds that command for ``command_timeout_s`` and then
returns to neutral at ``return_speed_m_s``; all counted in the status
(``displacement_commands``). ``wait_for_subscribers`` and ``duration_s`` do not apply.

Replay files are read and checked completely before the first sample is published; a bad file
ends the node with exit status 2 and one error line naming the file and the problem.
"""
import math
import sys
import time

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rcl_interfaces.msg import ParameterDescriptor
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, String

from mr_damper_model.commands import CurrentCommandLimiter
from mr_damper_model.data import DataError
from mr_damper_model.messages import (dict_to_array_msg, kwok_parameters_msg,
                                      measurement_to_msg, status_from_msg, status_msg)
from mr_damper_model.node_utils import (DropCounter, LATCHED_QOS, MEASUREMENT_QOS,
                                        ResettablePublisher, run_node, set_realtime_priority,
                                        spin_node, STATUS_QOS, stop_requested)

from .commands import CommandFollower, DisplacementCommandGuard
from .replay import ArraySource, MEASUREMENT_TOPIC, read_stream, SimSource

#: Current commands: only the newest matters; a command the rig could not take in time is lost
#: and counted (``dropped.command_lost``), the writer never waits for the rig.
COMMAND_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


class _Repeating:
    """A current schedule started again at the end of each pass (``duration_s`` None)."""

    duration_s = None

    def __init__(self, schedule):
        self._schedule = schedule
        self._period = float(schedule.duration_s)

    def __call__(self, t):
        return self._schedule(t % self._period)


def build_virtual_rig(options):
    """
    Build the virtual rig from the node's sim options.

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
    from mr_damper_model.plant import make_plant
    from mr_damper_model.params_file import load_params

    from . import excitation as exc_mod
    from .virtual_rig import VirtualRig
    params = None
    if options['truth_file']:
        params = load_params(options['truth_file'], model=options['plant']).parameters
    plant = make_plant(options['plant'], params)
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
        schedule = _Repeating(exc_mod.step_schedule(options['currents_a'], options['step_s']))
    else:
        raise ValueError("current_source must be 'schedule' or 'command', "
                         f"got {options['current_source']!r}")
    return VirtualRig(plant, excitation, schedule, sample_rate_hz=options['rate_hz'],
                      force_noise_n=options['noise_n'], rng=options['seed'])


class RigNode(Node):
    """Thin ROS adapter over the virtual rig and the replay readers."""

    def __init__(self):
        super().__init__('mr_damper_rig')
        d = self.declare_parameter
        d('mode', 'sim', ParameterDescriptor(description='sim | csv | bag'))
        d('file', '', ParameterDescriptor(description='CSV file (csv) or rosbag2 (bag)'))
        d('bag_topic', MEASUREMENT_TOPIC, ParameterDescriptor(
            description='Measurement topic inside the bag'))
        d('rate_factor', 1.0, ParameterDescriptor(
            description='Speed relative to real time; 0: as fast as subscribers acknowledge'))
        d('loop', False, ParameterDescriptor(description='Replay the file again and again'))
        d('time_offset_s', 0.0, ParameterDescriptor(
            description='Added to CSV time stamps [s]'))
        d('duration_s', 0.0, ParameterDescriptor(
            description='sim: simulated time to publish [s] (0: until stopped)'))
        d('exit_on_end', True, ParameterDescriptor(
            description='Exit (status 0) when the replay or the sim duration is done'))
        d('wait_for_subscribers', 0, ParameterDescriptor(
            description='Wait until this many measurement subscribers matched (max 30 s)'))
        d('flow_topic', '/mr_damper/identifier_status', ParameterDescriptor(
            description='rate_factor 0: JSON status whose samples_received paces the replay'))
        d('flow_window', 1000, ParameterDescriptor(
            description='rate_factor 0: samples allowed ahead of the consumer'))
        d('tick_s', 0.002, ParameterDescriptor(
            description='Publishing timer period [s] (samples due are published per tick)'))
        d('status_period_s', 0.5, ParameterDescriptor(description='Status period [s]'))
        d('realtime_priority', 0, ParameterDescriptor(
            description='SCHED_FIFO priority of the publishing threads (0: normal scheduling)'))
        d('measurement_topic', MEASUREMENT_TOPIC)
        d('true_parameters_topic', '/mr_damper/true_parameters')
        d('true_spencer_topic', '/mr_damper/true_spencer_parameters')
        d('current_command_topic', '/mr_damper/current_command')
        d('status_topic', '/mr_damper/rig_status')
        # sim options
        d('plant', 'spencer', ParameterDescriptor(description='spencer | kwok-current'))
        d('truth_file', '', ParameterDescriptor(
            description='Parameter file of the true damper (default: presets)'))
        d('excitation', 'cam', ParameterDescriptor(
            description='cam | multisine | chirp | random | commanded (hardware in the loop: '
            'follow displacement_command_topic through the actuator model)'))
        # hardware in the loop (excitation commanded)
        d('displacement_command_topic', '/mr_damper/displacement_command', ParameterDescriptor(
            description='commanded: piston displacement commands [m] (std_msgs/Float64)'))
        d('actuator', 'first', ParameterDescriptor(
            description='commanded: servo actuator model first | second | ideal'))
        d('actuator_tau_s', 0.012, ParameterDescriptor(
            description='commanded: time constant of the first-order actuator [s]'))
        d('actuator_wn_rad_s', 2 * math.pi * 25.0, ParameterDescriptor(
            description='commanded: natural frequency of the second-order actuator [rad/s]'))
        d('actuator_zeta', 0.7, ParameterDescriptor(
            description='commanded: damping ratio of the second-order actuator [-]'))
        d('actuator_delay_s', 0.002, ParameterDescriptor(
            description='commanded: transport delay of the actuator [s] (whole samples)'))
        d('stroke_m', 0.08, ParameterDescriptor(
            description='commanded: half stroke [m]; commands beyond are clamped (counted)'))
        d('command_timeout_s', 0.05, ParameterDescriptor(
            description='commanded: hold the last command this long [s, rig time], then '
            'return to neutral (counted)'))
        d('return_speed_m_s', 0.05, ParameterDescriptor(
            description='commanded: speed of the return to neutral [m/s]'))
        d('amplitude_m', 0.03, ParameterDescriptor(description='Excitation amplitude [m]'))
        d('frequency_hz', 1.1, ParameterDescriptor(description='Excitation frequency [Hz]'))
        d('currents_a', [0.0, 0.5, 1.0, 1.5, 2.0], ParameterDescriptor(
            description='Coil current schedule levels [A]'))
        d('step_s', 4.0, ParameterDescriptor(description='Dwell per current level [s]'))
        d('current_source', 'schedule', ParameterDescriptor(
            description='schedule | command (follow the current command topic)'))
        d('current_min_a', 0.0, ParameterDescriptor(
            description='Coil current minimum [A]: lower commands are clamped to it'))
        d('current_max_a', 2.0, ParameterDescriptor(
            description='Coil current maximum [A]: higher commands are clamped to it'))
        d('noise_n', 2.0, ParameterDescriptor(description='Load-cell noise std [N]'))
        d('seed', 1, ParameterDescriptor(description='Random seed of the sim'))
        d('rate_hz', 1000.0, ParameterDescriptor(description='sim DAQ rate [Hz]'))

        p = lambda name: self.get_parameter(name).value  # noqa: E731
        self.mode = p('mode')
        self.rate_factor = float(p('rate_factor'))
        if self.rate_factor < 0 or not math.isfinite(self.rate_factor):
            raise ValueError(f'rate_factor must be >= 0, got {self.rate_factor}')
        self.exit_on_end = bool(p('exit_on_end'))
        self.rig = None
        self.follower = None
        if self.mode in ('csv', 'bag'):
            if not p('file'):
                raise DataError(f'mode {self.mode} needs the `file` parameter')
            data = read_stream(self.mode, p('file'), p('bag_topic'))   # whole file checked
            self.source = ArraySource(data, loop=bool(p('loop')),
                                      offset_s=float(p('time_offset_s'))
                                      if self.mode == 'csv' else 0.0)
            self.get_logger().info(f'replaying {p("file")}: {data.n} samples, '
                                   f'{data.duration:.3f} s, x{self.rate_factor}')
        elif self.mode == 'sim':
            options = {k: p(k) for k in ('plant', 'excitation', 'amplitude_m', 'frequency_hz',
                                         'currents_a', 'step_s', 'current_source', 'noise_n',
                                         'seed', 'rate_hz', 'truth_file', 'actuator',
                                         'actuator_tau_s', 'actuator_wn_rad_s', 'actuator_zeta',
                                         'actuator_delay_s')}
            options['currents_a'] = [float(c) for c in options['currents_a']]
            self.rig = build_virtual_rig(options)
            sampler = self.rig
            if options['excitation'] == 'commanded':
                sampler = self.follower = CommandFollower(self.rig, DisplacementCommandGuard(
                    float(p('stroke_m')), float(p('command_timeout_s')),
                    float(p('return_speed_m_s')), self.rig.excitation.center_m))
            t0 = self.get_clock().now().nanoseconds * 1e-9
            self.source = SimSource(sampler, float(p('rate_hz')), t0, float(p('duration_s')))
            self.get_logger().info(f'virtual rig: {options["plant"]} damper, '
                                   f'{options["excitation"]} excitation, x{self.rate_factor}')
        else:
            raise ValueError(f"mode must be 'sim', 'csv' or 'bag', got {self.mode!r}")

        self.drops = DropCounter(self.get_logger())
        self.limiter = CurrentCommandLimiter(float(p('current_min_a')), float(p('current_max_a')))
        self._meas = ResettablePublisher(self, JointState, p('measurement_topic'),
                                         MEASUREMENT_QOS)
        self._pub_status = self.create_publisher(String, p('status_topic'), STATUS_QOS)
        if self.rig is not None:
            self._publish_truth(p('true_parameters_topic'), p('true_spencer_topic'))
            if p('current_source') == 'command':
                self.drops.subscribe(self, Float64, p('current_command_topic'), self._on_command,
                                     COMMAND_QOS, 'command_lost')
        if self.follower is not None:
            self.drops.subscribe(self, Float64, p('displacement_command_topic'),
                                 self._on_displacement, COMMAND_QOS, 'displacement_command_lost')
        self._flow_window = int(p('flow_window'))
        self._flow_received = None   # consumer's samples_received (latest, first seen)
        self._flow_base = None
        if self.rate_factor == 0:
            self.create_subscription(String, p('flow_topic'), self._on_flow, STATUS_QOS)
        self._wait_subs = int(p('wait_for_subscribers'))
        self._msg = None
        self.published = 0
        self.behind_max = 0
        self._last_cmd_wall = None   # commanded: wall time of the last command
        self._free = 0               # commanded: samples run on the rig's own clock since then
        self.commands = 0
        self.flow_restarts = 0
        self.finished = False
        self._start = None
        self._end = None
        self._created = time.monotonic()
        self.realtime = set_realtime_priority(int(p('realtime_priority')), self.get_logger())
        self.create_timer(float(p('tick_s')), self._tick)
        self.create_timer(float(p('status_period_s')), self._publish_status)

    def _publish_truth(self, kwok_topic, spencer_topic):
        truth = self.rig.true_parameters()
        model = truth.get('model')
        params = truth.get('parameters', {})
        if model == 'kwok-current':
            pub = self.create_publisher(Float64MultiArray, kwok_topic, LATCHED_QOS)
            values = dict(params)
            currents = [float(c) for c in self.get_parameter('currents_a').value] or [0.0]
            values.update(i_ref_a=float(truth.get('model_options', {}).get('i_ref_a', 2.0)),
                          window_end_s=0.0, current_min_a=min(currents),
                          current_max_a=max(currents), rmse_n=0.0,
                          nrmse_percent=0.0, valid=True)
            self.drops.publish(pub, kwok_parameters_msg(values))
        else:
            pub = self.create_publisher(Float64MultiArray, spencer_topic, LATCHED_QOS)
            self.drops.publish(pub, dict_to_array_msg({k: float(v) for k, v in params.items()}))
        self._truth_pub = pub

    def _on_command(self, msg):
        current, outcome = self.limiter.apply(msg.data)
        if current is None:
            self.get_logger().warning(
                f'current command {msg.data} A refused ({outcome}, '
                f'{self.limiter.counts[outcome]} in all)', throttle_duration_sec=1.0)
            return
        if outcome != 'accepted':
            self.get_logger().warning(
                f'current command {msg.data} A clamped to {current} A ({outcome}, '
                f'{self.limiter.counts[outcome]} in all)', throttle_duration_sec=1.0)
        self.rig.command_current(current)
        self.commands += 1

    def _on_displacement(self, msg):
        target, outcome = self.follower.command(msg.data)
        if outcome != 'accepted':
            what = 'refused' if target is None else f'clamped to {target} m'
            self.get_logger().warning(
                f'displacement command {msg.data} m {what} ({outcome}, '
                f'{self.follower.guard.counts[outcome]} in all)', throttle_duration_sec=1.0)
        if self._start is None:
            self._start = time.monotonic()
            self.source.t0 = self.get_clock().now().nanoseconds * 1e-9
        self._last_cmd_wall = time.monotonic()
        self._free = 0
        self._publish_sample()   # lockstep: one rig sample per car step

    def _publish_sample(self):
        self._msg = measurement_to_msg(*self.source.sample(self.published), msg=self._msg)
        self.published += 1
        if not self._meas.publish(self._msg):
            self.drops.count('measurement_not_published')

    def _tick_commanded(self):
        """Run on the rig's own clock while the car is silent (hold, then back to neutral)."""
        if self._last_cmd_wall is None:
            return
        silent_s = (time.monotonic() - self._last_cmd_wall) * (self.rate_factor or 1.0)
        if silent_s <= self.follower.guard.timeout_s:
            return
        due = int(silent_s * self.follower.rig.sample_rate_hz) - self._free
        for _ in range(max(0, min(due, 5000))):
            self._publish_sample()
            self._free += 1

    def _on_flow(self, msg):
        try:
            received = int(status_from_msg(msg)['samples_received'])
        except (ValueError, KeyError, TypeError):
            return
        if self._flow_received is not None and received < self._flow_received \
                and self._flow_base is not None:
            # the consumer restarted (its count began again): pace against the new count
            self._flow_base = received - self.published
            self.flow_restarts += 1
        self._flow_received = received
        if self._flow_base is None and self._start is None:
            self._flow_base = received

    def _tick(self):
        if self.finished:
            return
        if self.follower is not None:
            self._tick_commanded()
            return
        if self._start is None:
            subs = self._meas.get_subscription_count()
            waiting = time.monotonic() - self._created < 30.0
            if subs < self._wait_subs and waiting:
                return
            if self.rate_factor == 0 and self._flow_base is None and waiting:
                return   # the consumer's first status gives the base count
            self._start = time.monotonic()
            if self.rig is not None:   # stamps: wall clock at the first sample + sim time
                self.source.t0 = self.get_clock().now().nanoseconds * 1e-9
        total = self.source.total()
        if self.rate_factor > 0:
            due = self.source.count_due((time.monotonic() - self._start) * self.rate_factor)
        elif self._flow_base is not None:
            due = self._flow_received - self._flow_base + self._flow_window
        else:
            due = self.published + 1   # no flow status: one sample per tick
        if total is not None:
            due = min(due, total)
        if self.rate_factor > 0:
            self.behind_max = max(self.behind_max, due - self.published)
        n = max(0, min(due - self.published, 5000))
        for _ in range(n):
            self._msg = measurement_to_msg(*self.source.sample(self.published), msg=self._msg)
            if not self._meas.publish(self._msg):
                break   # writer replaced: this sample and the rest go out once it is ready
            self.published += 1
        if total is not None and self.published >= total:
            self._end = time.monotonic()
            self._wait_acked(self._meas.publisher, 10.0)
            self.finished = True
            self._publish_status()
            self._wait_acked(self._pub_status, 2.0)   # final status out
            self.get_logger().info(f'done: {self.published} samples published')

    def flush(self, timeout_s=1.5):
        """
        At shutdown: let the readers take the samples still in the writer, at most ``timeout_s``.

        A reader that is behind (it takes the stream in bursts) gets the rest of it before the
        writer goes; a dead or stopped one cannot delay the exit by more than ``timeout_s``.
        """
        self._wait_acked(self._meas.publisher, timeout_s, on_stop=True)

    @staticmethod
    def _wait_acked(pub, timeout_s, on_stop=False):
        """Wait for the readers' acknowledgements, at most ``timeout_s`` (or a stop request)."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and (on_stop or not stop_requested()):
            if pub.wait_for_all_acked(Duration(seconds=0.1)):
                return True
        return False

    def _publish_status(self):
        end = self._end if self._end is not None else time.monotonic()
        elapsed = end - self._start if self._start else 0.0
        status = {'mode': self.mode, 'samples_published': self.published,
                  'rate_factor': self.rate_factor, 'elapsed_s': elapsed,
                  'effective_rate_hz': self.published / elapsed if elapsed > 0 else 0.0,
                  'behind_max_samples': self.behind_max, 'done': self.finished,
                  'subscribers': self._meas.get_subscription_count(),
                  'writer_resets': self._meas.resets,
                  'current_commands': self.commands, 'commands': dict(self.limiter.counts),
                  'dropped': self.drops.counts(), 'flow_restarts': self.flow_restarts,
                  'realtime': self.realtime}
        if self.follower is not None:
            status['displacement_commands'] = dict(self.follower.guard.counts)
            status['actuator'] = {'kind': self.follower.rig.excitation.actuator.kind,
                                  'equivalent_delay_s':
                                      self.follower.rig.excitation.actuator.equivalent_delay_s}
        if self.rig is not None:
            status['coil_current_a'] = float(getattr(self.rig.plant, 'current', math.nan))
        self.drops.publish(self._pub_status, status_msg(status))


def main(args=None):
    """Run the rig node; exit status 2 on a bad file or parameter."""
    return run_node(RigNode, 'rig_node', (DataError, ValueError),
                    run=lambda node: spin_node(node, lambda: node.finished and node.exit_on_end),
                    finish=lambda node: node.flush(), args=args)


if __name__ == '__main__':
    sys.exit(main())
