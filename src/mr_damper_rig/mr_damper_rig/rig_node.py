"""
Rig node: the virtual MR damper rig, or a replay of a recorded DAQ CSV file or rosbag2.

``ros2 run mr_damper_rig rig_node`` (console script ``rig_node``). Converts messages and calls
the core: :class:`mr_damper_rig.pacing.Pacer` says how many samples are due at each tick (real
time times ``rate_factor``, or with ``rate_factor`` 0 at most ``flow_window`` samples ahead of
the consumer's count on ``mr_damper/samples_received``), the sources of
:mod:`mr_damper_rig.replay` give the samples, :mod:`mr_damper_rig.commands` checks the commands
and :class:`mr_damper_rig.rig_health.RigHealth` turns the counters into ``/diagnostics``.

Topics (relative names: remap them with ``--ros-args -r old:=new`` or start the node in a
namespace, ``-r __ns:=/fl``): publishes ``mr_damper/measurement``
(mr_damper_interfaces/DamperSamples: ``samples_per_message`` consecutive DAQ samples per
message, cut by :class:`mr_damper_rig.batching.BatchStream`; reliable keep-all), in ``sim``
mode the latched truth on ``mr_damper/true_parameters`` (KwokParameters, kwok-current plant) or
``mr_damper/true_spencer_parameters`` (DamperModel, Spencer plant), ``/diagnostics``, and with
``publish_clock`` (csv / bag replays) ``/clock``: one rosgraph_msgs/Clock per timer tick in
which samples went out, carrying the stamp of the newest of them, so nodes started with
``use_sim_time:=true`` run on the recording's time at any ``rate_factor``. The rig's own
timers and pacing stay on wall time (a steady clock): it is the clock source. Subscribes to
``mr_damper/current_command`` (std_msgs/Float64, ``current_source:=command``),
``mr_damper/displacement_command`` (std_msgs/Float64, ``excitation:=commanded``) and
``mr_damper/samples_received`` (std_msgs/UInt64, ``rate_factor`` 0).

Faults elsewhere never stop the rig: when a dead or stopped reader has filled the reliable
measurement writer's history, the writer is replaced (``node_utils.ResettablePublisher``,
``writer_resets`` in the diagnostics) and the samples due meanwhile are published once the healthy
readers have matched the new writer; other failed ``publish()`` calls are counted
(``dropped.publish_failed``) and logged, throttled. With ``current_source:=command`` each
current command is checked by :class:`mr_damper_common.commands.CurrentCommandLimiter`: out of
``[current_min_a, current_max_a]`` clamped, non-finite refused, both counted (``commands``)
with a throttled warning.

Hardware-in-the-loop (``excitation:=commanded``, see docs/hil.md): the piston follows the
displacement commands [m] through a servo-actuator model, in lockstep with the car: each command
received steps the actuator and the damper by one DAQ period and publishes that sample at once,
alone, on ``mr_damper/hil_measurement`` (DamperSamples of one sample, reliable depth 10);
``mr_damper/measurement`` carries the same samples in batches. Commands beyond ``+-stroke_m`` are
clamped, non-finite refused; a car silent for longer than ``command_timeout_s`` (wall time times
``rate_factor``) makes the rig run on its own clock, holding and then returning to neutral
(:class:`mr_damper_rig.pacing.LockstepPacer`). The tracking error (guarded target minus measured
displacement) is in the diagnostics.

Replay files are read and checked completely before the first sample is published; a bad file
ends the node with exit status 2 and one error line naming the file and the problem.
"""
import math
import sys
import time

import numpy as np

from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg
from mr_damper_interfaces.msg import DamperModel, DamperSamples, KwokParameters
from std_msgs.msg import Float64, UInt64

from mr_damper_common.commands import CurrentCommandLimiter
from mr_damper_model.io.data import DataError
from mr_damper_common.messages import (damper_model_msg, kwok_parameters_msg, samples_to_msg,
                                       seconds_to_stamp)
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, DropCounter,
                                         LATCHED_QOS, MEASUREMENT_QOS, node_time_s, Param,
                                         ResettablePublisher, run_node, set_realtime_priority,
                                         spin_node, STATUS_QOS, stop_requested)

from .batching import BatchStream
from .commands import CommandFollower, DisplacementCommandGuard
from .pacing import LockstepPacer, Pacer
from .replay import ArraySource, MEASUREMENT_TOPIC, read_stream, SimSource
from .rig_health import RigHealth
from .virtual_rig import build_virtual_rig

#: Current and displacement commands: only the newest matters; a command the rig could not
#: take in time is overwritten by the next (the writer never waits). ``std_msgs/Float64``
#: carries no number: the rig counts the commands it took (``current_commands``), to set
#: against the sender's count (docs/faults.md, Lost messages).
COMMAND_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: ``/clock``: reliable keep-last (rclpy's time source reads it best effort, depth 1).
CLOCK_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE)

#: Relative topic names (resolved in the node's namespace).
MEASUREMENT = 'mr_damper/measurement'
TRUE_PARAMETERS = 'mr_damper/true_parameters'
TRUE_SPENCER = 'mr_damper/true_spencer_parameters'
CURRENT_COMMAND = 'mr_damper/current_command'
DISPLACEMENT_COMMAND = 'mr_damper/displacement_command'
SAMPLES_RECEIVED = 'mr_damper/samples_received'
#: Hardware in the loop: each lockstep sample at once, alone, for the car (the measurement
#: stream still carries every sample, in batches, for the identifier and the recorder).
HIL_MEASUREMENT = 'mr_damper/hil_measurement'

#: Every parameter of the rig node (the one place they are declared).
PARAMETERS = (
    Param('mode', 'sim', 'Source: sim (virtual rig) or csv / bag (replay of a file)'),
    Param('file', '', 'CSV file (csv) or rosbag2 directory / .db3 / .mcap (bag)'),
    Param('bag_topic', MEASUREMENT_TOPIC,
          'bag: measurement topic inside the bag (DamperSamples or sensor_msgs/JointState)'),
    Param('rate_factor', 1.0, 'Speed relative to real time [-]; 0: as fast as the consumer '
          'takes the samples (flow control on mr_damper/samples_received); changes between '
          'values > 0 while running', 0.0, 1000.0, dynamic=True),
    Param('loop', False, 'Replay the file again and again (stamps keep increasing)'),
    Param('time_offset_s', 0.0, 'csv: added to the time stamps [s]', -1e9, 1e9),
    Param('duration_s', 0.0, 'sim: simulated time to publish [s] (0: until stopped)',
          0.0, 1e9),
    Param('exit_on_end', True, 'Exit (status 0) when the replay or the sim duration is done'),
    Param('wait_for_subscribers', 0, 'Wait until this many measurement readers matched '
          '(at most 30 s) before the first sample', 0, 1000),
    Param('flow_window', 1000, 'rate_factor 0: samples allowed ahead of the consumer\'s '
          'count', 1, 10_000_000, dynamic=True),
    Param('samples_per_message', 20, 'Samples per measurement message (DamperSamples batch): '
          'a batch goes out when its last sample is due, so it adds at most this many DAQ '
          'periods of latency (hardware in the loop: each sample also goes out at once, alone, '
          'on mr_damper/hil_measurement)', 1, 100000),
    Param('tick_s', 0.002, 'Publishing timer period [s, wall time]: the samples due are '
          'published at every tick', 1e-4, 1.0),
    Param('publish_clock', False, 'csv / bag: publish /clock (one per tick) from the stamps '
          'of the published samples, for nodes with use_sim_time'),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('stop_flush_s', 5.0, 'At shutdown: wait at most this long [s, wall time] for the '
          'measurement readers to acknowledge the samples still in the writer (a reader behind '
          'on a loaded machine gets the rest; a dead one delays the exit this long at most)',
          0.0, 60.0),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the publishing threads '
          '(0: normal scheduling; needs root)', 0, 99),
    Param('plant', 'spencer', 'sim: true damper model, spencer or kwok-current'),
    Param('truth_file', '', 'sim: parameter file of the true damper (empty: presets)'),
    Param('excitation', 'cam', 'sim: piston motion, cam, multisine, chirp, random or '
          'commanded (hardware in the loop: follow mr_damper/displacement_command)'),
    Param('actuator', 'first', 'commanded: servo actuator model first, second or ideal'),
    Param('actuator_tau_s', 0.012, 'commanded: time constant of the first-order actuator [s]',
          0.0, 10.0),
    Param('actuator_wn_rad_s', 2 * math.pi * 25.0,
          'commanded: natural frequency of the second-order actuator [rad/s]', 0.0, 1e5),
    Param('actuator_zeta', 0.7, 'commanded: damping ratio of the second-order actuator [-]',
          0.0, 10.0),
    Param('actuator_delay_s', 0.002, 'commanded: transport delay of the actuator [s] '
          '(whole samples)', 0.0, 1.0),
    Param('stroke_m', 0.08, 'commanded: half stroke [m]; commands beyond are clamped '
          '(counted)', 1e-6, 1.0, dynamic=True),
    Param('command_timeout_s', 0.05, 'commanded: hold the last command this long [s, rig '
          'time], then return to neutral (counted)', 1e-6, 60.0, dynamic=True),
    Param('return_speed_m_s', 0.05, 'commanded: speed of the return to neutral [m/s]',
          1e-6, 10.0, dynamic=True),
    Param('amplitude_m', 0.03, 'sim: excitation amplitude [m]', 0.0, 1.0),
    Param('frequency_hz', 1.1, 'sim: excitation frequency [Hz]', 0.0, 1000.0),
    Param('currents_a', [0.0, 0.5, 1.0, 1.5, 2.0],
          'sim: coil current schedule levels [A], repeated'),
    Param('step_s', 4.0, 'sim: dwell per current level [s]', 1e-3, 1e6),
    Param('current_source', 'schedule', 'sim: coil current from the schedule, or command '
          '(follow mr_damper/current_command)'),
    Param('current_min_a', 0.0, 'Coil current minimum [A]: lower commands are clamped to it',
          -10.0, 10.0, dynamic=True),
    Param('current_max_a', 2.0, 'Coil current maximum [A]: higher commands are clamped to it',
          -10.0, 10.0, dynamic=True),
    Param('noise_n', 2.0, 'sim: load-cell noise standard deviation [N]', 0.0, 1e6),
    Param('seed', 1, 'sim: random seed', 0, 2 ** 31 - 1),
    Param('rate_hz', 1000.0, 'sim: DAQ rate [Hz]', 1.0, 1e6),
)


class RigNode(Node):
    """Thin ROS adapter over the virtual rig, the replay sources and the pacer."""

    def __init__(self, **kwargs):
        super().__init__('mr_damper_rig', **kwargs)   # kwargs: e.g. parameter_overrides (tests)
        p = declare_parameters(self, PARAMETERS, self._on_set)
        self.mode = p['mode']
        self.exit_on_end = bool(p['exit_on_end'])
        self.stop_flush_s = float(p['stop_flush_s'])
        self.rig = None
        self.follower = None
        if self.mode in ('csv', 'bag'):
            if not p['file']:
                raise DataError(f'mode {self.mode} needs the `file` parameter')
            data = read_stream(self.mode, p['file'], p['bag_topic'])   # whole file checked
            self.source = ArraySource(data, loop=bool(p['loop']),
                                      offset_s=float(p['time_offset_s'])
                                      if self.mode == 'csv' else 0.0)
            hardware = f'replay {p["file"]}'
            self.get_logger().info(f'replaying {p["file"]}: {data.n} samples, '
                                   f'{data.duration:.3f} s, x{p["rate_factor"]}')
        elif self.mode == 'sim':
            options = {k: p[k] for k in ('plant', 'excitation', 'amplitude_m', 'frequency_hz',
                                         'currents_a', 'step_s', 'current_source', 'noise_n',
                                         'seed', 'rate_hz', 'truth_file', 'actuator',
                                         'actuator_tau_s', 'actuator_wn_rad_s', 'actuator_zeta',
                                         'actuator_delay_s')}
            options['currents_a'] = [float(c) for c in options['currents_a']]
            self.rig = build_virtual_rig(options)
            sampler = self.rig
            if options['excitation'] == 'commanded':
                sampler = self.follower = CommandFollower(self.rig, DisplacementCommandGuard(
                    p['stroke_m'], p['command_timeout_s'], p['return_speed_m_s'],
                    self.rig.excitation.center_m))
            self.source = SimSource(sampler, float(p['rate_hz']), self._now_s(),
                                    float(p['duration_s']))
            hardware = f'virtual rig ({options["plant"]})'
            self.get_logger().info(f'virtual rig: {options["plant"]} damper, '
                                   f'{options["excitation"]} excitation, x{p["rate_factor"]}')
        else:
            raise ValueError(f"mode must be 'sim', 'csv' or 'bag', got {self.mode!r}")
        publish_clock = bool(p['publish_clock'])
        if publish_clock and self.mode == 'sim':
            raise ValueError('publish_clock needs a replay (mode csv or bag): the sim rig '
                             'stamps its samples with the wall clock')
        if publish_clock and self.get_parameter('use_sim_time').value:
            raise ValueError('publish_clock and use_sim_time together: the rig is the clock '
                             'source, start it on wall time')

        # Wall time is the point here: the rig paces the stream (and is the clock source of a
        # replay), so its timers and its pacer run on a steady clock, never on /clock.
        if self.follower is not None:
            self.pacer = LockstepPacer(float(p['rate_hz']), float(p['command_timeout_s']),
                                       float(p['rate_factor']), clock=time.monotonic,
                                       wait_for_subscribers=int(p['wait_for_subscribers']))
        else:
            self.pacer = Pacer(self.source, float(p['rate_factor']), clock=time.monotonic,
                               wait_for_subscribers=int(p['wait_for_subscribers']),
                               flow_window=int(p['flow_window']))
        self.drops = DropCounter(self.get_logger())
        self.limiter = CurrentCommandLimiter(p['current_min_a'], p['current_max_a'])
        self._health = RigHealth()
        self._wait_subs = int(p['wait_for_subscribers'])
        self._meas = ResettablePublisher(self, DamperSamples, MEASUREMENT, MEASUREMENT_QOS)
        self.stream = BatchStream(self.source, self.pacer, int(p['samples_per_message']))
        self._period_s = (1.0 / float(p['rate_hz']) if self.mode == 'sim'
                          else self._median_period(self.source))
        self._clock_pub = (self.create_publisher(ClockMsg, '/clock', CLOCK_QOS)
                           if publish_clock else None)
        self._clock_msg = ClockMsg()
        self.clock_published = 0
        self.clock_last_s = math.nan
        if self.rig is not None:
            self._publish_truth()
            if p['current_source'] == 'command':
                self.drops.subscribe(self, Float64, CURRENT_COMMAND, self._on_command,
                                     COMMAND_QOS)
        self._link_msg = None
        if self.follower is not None:
            self._link_pub = self.create_publisher(DamperSamples, HIL_MEASUREMENT, COMMAND_QOS)
            self._displacement_sub = None   # opened once the measurement readers matched
        elif self.pacer.rate_factor == 0:
            self.create_subscription(UInt64, SAMPLES_RECEIVED, self._on_flow, STATUS_QOS)
        self._msg = None
        self.backlog = 0
        self.commands = 0
        self.finished = False
        self.realtime = set_realtime_priority(int(p['realtime_priority']), self.get_logger())
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(float(p['tick_s']), self._tick, clock=self._wall)
        self._diag = DiagnosticsPublisher(self, self.health, period_s=p['diagnostics_period_s'],
                                          hardware_id=hardware, drops=self.drops)

    def _now_s(self):
        """Return the node clock's time [s] (ROS time under ``use_sim_time``)."""
        return node_time_s(self)

    def _on_set(self, changes):
        """Apply dynamic parameters to the core objects; return '' or why they are refused."""
        new = {name: self.get_parameter(name).value for name in
               ('current_min_a', 'current_max_a', 'stroke_m', 'command_timeout_s',
                'return_speed_m_s')}
        new.update(changes)
        guard_keys = {'stroke_m', 'command_timeout_s', 'return_speed_m_s'}
        try:
            follows_current = (self.rig is not None and
                               self.get_parameter('current_source').value == 'command')
            if {'current_min_a', 'current_max_a'} & set(changes) and not follows_current:
                return 'current_min_a / current_max_a apply only with current_source:=command'
            if guard_keys & set(changes) and self.follower is None:
                return (f'{sorted(guard_keys & set(changes))} apply only with '
                        'excitation:=commanded')
            if 'rate_factor' in changes and (changes['rate_factor'] == 0) != (
                    self.pacer.rate_factor == 0):
                return ('rate_factor cannot change to or from 0 while running (flow control '
                        'is chosen at start-up)')
            if 'flow_window' in changes and (self.follower is not None
                                             or self.pacer.rate_factor != 0):
                return 'flow_window applies only with rate_factor 0 (not to a commanded rig)'
            CurrentCommandLimiter(new['current_min_a'], new['current_max_a'])   # check only
            if 'rate_factor' in changes:
                self.pacer.set_rate_factor(changes['rate_factor'])
            if 'flow_window' in changes:
                self.pacer.set_flow_window(changes['flow_window'])
            self.limiter.set_range(new['current_min_a'], new['current_max_a'])
            if self.follower is not None:
                self.follower.guard.configure(stroke_m=new['stroke_m'],
                                              timeout_s=new['command_timeout_s'],
                                              return_speed_m_s=new['return_speed_m_s'])
                self.pacer.timeout_s = float(new['command_timeout_s'])
        except ValueError as exc:
            return str(exc)
        return ''

    def _publish_truth(self):
        truth = self.rig.true_parameters()
        model = truth.get('model')
        params = truth.get('parameters', {})
        if model == 'kwok-current':
            pub = self.create_publisher(KwokParameters, TRUE_PARAMETERS, LATCHED_QOS)
            values = dict(params)
            currents = [float(c) for c in self.get_parameter('currents_a').value] or [0.0]
            values.update(i_ref_a=float(truth.get('model_options', {}).get('i_ref_a', 2.0)),
                          current_min_a=min(currents),
                          current_max_a=max(currents), rmse_n=0.0,
                          nrmse_percent=0.0, valid=True)
            self.drops.publish(pub, kwok_parameters_msg(values, stamp_s=self._now_s()))
        else:
            pub = self.create_publisher(DamperModel, TRUE_SPENCER, LATCHED_QOS)
            self.drops.publish(pub, damper_model_msg(model, params, truth.get('model_options'),
                                                     stamp_s=self._now_s()))
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

    def _open_link(self):
        """
        Take displacement commands once ``wait_for_subscribers`` measurement readers matched.

        Until then the car, which waits for its link to be matched both ways before its first
        step, does not start: the identifier and the recorder see the stream from its first
        sample.
        """
        if self.pacer.accepting(self._meas.get_subscription_count()):
            self._displacement_sub = self.drops.subscribe(
                self, Float64, DISPLACEMENT_COMMAND, self._on_displacement, COMMAND_QOS)
            self.get_logger().info(
                f'taking displacement commands ({self._meas.get_subscription_count()} '
                f'measurement readers, {self._wait_subs} awaited)')

    def _on_displacement(self, msg):
        target, outcome = self.follower.command(msg.data)
        if outcome != 'accepted':
            what = 'refused' if target is None else f'clamped to {target} m'
            self.get_logger().warning(
                f'displacement command {msg.data} m {what} ({outcome}, '
                f'{self.follower.guard.counts[outcome]} in all)', throttle_duration_sec=1.0)
        if self.pacer.start_s is None:
            self.source.t0 = self._now_s()
        self.pacer.command()
        self._publish_lockstep()   # lockstep: one rig sample per car step

    def _publish_lockstep(self, free=False):
        """Send the next sample alone on the car's link, then the measurement batches due."""
        if not self.stream.publish_one(self._publish_link, free=free):
            self.drops.count('hil_sample_not_published')
        self.stream.publish_full(self._publish_batch)

    def _publish_link(self, t, x, v, f, i, sequence, first_index):
        """Hardware in the loop: one sample at once on ``mr_damper/hil_measurement``."""
        self._link_msg = samples_to_msg(t, x, v, f, i, sequence=sequence,
                                        first_index=first_index,
                                        sample_period_s=self._period_s, msg=self._link_msg)
        return self.drops.publish(self._link_pub, self._link_msg, 'hil_publish_failed')

    def _publish_batch(self, t, x, v, f, i, sequence, first_index):
        """Convert one batch to ``DamperSamples`` and publish it; True if it went out."""
        self._msg = samples_to_msg(t, x, v, f, i, sequence=sequence, first_index=first_index,
                                   sample_period_s=self._period_s, msg=self._msg)
        return self._meas.publish(self._msg)

    @staticmethod
    def _median_period(source):
        """Nominal DAQ period of a replay [s] (median stamp step; 0 if irregular)."""
        steps = source.rel[1:] - source.rel[:-1]
        if not steps.size:
            return 0.0
        period = float(np.median(steps))
        return period if np.allclose(steps, period, rtol=0.01, atol=0.0) else 0.0

    def _on_flow(self, msg):
        self.pacer.on_flow(msg.data)

    def _tick(self):
        if self.finished:
            return
        if self.follower is not None:
            if self._displacement_sub is None:
                self._open_link()
            for _ in range(self.pacer.due()):   # the car is silent: the rig's own clock
                self._publish_lockstep(free=True)
            return
        if not self.pacer.started:
            if self.pacer.waiting(self._meas.get_subscription_count()):
                return
            if self.rig is not None:   # stamps: ROS time at the first sample + sim time
                self.source.t0 = self._now_s()
        due, sent = self.stream.tick(self._publish_batch)
        self.backlog = due - sent
        if sent and self._clock_pub is not None:
            self.clock_last_s = self.stream.newest_s
            seconds_to_stamp(self.clock_last_s, self._clock_msg.clock)
            if self.drops.publish(self._clock_pub, self._clock_msg, 'clock_publish_failed'):
                self.clock_published += 1
        if self.pacer.finished:
            self._wait_acked(self._meas.publisher, 10.0)
            self.finished = True
            self._diag.publish()
            self._wait_acked(self._diag.publisher, 2.0)   # final status out
            self.get_logger().info(f'done: {self.pacer.published} samples published')

    def status_values(self):
        """Return the rig's status values (what ``/diagnostics`` carries)."""
        values = {'mode': self.mode, **self.pacer.values(), 'backlog_samples': self.backlog,
                  'messages_published': self.stream.sequence,
                  'samples_per_message': self.stream.samples_per_message,
                  'subscribers': self._meas.get_subscription_count(),
                  'wait_for_subscribers': self._wait_subs, 'writer_resets': self._meas.resets,
                  'current_commands': self.commands, 'commands': dict(self.limiter.counts),
                  'dropped': self.drops.counts(), 'realtime': self.realtime}
        values['done'] = self.finished
        if self.follower is not None:
            actuator = self.follower.rig.excitation.actuator
            values['displacement_commands'] = dict(self.follower.guard.counts)
            values['actuator'] = {'kind': actuator.kind,
                                  'equivalent_delay_s': actuator.equivalent_delay_s}
            values['tracking_error'] = self.follower.tracking.as_dict()
        if self.rig is not None:
            values['coil_current_a'] = float(getattr(self.rig.plant, 'current', math.nan))
        if self._clock_pub is not None:
            values['clock'] = {'published': self.clock_published, 'last_s': self.clock_last_s}
        return values

    def health(self):
        """Return the rig's :class:`~mr_damper_common.health.Health` (for ``/diagnostics``)."""
        return self._health(self.status_values())

    def flush(self, timeout_s=None):
        """
        At shutdown: let the readers take the samples still in the writer.

        At most ``timeout_s`` (default: the ``stop_flush_s`` parameter). A reader that is
        behind (it takes the stream in bursts; with a fixed 1.5 s a loaded suite's recording
        ended 1,340 samples short of the identifier's count) gets the rest of it before the
        writer goes; a dead or stopped one cannot delay the exit by more than ``timeout_s``.
        """
        timeout_s = self.stop_flush_s if timeout_s is None else timeout_s
        self._wait_acked(self._meas.publisher, timeout_s, on_stop=True)

    @staticmethod
    def _wait_acked(pub, timeout_s, on_stop=False):
        """Wait for the readers' acknowledgements, at most ``timeout_s`` (or a stop request)."""
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and (on_stop or not stop_requested()):
            if pub.wait_for_all_acked(Duration(seconds=0.1)):
                return True
        return False


def main(args=None):
    """Run the rig node; exit status 2 on a bad file or parameter."""
    return run_node(RigNode, 'rig_node', (DataError, ValueError),
                    run=lambda node: spin_node(node, lambda: node.finished and node.exit_on_end),
                    finish=lambda node: node.flush(), args=args)


if __name__ == '__main__':
    sys.exit(main())
