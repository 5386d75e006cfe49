"""
What a node counts and reports: dropped samples, throttled warnings, ``/diagnostics``.

:class:`DropCounter` counts samples dropped or lost by reason (publishes that never raise,
subscriptions that count lost messages from their sequence numbers), :class:`LogThrottle` gates
log lines at no cost, :class:`DiagnosticsPublisher` publishes a node's health periodically.
Imports rclpy.
"""
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration

from mr_damper_common.health import Health, STALE
from mr_damper_common.messages import diagnostic_array_msg, diagnostic_status_msg
from mr_damper_common.node_utils.qos import DIAGNOSTICS_QOS, PUBLISH_ERRORS
from mr_damper_common.node_utils.spinning import node_time_s
from mr_damper_common.sequence_gaps import SequenceGaps


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
        self._key_values = {}       # the last status's KeyValue messages, reused
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
            status = diagnostic_status_msg(self.name, health, self.hardware_id,
                                           self._key_values)
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
