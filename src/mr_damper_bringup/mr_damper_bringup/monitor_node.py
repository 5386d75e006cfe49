"""
The launcher's monitor: the latest status of every node, in the launcher's process.

A small rclpy node spun in a thread of ``mr-damper-suite``: it subscribes to ``/diagnostics``
(every node's status; the car's carries the running ride metrics) and the parameters of
:data:`mr_damper_bringup.topics.SUITE_TOPICS` (low rate; never the measurement stream, which
the recorder process takes) and keeps only the latest decoded message of each, for the progress
lines and the drain at shutdown. Decoding goes
through :mod:`mr_damper_bringup.topics` (one decoder per payload kind). It also keeps when each
node's status last arrived and when its own spin loop last turned: the heartbeats the launcher's
hang watch (:class:`mr_damper_bringup.supervisor.HangWatch`) is fed with.
"""
import sys
import threading
import time

import rclpy
from rclpy.executors import ExternalShutdownException

from mr_damper_common.node_utils import LATCHED_QOS, run_guarded, STATUS_QOS

from .topics import decode_parameters, decode_status, message_class, STATUS_KEYS, SUITE_TOPICS


class Monitor:
    """
    Latest state of the suite as its topics tell it (thread-safe, bounded).

    Attributes
    ----------
    status : dict
        Node (``rig``, ``identifier``, ``quarter_car``, ``controller``, ``recorder``) -> its
        latest status dict.
    history : dict
        Node -> the last two statuses (oldest first), to tell a count that stopped moving.
    parameters, n_parameters, n_valid, metrics
        Latest parameter dict, parameter messages, valid ones, latest ride metrics.
    beats : dict
        Status name (the node's fully qualified name without the leading slash, e.g.
        ``'fl/mr_damper_rig'``) -> ``time.monotonic()`` when its latest status arrived, whether
        it could be decoded or not (a node that sends a status is alive).
    spun : float or None
        ``time.monotonic()`` at the end of the monitor's latest turn of its spin loop.

    """

    def __init__(self):
        self.lock = threading.Lock()
        self.beats = {}
        self.spun = None
        self.status = {}
        self.history = {}
        self.parameters = None
        self.n_parameters = 0
        self.n_valid = 0
        self.metrics = None

    def on_status(self, key, msg):
        """Store one status message of topic ``key`` (undecodable ones only count as a beat)."""
        now = time.monotonic()
        with self.lock:
            for st in getattr(msg, 'status', ()):
                self.beats[str(st.name).split(':')[0].strip()] = now
        try:
            statuses = decode_status(key, msg)
        except ValueError:
            return
        self.store(statuses)

    def store(self, statuses):
        """Store decoded statuses, ``{node: status dict}``."""
        with self.lock:
            for node, d in statuses.items():
                self.status[node] = d
                self.history[node] = (self.history.get(node, ())[-1:] + (d,))
                if node == 'quarter_car' and d.get('ride_metrics'):
                    self.metrics = d['ride_metrics']   # the car's running ride metrics

    def on_parameters(self, msg):
        """Store one parameter message."""
        try:
            d = decode_parameters(msg)
        except ValueError:
            return
        with self.lock:
            self.parameters = d
            self.n_parameters += 1
            self.n_valid += d.get('valid') == 1.0

    def heartbeats(self):
        """Return ``(beats, spun)``: a copy of :attr:`beats` and :attr:`spun`."""
        with self.lock:
            return dict(self.beats), self.spun

    def snapshot(self):
        """Return a copy: ``(status, history, parameters, n_params, n_valid, metrics)``."""
        with self.lock:
            return (dict(self.status), dict(self.history), self.parameters, self.n_parameters,
                    self.n_valid, self.metrics)


def start_monitor(monitor):
    """
    Create the monitor node in this process and spin it in a thread.

    Returns
    -------
    callable
        Stops the monitor (joins the thread, destroys the node, shuts its context down) and
        returns True, or False when that teardown did not end within ``run_guarded``'s guard
        (it is left in a daemon thread).

    """
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = rclpy.create_node('suite_monitor', context=ctx)
    for key in STATUS_KEYS:
        row = SUITE_TOPICS[key]
        node.create_subscription(message_class(row.type), row.name,
                                 lambda msg, key=key: monitor.on_status(key, msg), STATUS_QOS)
    params = SUITE_TOPICS['parameters']
    node.create_subscription(message_class(params.type), params.name, monitor.on_parameters,
                             LATCHED_QOS)
    executor = rclpy.executors.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    running = threading.Event()
    running.set()

    def spin():
        try:
            while running.is_set():
                executor.spin_once(timeout_sec=0.1)
                monitor.spun = time.monotonic()
        except (ExternalShutdownException, KeyboardInterrupt):
            pass
        except Exception as exc:  # noqa: B902 - report and stop monitoring, never kill the run
            print(f'mr-damper-suite: monitor stopped: {exc}', file=sys.stderr)

    thread = threading.Thread(target=spin, name='suite_monitor', daemon=True)
    thread.start()

    def stop():
        running.clear()
        thread.join(5.0)

        def teardown():
            executor.remove_node(node)
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)

        # the middleware's teardown has been seen to block for good: the launcher goes on to
        # write the run's summary without it
        return run_guarded(teardown, name='suite_monitor_teardown',
                           what='mr-damper-suite: the monitor node\'s teardown')

    return stop
