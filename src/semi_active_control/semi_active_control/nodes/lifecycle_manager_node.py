"""
Lifecycle manager node: brings the vehicle chain up in order and deactivates it when a node dies.

``ros2 run semi_active_control lifecycle_manager --ros-args -p node_names:="['vehicle_bridge',
'vehicle_estimator', 'vehicle_controller']"``

As nav2's lifecycle manager: the ROS-free
:class:`semi_active_control.supervision.lifecycle_chain.LifecycleChain` decides the next
transition (configure every node in order, then activate every node in order; with a node
dead, deactivate the active ones in reverse order; when it is back, up again); this node sends
each as a ``lifecycle_msgs/ChangeState`` call to ``<node>/change_state`` and watches each
node's ``<node>/heartbeat`` (the state it is in; silent for ``heartbeat_timeout_s``: dead).

Topics: sub ``<node>/heartbeat`` (std_msgs/Header) per node; services called
``<node>/change_state``; pub ``/diagnostics`` (status ``lifecycle_manager``: OK while the chain
is up, WARN while it comes up, ERROR with a node dead; the chain's states, counts and last
events).
"""
import sys
import threading
import time

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Header

from mr_damper_common.health import ERROR, OK, WARN, worst
from mr_damper_common.lifecycle_utils import HEARTBEAT_QOS
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, Param,
                                         run_node, spin_node)
from semi_active_control.supervision.lifecycle_chain import LifecycleChain

#: ``lifecycle_msgs/Transition`` ids of the transitions the chain asks for.
TRANSITION_IDS = {'configure': Transition.TRANSITION_CONFIGURE,
                  'cleanup': Transition.TRANSITION_CLEANUP,
                  'activate': Transition.TRANSITION_ACTIVATE,
                  'deactivate': Transition.TRANSITION_DEACTIVATE}

#: The node's parameters (the one place they are declared).
PARAMETERS = (
    Param('node_names', ['vehicle_bridge', 'vehicle_estimator', 'vehicle_controller'],
          'Managed nodes in the chain\'s order (first up, last down), relative to this node\'s '
          'namespace'),
    Param('autostart', True, 'Bring the chain up (false: only watch it)'),
    Param('heartbeat_timeout_s', 1.0, 'A node without a heartbeat for this long is dead and '
          'deactivates the chain [s]', 0.05, 3600.0),
    Param('service_timeout_s', 10.0, 'A transition not answered within this is a failure (the '
          'estimator\'s configure designs its filter: seconds) [s]', 0.1, 3600.0),
    Param('retry_s', 1.0, 'Wait before a failed transition is tried again [s]', 0.01, 3600.0),
    Param('period_s', 0.05, 'Period of the chain\'s decisions [s]', 0.001, 10.0),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
)


class LifecycleManagerNode(Node):
    """Thin node over :class:`LifecycleChain` (see the module docstring)."""

    def __init__(self, **node_kwargs):
        super().__init__('lifecycle_manager', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS)
        self.lock = threading.Lock()
        self.chain = LifecycleChain(p['node_names'],
                                    heartbeat_timeout_s=p['heartbeat_timeout_s'],
                                    service_timeout_s=p['service_timeout_s'],
                                    retry_s=p['retry_s'])
        if not p['autostart']:
            self.chain.watch()
        self.change_state = {n: self.create_client(ChangeState, f'{n}/change_state')
                             for n in self.chain.nodes}
        self.subs = [self.create_subscription(Header, f'{n}/heartbeat',
                                              lambda m, n=n: self.on_heartbeat(n, m),
                                              HEARTBEAT_QOS) for n in self.chain.nodes]
        self.timer = self.create_timer(p['period_s'], self.on_timer,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='lifecycle_manager')
        self.get_logger().info('managing ' + ' -> '.join(self.chain.nodes))

    def on_heartbeat(self, name, msg):
        """Take a node's heartbeat (its lifecycle state)."""
        with self.lock:
            self.chain.heartbeat(name, msg.frame_id, time.monotonic())

    def on_timer(self):
        """Ask for the next transition, if any."""
        with self.lock:
            req = self.chain.next_request(time.monotonic())
        if req is None:
            return
        name, transition = req
        self.get_logger().info(f'{name}: {transition}')
        request = ChangeState.Request()
        request.transition.id = TRANSITION_IDS[transition]
        future = self.change_state[name].call_async(request)
        future.add_done_callback(lambda f: self.on_result(name, transition, f))

    def on_result(self, name, transition, future):
        """Take a transition's answer."""
        try:
            ok = bool(future.result().success)
        except Exception as exc:  # noqa: B902 - a failed call is a refused transition
            self.get_logger().warning(f'{name}: {transition} failed: {exc}')
            ok = False
        if not ok:
            self.get_logger().warning(f'{name}: {transition} refused',
                                      throttle_duration_sec=1.0)
        with self.lock:
            ups = self.chain.ups
            self.chain.result(name, transition, ok, time.monotonic())
            now_ups, first = self.chain.ups, self.chain.first_up_s
        if now_ups > ups:
            self.get_logger().info(f'chain up: every node active ({first:.2f} s after the '
                                   'start)' if now_ups == 1 else
                                   f'chain up again (time {now_ups})')

    def status(self):
        """Return the chain's status."""
        with self.lock:
            return self.chain.status(time.monotonic())

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        dead = [n for n in st['nodes'] if not st['alive'][n]]
        problems = []
        if dead and st['counts']['deaths']:
            problems.append((ERROR, 'dead: ' + ', '.join(dead) + '; chain deactivated'))
        elif not st['up']:
            problems.append((WARN, 'chain not up: ' + ', '.join(
                f'{n} {st["state"][n]}' for n in st['nodes'])))
        return worst(problems or [(OK, 'chain up')], st)


def main(args=None):
    """Entry point of ``lifecycle_manager``."""
    return run_node(LifecycleManagerNode, 'lifecycle_manager', (ValueError,),
                    run=lambda node: spin_node(node, events=True), args=args)


if __name__ == '__main__':
    sys.exit(main())
