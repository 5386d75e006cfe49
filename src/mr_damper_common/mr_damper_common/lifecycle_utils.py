"""
ROS side of the suite's managed (lifecycle) nodes: state, heartbeat, autostart, shutdown.

A managed node is an ``rclpy.lifecycle.LifecycleNode`` whose transition callbacks call its
ROS-free core (configure: load and check, open; activate: start commanding; deactivate: the
safe state; cleanup: close). Around that every managed node of the suite has:

- a **heartbeat** (:class:`Heartbeat`): ``~/heartbeat`` (``std_msgs/Header``: the stamp and,
  in ``frame_id``, the node's lifecycle state) every ``period_s`` of steady time, from the node's
  construction on, so a lifecycle manager sees a node that is up but unconfigured, and sees a
  dead or stalled one go silent (nav2 uses bonds for the same);
- **autostart** (:func:`autostart`): configure and activate itself at start, for a node run by
  hand without a manager;
- a **clean end** (:func:`end_managed`): an active node is deactivated (its safe state) and
  shut down before the process ends, also on SIGINT / SIGTERM.

Imports rclpy (listed in ``ROS_MODULES`` of ``tests/test_core_is_ros_free.py``).
"""
from lifecycle_msgs.msg import State
from rclpy.clock import Clock, ClockType
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header

from mr_damper_common import messages
from mr_damper_common.node_utils import (DiagnosticsPublisher, DropCounter, node_time_s, Param,
                                         PUBLISH_ERRORS, run_node, set_cpu_affinity,
                                         set_realtime_priority, spin_node)
from mr_damper_common.scheduling import freeze_heap

#: The heartbeat topic of a managed node (private: ``/<namespace>/<node>/heartbeat``).
HEARTBEAT_TOPIC = '~/heartbeat'
#: Heartbeats: only the newest matters.
HEARTBEAT_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)

#: Parameters every managed node of the suite has (after its own).
MANAGED_PARAMETERS = (
    Param('autostart', False, 'Configure and activate at start (without a lifecycle manager)'),
    Param('heartbeat_period_s', 0.1, 'Period of ~/heartbeat [s]', 0.01, 10.0),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
    Param('realtime_priority', 0, 'SCHED_FIFO priority of the node\'s threads, set when it is '
          'configured (1..99; 0 = normal scheduling; the threads of the middleware and other '
          'libraries get normal scheduling at nice -20); needs CAP_SYS_NICE [-]', 0, 99),
    Param('cpu_affinity', '', 'CPUs the node\'s threads are pinned to when it is configured, '
          'a Linux CPU list as taskset -c takes it ("1", "2-3"; "" = any)'),
)

SUCCESS = TransitionCallbackReturn.SUCCESS
FAILURE = TransitionCallbackReturn.FAILURE
ERROR = TransitionCallbackReturn.ERROR


class SafeTransitions:
    """
    The cleanup, shutdown and error transitions of a managed node with a safe state (a mixin).

    Put it before ``LifecycleNode`` in the bases. The node defines ``on_deactivate`` (its safe
    state), ``_teardown`` (drop what configure made) and ``_in_safe_reach(shutdown)``: True
    when deactivating first would reach its safe state (at shutdown: while it commands; on
    error: while it still can). Then **cleanup** tears down; **shutdown** and **error**
    deactivate first when in reach, then tear down (error: back to unconfigured).
    """

    def on_cleanup(self, state):
        """Drop what configure made."""
        self._teardown()
        return SUCCESS

    def on_shutdown(self, state):
        """Deactivate first if commanding (the safe state), then tear down."""
        if self._in_safe_reach(True):
            self.on_deactivate(state)
        self._teardown()
        return SUCCESS

    def on_error(self, state):
        """Go to the safe state if still possible, tear down: back to unconfigured."""
        if self._in_safe_reach(False):
            self.on_deactivate(state)
        self._teardown()
        return SUCCESS


def apply_scheduling(node, params):
    """
    Give ``node``'s process its ``cpu_affinity`` and its threads ``realtime_priority``.

    Only the interpreter's threads get the priority; the libraries' own threads (the
    middleware's) stay at normal scheduling, at nice -20, and no later thread inherits either
    (``set_realtime_priority(..., native_threads=False)``: with every thread at SCHED_FIFO on
    one core a vehicle computer froze in its configure).
    """
    set_realtime_priority(int(params['realtime_priority']), node.get_logger(),
                          native_threads=False)
    set_cpu_affinity(params['cpu_affinity'], node.get_logger())


def state_label(node):
    """
    Return a lifecycle node's current state label (``unconfigured``, ``inactive``, ...).

    rclpy keeps it in the node's state machine (``_state_machine.current_state``: id, label);
    it has no public accessor in this version.
    """
    return node._state_machine.current_state[1]


def is_active(node):
    """Return True when a lifecycle node is in the ``active`` state."""
    return node._state_machine.current_state[0] == State.PRIMARY_STATE_ACTIVE


class Heartbeat:
    """
    Publish a managed node's lifecycle state every ``period_s`` on ``~/heartbeat``.

    Parameters
    ----------
    node : rclpy.lifecycle.LifecycleNode
    period_s : float
        Period [s, steady clock: the heartbeat goes on when ``/clock`` stops].
    drops : DropCounter, optional
        Counts a failed publish instead of raising.

    """

    def __init__(self, node, period_s=0.1, drops=None):
        self._node = node
        self._drops = drops
        self._pub = node.create_publisher(Header, HEARTBEAT_TOPIC, HEARTBEAT_QOS)
        self._msg = Header()
        self.published = 0
        self._timer = node.create_timer(float(period_s), self.publish,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    def publish(self):
        """Publish the state now."""
        messages.seconds_to_stamp(max(node_time_s(self._node), 0.0), self._msg.stamp)
        self._msg.frame_id = state_label(self._node)
        if self._drops is not None:
            ok = self._drops.publish(self._pub, self._msg, 'heartbeat_publish_failed')
        else:
            try:
                self._pub.publish(self._msg)
                ok = True
            except PUBLISH_ERRORS:
                ok = False
        self.published += int(ok)


def managed_services(node, params, hardware_id):
    """
    Give a managed node what every one has: drop counter, heartbeat, ``/diagnostics``.

    Sets ``node.drops`` (:class:`DropCounter`), ``node.heartbeat`` (:class:`Heartbeat`) and
    ``node.diagnostics`` (:class:`DiagnosticsPublisher` of ``node.health``) from the
    :data:`MANAGED_PARAMETERS` values in ``params``.
    """
    node.drops = DropCounter(node.get_logger())
    node.heartbeat = Heartbeat(node, params['heartbeat_period_s'], node.drops)
    node.diagnostics = DiagnosticsPublisher(node, node.health,
                                            period_s=params['diagnostics_period_s'],
                                            hardware_id=hardware_id, drops=node.drops)


def run_managed(make_node, name, errors=(ValueError,), args=None):
    """
    Run a managed node until SIGINT / SIGTERM (``run_node``): autostart if asked, clean end.

    ``make_node()`` builds the node (its parameters in ``node.p``, with ``autostart``); at the
    end an active node is deactivated (its safe state) and shut down (:func:`end_managed`).
    A short GIL switch interval (0.5 ms, as the car nodes): a managed node's hot input runs in
    a lane thread of its own next to the executor's and the middleware's, and a thread that
    becomes ready waits for the one holding the GIL at most that long instead of 5 ms.
    """
    import sys
    sys.setswitchinterval(0.0005)

    def run(node):
        freeze_heap()
        if node.p['autostart']:
            autostart(node)
        spin_node(node, events=True)
    return run_node(make_node, name, errors, run=run, finish=end_managed, args=args)


def autostart(node):
    """Configure and then activate ``node`` now; return its state label afterwards."""
    if node.trigger_configure() == SUCCESS:
        node.trigger_activate()
    return state_label(node)


def end_managed(node):
    """
    Bring a managed node to its end: deactivate (the safe state), final status, shut down.

    The final ``/diagnostics`` status (``DiagnosticsPublisher.publish_final``: it waits for
    the readers' acknowledgement) holds the counts of the whole run.

    For the process's end (``run_node``'s ``finish``); errors of a context already going down
    are ignored.
    """
    try:
        if is_active(node):
            node.trigger_deactivate()
        diagnostics = getattr(node, 'diagnostics', None)
        if diagnostics is not None:       # the final counts, before the core goes
            diagnostics.publish_final()
        if node._state_machine.current_state[0] != State.PRIMARY_STATE_FINALIZED:
            node.trigger_shutdown()
    except Exception as exc:  # noqa: B902 - the context may be gone after Ctrl-C
        node.get_logger().warning(f'lifecycle end: {type(exc).__name__}: {exc}')
