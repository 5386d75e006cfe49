"""
``mr-damper-record``: record every suite topic into ONE MCAP file with typed schemas.

For machines without ``ros2 bag``: subscribes to every row of the topic table
(:data:`mr_damper_bringup.topics.SUITE_TOPICS`: measurement, parameters, true parameters,
current and displacement commands, car state, ride metrics, statuses) and hands each message,
still serialised, to :class:`mr_damper_bringup.recorder.SuiteRecorder` (rosbags writer,
streamed to disk) until Ctrl-C (SIGINT) or SIGTERM, ``--duration`` seconds or ``--count``
measurements. The measurement topic is read with the rig's reliable KEEP_ALL QoS
(``node_utils.MEASUREMENT_QOS``): nothing is lost. On a stop it keeps taking messages until none
has arrived for ``--quiet-s`` (the stream in flight is drained), then closes the file properly
and exits 0. It publishes its counts on ``/diagnostics`` (status ``mr_damper_record``; the
launcher waits on them at shutdown). The file opens in Foxglove / PlotJuggler; its
measurement topic replays with ``rig_node --ros-args -p mode:=bag -p file:=FILE.mcap`` and feeds
``mr-damper-identify``.

Example::

    mr-damper-record --out run1.mcap --duration 60
    mr-damper-record --out meas.mcap --only measurement      # the measurement topic alone
"""
import argparse
import array
import faulthandler
from pathlib import Path
import sys
import time

import rclpy
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.executors import ExternalShutdownException
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
import yaml

from mr_damper_common.health import Health, OK, WARN
from mr_damper_common.node_utils import (DiagnosticsPublisher, DropCounter, install_stop_handlers,
                                         make_executor, MEASUREMENT_QOS, PARAMETERS_QOS,
                                         stop_requested, tear_down)

from .processes import wait_while_progressing
from .recorder import SuiteRecorder
from .topics import (CAN_TOPICS, message_class, namespaced_table, NODE_PARAMETERS_TOPIC,
                     PARAMETER_NODES, SENSING_TOPICS, SUITE_TOPICS, topic_table)

#: QoS of each kind of the topic table (reliable readers match every writer of the suite)
QOS = {'measurement': MEASUREMENT_QOS, 'latched': PARAMETERS_QOS,
       'default': QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST,
                             reliability=ReliabilityPolicy.RELIABLE)}


class ParameterPoller:
    """
    Ask each suite node for all its parameters every ``period_s``; record a set when it changed.

    Uses the nodes' standard parameter services (``/NODE/list_parameters``,
    ``/NODE/get_parameters``), so the recording holds the values each node runs with, its own
    defaults included; a node that is not up is skipped until it is.
    """

    def __init__(self, node, recorder, names, period_s):
        self.node = node
        self.recorder = recorder
        self.clients = {name: (node.create_client(ListParameters, f'/{name}/list_parameters'),
                               node.create_client(GetParameters, f'/{name}/get_parameters'))
                        for name in names}
        self.last = {}
        self.busy = set()
        self.timer = node.create_timer(period_s, self.poll)

    def poll(self):
        """Send a list request to every node that is up and not already being asked."""
        for name, (lister, getter) in self.clients.items():
            if name in self.busy or not (lister.service_is_ready() and getter.service_is_ready()):
                continue
            self.busy.add(name)
            future = lister.call_async(ListParameters.Request())
            future.add_done_callback(lambda f, name=name: self._listed(name, f))

    def _listed(self, name, future):
        try:
            names = list(future.result().result.names)
        except Exception:  # noqa: B902 - the node went away: ask again next period
            self.busy.discard(name)
            return
        request = GetParameters.Request(names=names)
        future = self.clients[name][1].call_async(request)
        future.add_done_callback(lambda f, name=name, names=names: self._got(name, names, f))

    def _got(self, name, names, future):
        self.busy.discard(name)
        try:
            values = future.result().values
        except Exception:  # noqa: B902 - as above
            return
        params = {}
        for key, value in zip(names, values):
            value = parameter_value_to_python(value)
            if isinstance(value, (array.array, list, tuple)):
                value = list(value)
            params[key] = value
        if params and params != self.last.get(name):
            self.last[name] = params
            self.recorder.write_text(
                NODE_PARAMETERS_TOPIC, yaml.safe_dump({name: {'ros__parameters': params}}),
                self.node.get_clock().now().nanoseconds)


def _parser():
    p = argparse.ArgumentParser(prog='mr-damper-record', description=__doc__.split('\n')[1])
    p.add_argument('--out', required=True, help='MCAP file to create (must not exist)')
    p.add_argument('--only', action='append', metavar='KEY',
                   choices=sorted({**SUITE_TOPICS, **CAN_TOPICS, **SENSING_TOPICS}),
                   help='record only this topic key (repeat; default: every suite topic)')
    p.add_argument('--can', action='store_true',
                   help='also the CAN bridge\'s topics (measured current, can/car_state, '
                        'can/body_imu, can/wheel_imu)')
    p.add_argument('--sensing', action='store_true',
                   help='also the vehicle sensing topics (quarter_car/body_imu, '
                        'quarter_car/suspension_position, quarter_car/true_state)')
    p.add_argument('--namespace', action='append', default=[], metavar='NS',
                   help='record the suite topics of the nodes in namespace NS (repeat for '
                        'several car corners: fl, fr, rl, rr); default: the root namespace')
    p.add_argument('--suite-config', metavar='YAML',
                   help='parameter YAML of the suite, stored in the file (/mr_damper/'
                        'suite_config) for the report')
    p.add_argument('--duration', type=float, default=0.0,
                   help='stop after this many seconds (0: until Ctrl-C)')
    p.add_argument('--count', type=int, default=0,
                   help='stop after this many measurements (0: no limit)')
    p.add_argument('--quiet-s', type=float, default=0.5,
                   help='at a stop, record on until nothing came for this long [s]')
    p.add_argument('--status-period-s', type=float, default=0.2,
                   help='period of the own status [s]')
    p.add_argument('--parameters-period-s', type=float, default=2.0,
                   help='period of asking the suite nodes for their parameters [s] (0: never)')
    return p


def main(argv=None):
    """Record until Ctrl-C / --duration / --count; return the exit status."""
    argv = sys.argv if argv is None else argv
    args = _parser().parse_args(remove_ros_args(argv)[1:])
    out = Path(args.out)
    try:
        config_text = Path(args.suite_config).read_text() if args.suite_config else None
        table = namespaced_table(topic_table(args.only, can=args.can, sensing=args.sensing),
                                 args.namespace)
        recorder = SuiteRecorder(out, table,
                                 config_text=config_text, start_ns=time.time_ns())
    except (OSError, ValueError, LookupError) as exc:
        print(f'mr-damper-record: error: {exc}', file=sys.stderr)
        return 2
    install_stop_handlers()   # SIGINT / SIGTERM: drain, close the file, exit 0
    faulthandler.enable()     # a crash in the middleware: every thread's Python stack to the log
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('mr_damper_record')
    drops = DropCounter(node.get_logger())
    clock = node.get_clock()
    start = time.monotonic()
    with recorder:
        def subscribe(key, row):
            # measurement batches lost on the way are counted from their sequence numbers
            # (never the middleware's MESSAGE_LOST event: docs/faults.md)
            def on_msg(raw):
                drops.count('measurements_lost', recorder.write(key, raw, clock.now().nanoseconds))
            node.create_subscription(message_class(row.type), row.name, on_msg, QOS[row.qos],
                                     raw=True)

        for key, row in recorder.topics.items():
            subscribe(key, row)

        def health():
            lost = drops.counts()
            return Health(WARN if lost else OK,
                          f'{sum(lost.values())} message(s) lost before they were taken'
                          if lost else 'recording',
                          {'messages': dict(recorder.counts),
                           # samples (a measurement message is a batch of them)
                           'measurements': recorder.measurements(),
                           'measurements_by_namespace': {
                               k.split('/')[0]: n for k, n in recorder.samples.items()
                               if '/' in k},
                           'undecodable': dict(recorder.undecodable),
                           # status entries recorded per node (the launcher's stop waits for
                           # every live node's)
                           'statuses': dict(recorder.statuses),
                           'lost': lost, 'file': str(out)})

        diagnostics = DiagnosticsPublisher(node, health, period_s=args.status_period_s,
                                           drops=drops)
        poller = None
        if args.parameters_period_s > 0:
            names = ([f'{ns}/{n}' for ns in args.namespace for n in PARAMETER_NODES]
                     or PARAMETER_NODES)
            poller = ParameterPoller(node, recorder, names, args.parameters_period_s)

        def taken():
            return sum(recorder.counts.values())

        # the suite's executor (EventsExecutor) in a spin_once loop: rclpy.spin_once(node)
        # adds and removes the node on every call, too slow for a few kHz of messages
        executor = make_executor()
        executor.add_node(node)

        def spin_and_count():
            executor.spin_once(timeout_sec=0.05)
            return False, taken()

        node.get_logger().info(f'recording {len(recorder.topics)} topics into {out}')
        try:
            while rclpy.ok() and not stop_requested():
                executor.spin_once(timeout_sec=0.1)
                if args.duration > 0 and time.monotonic() - start >= args.duration:
                    break
                if args.count > 0 and recorder.measurements() >= args.count:
                    break
            diagnostics.close()
            if poller is not None:
                node.destroy_timer(poller.timer)
            diagnostics.publish()
            # drain: take what is still in flight until nothing came for --quiet-s
            wait_while_progressing(spin_and_count, args.quiet_s, 60.0, poll_s=0.0)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            executor.remove_node(node)     # nothing is taken (or written) after this
    # the file is complete (its footer written when `with` closed it) and the counts printed
    # before the middleware's teardown, which has been seen to block for good: it gets
    # TEARDOWN_GUARD_S, then the process exits 0 without it (spinning.tear_down)
    lost = sum(drops.counts().values())
    print(f'mr-damper-record: {sum(recorder.counts.values())} messages '
          f'({recorder.measurements()} measurement samples) written to {out}'
          f'{f", {lost} lost before they were taken" if lost else ""}', file=sys.stderr,
          flush=True)
    tear_down(node, 'mr-damper-record', 0)
    return 0


if __name__ == '__main__':
    sys.exit(main())
