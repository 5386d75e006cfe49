"""
ROS 2 helpers shared by the suite's nodes: QoS, parameters, diagnostics, spin loop, ``main``.

Imports rclpy (listed in ``ROS_MODULES`` of ``tests/test_core_is_ros_free.py``); the numerical
core never imports this module.
"""
from dataclasses import dataclass
import os
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.exceptions import InvalidHandle, ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)

from mr_damper_common.health import Health, STALE
from mr_damper_common.messages import diagnostic_array_msg, diagnostic_status_msg
from mr_damper_common.sequence_gaps import SequenceGaps

from mr_damper_common.stop_flag import (  # noqa: F401 (re-exported for the nodes)
    _STOP, install_stop_handlers, request_stop, stop_requested)

#: Measurement stream, writer (rig) and readers (identifier, recorders): reliable, KEEP_ALL.
#: Every sample of a healthy run arrives (zero loss, also in bursts and at 2-5 kHz): a reliable
#: writer keeps each sample until every reader acknowledged it, and Fast DDS's readers
#: acknowledge only with the writer's heartbeat (about every 3 s), so a KEEP_LAST writer shallow
#: enough to stay below Fast DDS's default resource limit (5,000 samples) drops samples a busy
#: reader asked to be resent (checked: 10,961 of 31,673 lost in a 22-s suite run at 2 kHz with
#: KEEP_LAST 4,000; 0 with KEEP_ALL). The price of KEEP_ALL: a reader that died without leaving
#: (SIGKILL) or is stopped (SIGSTOP) never acknowledges, the writer's history fills up (5,000
#: messages: 100 s of a 1 kHz rig in 20-sample batches, 5 s with one sample per message) and
#: ``publish()`` raises ``cannot publish data``. The rig then
#: replaces its writer with :class:`ResettablePublisher` (the stuck history goes with the old
#: one), waits until the new writer has matched its readers again and publishes the samples due
#: meanwhile: healthy readers lose nothing, the dead or stopped reader loses what it missed
#: (it counts them from the batches' sequence numbers: ``message_lost``), and the rig never
#: blocks for more than one failed ``publish()`` (Fast DDS's max_blocking_time, 100 ms).
MEASUREMENT_QOS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                             reliability=ReliabilityPolicy.RELIABLE)
#: Latched readers (car, controller: KEEP_LAST 1, only the newest set matters) and latched
#: writers of a value that changes once (the rig's true parameters).
LATCHED_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: The identified parameters' writer, and readers that need every set (the recorder, tests):
#: transient local so late subscribers get the newest, KEEP_LAST 100 so a burst of sets (in-order
#: fits of a replay under sim time publish back to back) reaches every reliable reader instead of
#: overwriting the writer's only slot before it was delivered (seen: 1 to 3 of 19 sets missing at
#: a test listener with depth 1). A KEEP_LAST 1 reader (the car) still keeps the newest only.
PARAMETERS_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                            reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Status topics, e.g. ``mr_damper/samples_received`` (KEEP_LAST 10: a stalled reader costs the
#: writer nothing, and the rig needs the newest count only).
STATUS_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                        reliability=ReliabilityPolicy.RELIABLE)

#: Readers of a vehicle sensor stream (1 kHz accelerometers, position sensors): best effort as
#: ``qos_profile_sensor_data``, so any sensor driver's writer connects, but KEEP_LAST 100 instead
#: of 5, so a reader not scheduled for a while takes up to 0.1 s of readings in a burst. Deeper
#: is not better for a control loop: with 1000, a starved state estimator in the suite (load 8)
#: ran 0.7 s behind the car instead of losing (and counting) readings; on its own at load 6.6
#: (``bench/bench_estimator_rate.py``) depth 100 lost 0.9-10 % of the readings, 1000 none.
SENSOR_QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                        reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)

#: The vehicle computer's per-cycle topics (chassis sensors, full-car state, command):
#: reliable, KEEP_LAST 2. A control loop wants the newest cycle, not a backlog: a reader that
#: was starved takes at most two old cycles (answered late: counted as deadline misses) and
#: the rest is counted as lost from the messages' sequence numbers.
VEHICLE_QOS = QoSProfile(depth=2, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE)

#: ``/diagnostics``: KEEP_LAST 10, reliable (as ROS 2's diagnostic_updater publishes it).
DIAGNOSTICS_QOS = STATUS_QOS

#: What ``publish()`` raises when the middleware refuses a sample or the node is shutting down.
PUBLISH_ERRORS = (_rclpy.RCLError, InvalidHandle)


class DropCounter:
    """
    Samples a node dropped or lost, counted by reason, and a publish that never raises.

    Thread-safe (the quarter car publishes from its control thread). Each reason gets one
    warning per ``warn_period_s`` on the node's logger. ``counts()`` goes into the status.

    Parameters
    ----------
    logger : rclpy logger
        Where the throttled warnings go.
    warn_period_s : float
        Throttle period of the warnings [s].

    """

    def __init__(self, logger, warn_period_s=1.0):
        self._logger = logger
        self._warn = LogThrottle(warn_period_s)
        self._lock = threading.Lock()
        self._counts = {}

    def count(self, reason, n=1, detail=''):
        """Add ``n`` samples dropped for ``reason`` and log a throttled warning."""
        if n <= 0:
            return
        with self._lock:
            self._counts[reason] = self._counts.get(reason, 0) + int(n)
            total = self._counts[reason]
            due = self._warn.due(reason)
        if due:
            self._logger.warning(f'{n} sample(s) dropped ({reason}, {total} in all)'
                                 f'{": " + detail if detail else ""}')

    def counts(self):
        """Return ``{reason: samples}`` (a copy; reasons never seen are absent)."""
        with self._lock:
            return dict(self._counts)

    def publish(self, publisher, msg, reason='publish_failed'):
        """
        Publish ``msg``; on a middleware error count it under ``reason`` and return False.

        A node whose readers died or stalled, or that is shutting down, keeps running.
        """
        try:
            publisher.publish(msg)
            return True
        except PUBLISH_ERRORS as exc:
            try:
                topic = publisher.topic_name
            except PUBLISH_ERRORS:   # the publisher itself was destroyed
                topic = '(destroyed publisher)'
            self.count(reason, 1, f'{topic}: {exc}')
            return False

    def publish_next(self, publisher, msg, reason='publish_failed'):
        """
        :meth:`publish` a numbered message, then advance its ``sequence`` (+1 per message).

        ``msg`` is the publisher's own message object, reused for each message it sends, so its
        ``sequence`` is the publisher's running count from 0; a failed publish advances it too
        (its readers count that message lost, as they should).
        """
        sent = self.publish(publisher, msg, reason)
        msg.sequence += 1
        return sent

    def subscribe(self, node, msg_type, topic, callback, qos, reason=None, *, raw=False):
        """
        ``node.create_subscription``; lost messages of a numbered type counted under ``reason``.

        A message type with its own running ``sequence`` and a ``header``
        (``mr_damper_interfaces/DamperSamples``, ``QuarterCarState``) is counted here: the
        jumps of the sequence of each publisher's stream (its ``header.frame_id``) are the
        messages that never reached the callback (:class:`~mr_damper_common.sequence_gaps.
        SequenceGaps`), counted under ``reason`` (default ``'message_lost'``); a publisher's
        restart is logged, not counted. The middleware's MESSAGE_LOST event is never armed: on
        this Fast DDS taking it can deadlock the node (ros2/rmw_fastrtps#890).

        Other types, and raw subscriptions, carry no number to count here: ``docs/faults.md``
        (Lost messages) says where their losses are counted; a ``reason`` for one of them is a
        ValueError, so no count is promised that cannot be kept.
        """
        fields = msg_type.get_fields_and_field_types()
        if raw or 'sequence' not in fields or 'header' not in fields:
            if reason is not None:
                raise ValueError(f'{topic}: {msg_type.__name__}{" (raw)" if raw else ""} has '
                                 f'no sequence to count {reason!r} from')
            return node.create_subscription(msg_type, topic, callback, qos, raw=raw)
        reason = 'message_lost' if reason is None else reason
        gaps = SequenceGaps()

        def numbered(msg):
            restarts = gaps.restarts
            self.count(reason, gaps.offer(msg.sequence, msg.header.frame_id),
                       f'{topic} sequence jumped to {msg.sequence}')
            if gaps.restarts != restarts and self._warn.due(f'restart {topic}'):
                self._logger.warning(f'{topic}: the publisher of {msg.header.frame_id!r} '
                                     f'restarted (sequence {msg.sequence}): not counted as lost')
            callback(msg)
        return node.create_subscription(msg_type, topic, numbered, qos)


class LogThrottle:
    """
    Say whether a throttled log line is due, at no cost while it is not.

    rclpy's own ``throttle_duration_sec`` decides only after it has found the calling frame and
    its source line (``inspect.getframeinfo``, which stats the file system): about 1 ms per call
    even when nothing is logged (``bench/bench_estimator_rate.py``), which a node calling it per
    message at 1 kHz cannot afford. Gate the call instead::

        if self.warn_invalid.due():
            self.get_logger().warning(...)

    Parameters
    ----------
    period_s : float
        At most one line per key per ``period_s`` [s, monotonic wall clock].

    """

    def __init__(self, period_s=1.0):
        self.period_s = float(period_s)
        self._last = {}

    def due(self, key=None):
        """Return True (and restart the period of ``key``) when a line may be logged now."""
        now = time.monotonic()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            return False
        self._last[key] = now
        return True


class ResettablePublisher:
    """
    A KEEP_ALL publisher that replaces its writer when a reader stops acknowledging.

    :meth:`publish` returns False instead of raising when the middleware refuses a sample
    (the writer's history is full of samples a dead or stopped reader never acknowledged): the
    writer is destroyed and created again (counted in :attr:`resets`, a throttled warning), and
    the caller should hold its samples until :meth:`ready` - the new writer matched as many
    readers as the old one had, or ``rematch_timeout_s`` passed - and publish them then.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the publisher.
    msg_type, topic, qos
        As for ``node.create_publisher``.
    rematch_timeout_s : float
        Longest wait for the readers to match the new writer [s] (discovery on loopback: tens
        of ms, about 3 s once in a while).

    """

    def __init__(self, node, msg_type, topic, qos, *, rematch_timeout_s=5.0):
        self._node = node
        self._args = (msg_type, topic, qos)
        self._timeout = float(rematch_timeout_s)
        self.publisher = node.create_publisher(*self._args)
        self.resets = 0
        self._want = 0
        self._reset_at = None

    def publish(self, msg):
        """Publish ``msg``; False (writer replaced, sample not sent) if the middleware refused."""
        if self._reset_at is not None and not self.ready():
            return False
        try:
            self.publisher.publish(msg)
            return True
        except PUBLISH_ERRORS as exc:
            if stop_requested() or not rclpy.ok(context=self._node.context):
                return False
            self._reset(exc)
            return False

    def _reset(self, exc):
        self._want = max(self.publisher.get_subscription_count() - 1, 0)
        self._node.destroy_publisher(self.publisher)
        self.publisher = self._node.create_publisher(*self._args)
        self.resets += 1
        self._reset_at = time.monotonic()
        self._node.get_logger().warning(
            f'{self._args[1]}: a reader stopped acknowledging ({exc}); writer replaced '
            f'({self.resets} in all), publishing resumes once the readers match again',
            throttle_duration_sec=1.0)

    def ready(self):
        """Return True unless a new writer is still waiting for its readers to match."""
        if self._reset_at is None:
            return True
        if (self.publisher.get_subscription_count() >= self._want
                or time.monotonic() - self._reset_at >= self._timeout):
            self._reset_at = None
            return True
        return False

    def get_subscription_count(self):
        """Readers matched by the current writer."""
        return self.publisher.get_subscription_count()


@dataclass(frozen=True)
class Param:
    """
    One declared ROS parameter of a node: default, description, range, and whether it may change.

    Attributes
    ----------
    name : str
        Parameter name.
    default : bool, int, float, str or list
        Default value (its type is the parameter's type).
    description : str
        What it does, with its unit in brackets (``'Peak force [N]'``).
    low, high : float or None
        Inclusive range of a numeric parameter (None: unbounded on that side); rclpy refuses
        values outside it, at start-up and at run time.
    dynamic : bool
        True: applied while the node runs (the node's on-set callback applies it); False:
        read at start-up only, declared read-only, so ``ros2 param set`` is refused with a
        reason instead of being accepted and ignored.

    """

    name: str
    default: object
    description: str
    low: float = None
    high: float = None
    dynamic: bool = False

    def descriptor(self):
        """Return the ``ParameterDescriptor`` (description, range, read-only, constraints)."""
        desc = ParameterDescriptor(
            description=self.description, read_only=not self.dynamic,
            additional_constraints=('can be changed while running' if self.dynamic else
                                    'read at start-up: restart the node to change it'))
        if self.low is None and self.high is None:
            return desc
        if isinstance(self.default, bool) or not isinstance(self.default, (int, float)):
            raise TypeError(f'parameter {self.name}: a range needs a numeric default')
        if isinstance(self.default, int):
            desc.integer_range = [IntegerRange(
                from_value=int(self.low if self.low is not None else -2 ** 31),
                to_value=int(self.high if self.high is not None else 2 ** 31 - 1), step=0)]
        else:
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(self.low if self.low is not None else -1e300),
                to_value=float(self.high if self.high is not None else 1e300), step=0.0)]
        return desc


def declare_parameters(node, specs, on_set=None):
    """
    Declare ``specs`` on ``node`` and install the on-set callback of the dynamic ones.

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    specs : iterable of Param
        Its parameters.
    on_set : callable or None
        ``on_set(changes)`` with ``changes`` a dict name -> new value of dynamic parameters
        (already type- and range-checked by rclpy); applies them and returns ``''``, or returns
        the reason they are refused (nothing applied). Required if a spec is dynamic.

    Returns
    -------
    dict
        Name -> value after overrides (``-p``, parameter files).

    Raises
    ------
    rclpy.exceptions.InvalidParameterValueException
        A value outside its range (the node cannot start; ``run_node`` reports it).

    """
    specs = list(specs)
    values = {}
    for spec in specs:
        values[spec.name] = node.declare_parameter(spec.name, spec.default,
                                                   spec.descriptor()).value
    dynamic = {s.name for s in specs if s.dynamic}
    if dynamic:
        if on_set is None:
            raise ValueError('`on_set` is required when a parameter is dynamic')

        def callback(params):
            changes = {p.name: p.value for p in params if p.name in dynamic}
            if not changes:
                return SetParametersResult(successful=True)
            reason = on_set(changes)
            if reason:
                node.get_logger().warning(f'parameter change refused: {reason}')
            else:
                node.get_logger().info(f'parameters changed: {changes}')
            return SetParametersResult(successful=not reason, reason=reason or '')

        node.add_on_set_parameters_callback(callback)
    return values


def node_time_s(node):
    """Return the node clock's now [s]: ROS time (``/clock`` under ``use_sim_time``)."""
    return node.get_clock().now().nanoseconds * 1e-9


class DiagnosticsPublisher:
    """
    Publish a node's :class:`~mr_damper_common.health.Health` on ``/diagnostics`` periodically.

    One ``DiagnosticStatus`` per period of wall time (steady clock), named ``'<fully qualified
    node name>'`` without the leading slash (``'fl/mr_damper_identifier'`` under namespace
    ``fl``), stamped by the node's
    clock (ROS time under ``use_sim_time``). ``/diagnostics`` is absolute by convention: every
    corner's nodes publish to the same topic, told apart by the status name.

    Parameters
    ----------
    node : rclpy.node.Node
        The node.
    health : callable
        ``health()`` -> Health; an exception becomes a STALE status naming it (the node goes
        on).
    period_s : float
        Publication period [s] (about 1 Hz by convention).
    hardware_id : str
        The device, e.g. the damper or the car corner.
    drops : DropCounter, optional
        Counts a failed publish (``diagnostics_publish_failed``) instead of raising.

    """

    def __init__(self, node, health, *, period_s=1.0, hardware_id='', drops=None):
        self._node = node
        self._health = health
        self._drops = drops
        self.name = node.get_fully_qualified_name().lstrip('/')
        self.hardware_id = hardware_id
        self.published = 0
        self._pub = node.create_publisher(DiagnosticArray, '/diagnostics', DIAGNOSTICS_QOS)
        # a steady (wall) timer: under use_sim_time the status keeps coming when /clock stops
        # (end of a replay, stalled player); the stamp is still the node's (ROS) time
        self._timer = node.create_timer(float(period_s), self.publish,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    @property
    def publisher(self):
        """Return the ``/diagnostics`` writer, e.g. to wait for its readers' acknowledgements."""
        return self._pub

    def close(self):
        """Stop the periodic publication (``publish()`` still works)."""
        if self._timer is not None:
            self._node.destroy_timer(self._timer)
            self._timer = None

    def publish_final(self, timeout_s=1.0):
        """
        At shutdown: stop the timer, publish the last status, wait for its acknowledgements.

        A node whose counts are compared with another's (e.g. frames sent and received) ends
        with a status that holds its final counts; the wait (at most ``timeout_s``) lets the
        readers (the suite's recorder) take it before the node goes.
        """
        self.close()
        health = self.publish()
        self._pub.wait_for_all_acked(Duration(seconds=float(timeout_s)))
        return health

    def publish(self):
        """Build and publish the status now; return the :class:`Health` sent."""
        stamp = node_time_s(self._node)
        try:        # the values are written into the message too: both inside the guard
            health = self._health()
            status = diagnostic_status_msg(self.name, health, self.hardware_id)
        except Exception as exc:  # noqa: B902 - a status bug must not kill the node
            health = Health(STALE, f'status unavailable: {type(exc).__name__}: {exc}')
            status = diagnostic_status_msg(self.name, health, self.hardware_id)
        msg = diagnostic_array_msg([status], stamp_s=stamp)
        if self._drops is not None:
            if self._drops.publish(self._pub, msg, 'diagnostics_publish_failed'):
                self.published += 1
        else:
            self._pub.publish(msg)
            self.published += 1
        return health


def spin(executor, done=lambda: False, timeout_sec=0.1):
    """
    Spin ``executor`` until shutdown, a stop request (SIGINT / SIGTERM) or ``done()``.

    A ``spin_once`` loop: the kilted EventsExecutor's ``spin()`` stalls timers (checked here:
    one tick of a 5 ms timer per second), its ``spin_once`` runs them on time. An error from
    ``spin_once`` once shutdown has begun (e.g. ``RuntimeError: Unable to convert call
    argument`` of a message taken while the context went down) ends the loop quietly; before
    that it is raised.
    """
    while rclpy.ok() and not _STOP.is_set() and not done():
        try:
            executor.spin_once(timeout_sec=timeout_sec)
        except ExternalShutdownException:
            return
        except RuntimeError:
            if _STOP.is_set() or not rclpy.ok():
                return
            raise


def set_realtime_priority(priority, logger):
    """
    Put every thread of this process that exists now under SCHED_FIFO ``priority`` (0: no-op).

    Called after the node is created, so the executor (main) thread and the middleware's
    receive threads (created with the node) get it; threads started later (the fitting worker)
    reset themselves to SCHED_OTHER (see ``IdentifierNode._work``).
    Needs CAP_SYS_NICE (root); otherwise a warning and nothing changes.
    """
    if priority <= 0:
        return False
    try:
        param = os.sched_param(int(priority))
        for tid in os.listdir('/proc/self/task'):
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, param)
        return True
    except (OSError, AttributeError) as exc:
        logger.warning(f'realtime_priority {priority} not applied: {exc}')
        return False


def make_executor(events=True, context=None):
    """Return the executor of the suite's nodes: EventsExecutor when available and ``events``."""
    if events:
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor(context=context)
        except ImportError:  # pragma: no cover - older rclpy
            pass
    return SingleThreadedExecutor(context=context)


class FastLane:
    """
    A minimal node of its own, spun in its own thread, for one hot input of a node.

    rclpy's SingleThreadedExecutor rebuilds its wait set from every entity of its nodes on each
    wake-up (subscriptions, timers, the six parameter services, QoS event handlers) in Python:
    for a node taking a 1 kHz stream that is most of its CPU (the HIL car: 80 % of its samples
    in ``wait_for_ready_callbacks``). A lane has only what is subscribed on it (no parameter
    services, no rosout), in the parent's namespace and context; the process's remappings
    apply to it as to the parent. Its callbacks run in the lane's thread (the parent's code
    must be thread-safe for them, as for any second thread).

    Parameters
    ----------
    parent : rclpy.node.Node
        The node the lane serves (its name, namespace and context).
    suffix : str
        The lane node is ``<parent name>_<suffix>``. Its thread exists once :meth:`start`
        returned, so :func:`set_realtime_priority` called after that covers it.

    Attributes
    ----------
    node : rclpy.node.Node
        Create the lane's subscriptions on it (e.g. ``DropCounter.subscribe(lane.node, ...)``).

    """

    def __init__(self, parent, suffix):
        self.node = rclpy.create_node(
            f'{parent.get_name()}_{suffix}', namespace=parent.get_namespace(),
            context=parent.context, start_parameter_services=False, enable_rosout=False)
        self._executor = make_executor(events=True, context=parent.context)
        self._executor.add_node(self.node)
        self._thread = None

    def start(self):
        """Start spinning the lane (daemon thread, :func:`spin` loop); return self."""
        self._thread = threading.Thread(target=self._run, name=self.node.get_name(),
                                        daemon=True)
        self._thread.start()
        return self

    def _run(self):
        # not the stop flag: the lane serves the parent until it is closed (the control
        # thread's last step after SIGINT still gets its answer)
        context = self.node.context
        while self._thread is not None and context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except (ExternalShutdownException, InvalidHandle, RuntimeError):
                return      # the context went down under a take

    def close(self, timeout_s=1.0):
        """Stop the lane's thread (waits up to ``timeout_s`` [s]) and destroy its node."""
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout_s)
        self._executor.remove_node(self.node)
        self.node.destroy_node()


def spin_node(node, done=lambda: False, *, events=True):
    """Spin ``node`` on :func:`make_executor` with the :func:`spin` loop."""
    executor = make_executor(events)
    executor.add_node(node)
    spin(executor, done)


def run_node(make_node, name, errors=(ValueError,), *, run=spin_node, finish=None, args=None):
    """
    Run a node until SIGINT, SIGTERM or shutdown and return the process exit status.

    SIGINT and SIGTERM only set a flag (:func:`install_stop_handlers`): ``run`` returns, then
    ``finish`` and ``destroy_node`` run undisturbed, and the status is 0 however busy the node
    was. rclpy's own signal handlers are not installed.

    Parameters
    ----------
    make_node : callable
        Builds the node (after ``rclpy.init``).
    name : str
        Node name for the error line on stderr.
    errors : tuple of type
        Exceptions that mean bad parameters or input files: one error line, exit status 2
        (rclpy's ``ParameterException``, e.g. a value outside its declared range or of the
        wrong type, always counts as one).
    run : callable
        ``run(node)`` spins the node until :func:`stop_requested`; default :func:`spin_node`.
    finish : callable or None
        ``finish(node)`` before ``destroy_node``; a non-None return value replaces the status.
    args : list of str or None
        Passed to ``rclpy.init``.

    Returns
    -------
    int
        0, 2 on one of ``errors``, or what ``finish`` returned.

    """
    install_stop_handlers()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    code = 0
    try:
        node = make_node()
        if not _STOP.is_set():
            run(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except tuple(errors) + (ParameterException,) as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        code = 2
    finally:
        if node is not None:
            if finish is not None:
                status = finish(node)
                code = code if status is None else status
            node.destroy_node()
        rclpy.try_shutdown()
    return code
