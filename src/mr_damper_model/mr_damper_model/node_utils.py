"""
ROS 2 helpers shared by the suite's nodes: QoS profiles, executor, spin loop and ``main`` wrapper.

Imports rclpy (listed in ``ROS_MODULES`` of ``tests/test_core_is_ros_free.py``); the numerical
core never imports this module.
"""
import os
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: Measurement stream: reliable; every sample matters (see README "QoS").
MEASUREMENT_QOS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                             reliability=ReliabilityPolicy.RELIABLE)
#: Parameters: latched for late subscribers.
LATCHED_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: JSON status topics.
STATUS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def spin(executor, done=lambda: False):
    """
    Spin ``executor`` until shutdown or ``done()``.

    A ``spin_once`` loop: the kilted EventsExecutor's ``spin()`` stalls timers (checked here:
    one tick of a 5 ms timer per second), its ``spin_once`` runs them on time.
    """
    while rclpy.ok() and not done():
        executor.spin_once(timeout_sec=0.1)


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


def make_executor():
    """Return the executor used by the suite's nodes (EventsExecutor when available)."""
    try:
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    except ImportError:  # pragma: no cover - older rclpy
        return SingleThreadedExecutor()


def spin_node(node, done=lambda: False):
    """Spin ``node`` on :func:`make_executor` with the :func:`spin` loop."""
    executor = make_executor()
    executor.add_node(node)
    spin(executor, done)


def run_node(make_node, name, errors=(ValueError,), *, run=spin_node, finish=None, args=None):
    """
    Run a node until Ctrl-C or shutdown and return the process exit status.

    Parameters
    ----------
    make_node : callable
        Builds the node (after ``rclpy.init``).
    name : str
        Node name for the error line on stderr.
    errors : tuple of type
        Exceptions that mean bad parameters or input files: one error line, exit status 2.
    run : callable
        ``run(node)`` spins the node; default :func:`spin_node`.
    finish : callable or None
        ``finish(node)`` before ``destroy_node``; a non-None return value replaces the status.
    args : list of str or None
        Passed to ``rclpy.init``.

    Returns
    -------
    int
        0, 2 on one of ``errors``, or what ``finish`` returned.

    """
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = make_node()
        run(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except errors as exc:
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
