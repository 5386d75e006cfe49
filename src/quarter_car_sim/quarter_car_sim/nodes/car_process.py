"""
How a car node's process runs and ends (both car nodes: quarter car and full car).

A car node has a control thread (``stop()``, ``failed``): :func:`run_car_node` runs it as a
process (exit status 2 on a bad parameter or file, 1 when the control loop died) and
:func:`end_on_control_error` makes a dead control loop end the process after saying so on
``/diagnostics``. Shared here, not in a node module: no node module imports another.
"""
import sys

import rclpy

from mr_damper_common.node_utils import run_node, spin_node
from mr_damper_common.scheduling import freeze_heap


def end_on_control_error(node, failed):
    """
    Say on ``/diagnostics`` that a car node's control loop died, then shut its context down.

    A dead control loop must not leave a node that looks alive: ERROR on ``/diagnostics``
    (``node.diagnostics``), then the process ends (exit status 1, :func:`run_car_node`).
    """
    if rclpy.ok(context=node.context):
        node.get_logger().error(f'control loop stopped: {failed}')
        try:
            node.diagnostics.publish()
        finally:
            rclpy.try_shutdown(context=node.context)


def run_car_node(node_class, name, args=None):
    """
    Run a car node with a control thread (``stop()``, ``failed``); return the exit status.

    A short GIL switch interval (the control thread waits at most ~0.5 ms for the executor);
    the start-up heap frozen out of the garbage collector's passes
    (``mr_damper_common.scheduling.freeze_heap``: a full collection triggered in the control
    thread would walk it all while the car's step waits);
    ValueError, OSError: bad parameter, road or truth file (exit status 2). A
    SingleThreadedExecutor: the control thread publishes, the executor only takes parameter
    sets and runs the diagnostics timer (with plant rig also the rig's measurements; with the
    EventsExecutor here the rig received a fifth of the commands the control thread sent).
    """
    sys.setswitchinterval(0.0005)

    def run(node):
        freeze_heap()
        spin_node(node, events=False)
    return run_node(node_class, name, (ValueError, OSError), run=run, finish=_finish,
                    args=args)


def _finish(node):
    """Stop the control thread; exit status 1 if the control loop failed."""
    node.stop()
    return 1 if node.failed else None
