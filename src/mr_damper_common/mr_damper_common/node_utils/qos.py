"""
QoS profiles of the suite's topics and the publishers that go with them.

One home for the QoS of each kind of stream (measurements, latched sets, status, sensors, the
vehicle's cycle, ``/diagnostics``), :data:`PUBLISH_ERRORS` (what a refused ``publish()`` raises)
and :class:`ResettablePublisher` (a KEEP_ALL writer that survives a reader that stopped
acknowledging). Imports rclpy.
"""
import time

import rclpy
from rclpy.exceptions import InvalidHandle
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from mr_damper_common.stop_flag import stop_requested

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
#: A corner's state and its current command (car, estimator, controller): reliable, depth 10
#: (only the newest matters; a stalled reader costs the writer nothing).
CONTROL_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
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
