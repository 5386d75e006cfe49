"""
Vehicle state estimator node (managed): the chassis sensors in, one full-car state per cycle out.

``ros2 run semi_active_control vehicle_estimator_node --ros-args -p autostart:=true``

A lifecycle node over the ROS-free
:class:`semi_active_control.estimation.VehicleEstimatorCore` (the full-car Kalman filter on
the four body accelerometers and the four ride height sensors; faulty sensors named, counted
and left out; lost cycles predicted through). One ``FullCarState`` per sensor cycle.

Inputs (``input``):

- ``bus`` (default): ``vehicle/chassis_sensors`` (mr_damper_interfaces/ChassisSensors, one per
  cycle, from ``vehicle_bridge_node``; reliable, KEEP_LAST 2);
- ``topics``: per corner ``<c>/quarter_car/body_imu`` (sensor_msgs/Imu,
  ``linear_acceleration.z`` as specific force, +9.81 at rest, as REP 145 has it) and
  ``<c>/quarter_car/suspension_position`` (sensor_msgs/JointState, the first ``position``:
  travel [m], extension positive), best effort KEEP_LAST 100, as the quarter-car
  ``state_estimator_node`` takes them; a cycle runs at each reading of the ``clock_corner``'s
  position sensor, at its stamp.

Lifecycle: the filter is designed when the node starts (a few seconds: ``control.dlqe``);
**configure** starts it at rest and subscribes;
**activate** starts publishing; **deactivate** stops publishing (the controller then falls
back on its sensor timeout); **cleanup** drops the topics.

Topics out: ``vehicle/state`` (mr_damper_interfaces/FullCarState; reliable, KEEP_LAST 2),
``~/heartbeat``, ``/diagnostics`` (status ``vehicle_estimator``: validity, sensor faults with
their entries and cycles, cycles lost, readings).
"""
import math
import sys
import threading

from rclpy.lifecycle import LifecycleNode
from sensor_msgs.msg import Imu, JointState

from mr_damper_common import messages
from mr_damper_common.health import OK, WARN, worst
from mr_damper_common.lifecycle_utils import (apply_scheduling, MANAGED_PARAMETERS,
                                              managed_services, run_managed, SafeTransitions,
                                              state_label, SUCCESS)
from mr_damper_common.node_utils import (declare_parameters, FastLane, Param, SENSOR_QOS,
                                         VEHICLE_QOS)
from mr_damper_interfaces.msg import ChassisSensors, FullCarState
from semi_active_control.car.full_car import CORNERS
from semi_active_control.estimation.sensor_specs import G0
from semi_active_control.nodes.common import make_vehicle_estimator, VEHICLE_ESTIMATOR_PARAMETERS

#: The node's parameters: its input, then the filter's (shared with the loop node).
PARAMETERS = (
    Param('input', 'bus', 'Where the sensors come from: bus (vehicle/chassis_sensors) or '
          'topics (per corner Imu and JointState, as the quarter-car estimator)'),
    Param('clock_corner', 'fl', 'input topics: the corner whose position reading runs a cycle'),
) + VEHICLE_ESTIMATOR_PARAMETERS + MANAGED_PARAMETERS
INPUTS = ('bus', 'topics')


class VehicleEstimatorNode(SafeTransitions, LifecycleNode):
    """Thin lifecycle node over :class:`VehicleEstimatorCore` (see the module docstring)."""

    def __init__(self, **node_kwargs):
        super().__init__('vehicle_estimator', **node_kwargs)
        self.p = declare_parameters(self, PARAMETERS)
        self.lock = threading.Lock()
        p = self.p
        if p['input'] not in INPUTS or p['clock_corner'] not in CORNERS:
            raise ValueError(f'input must be one of {INPUTS} and clock_corner one of '
                             f'{CORNERS}, got {p["input"]!r}, {p["clock_corner"]!r}')
        # the filter's design (control.dlqe: seconds on a small computer) before the node is
        # up, so a transition never blocks the node's heartbeat for that long
        self.filter_core = make_vehicle_estimator(p)
        self.core = None
        self.active = False
        self.lane = None
        self.subs = []
        self.pub = None
        self.msg = FullCarState()
        managed_services(self, self.p, 'vehicle_estimator')

    # --- lifecycle ------------------------------------------------------------------------------
    def on_configure(self, state):
        """Start the filter at rest and subscribe to the sensors."""
        p = self.p
        core = self.filter_core
        core.reset()
        with self.lock:
            self.core = core
        self.pub = self.create_publisher(FullCarState, 'vehicle/state', VEHICLE_QOS)
        self.lane = FastLane(self, 'sensors')
        node = self.lane.node
        if p['input'] == 'bus':
            self.subs = [node.create_subscription(ChassisSensors, 'vehicle/chassis_sensors',
                                                  self.on_chassis, VEHICLE_QOS)]
        else:
            self.subs = []
            for c in CORNERS:
                self.subs.append(node.create_subscription(
                    Imu, f'{c}/quarter_car/body_imu',
                    lambda m, c=c: self.on_reading(f'accel_{c}',
                                                   m.linear_acceleration.z - G0), SENSOR_QOS))
                self.subs.append(node.create_subscription(
                    JointState, f'{c}/quarter_car/suspension_position',
                    lambda m, c=c: self.on_position(c, m), SENSOR_QOS))
        self.lane.start()
        apply_scheduling(self, p)
        self.get_logger().info(f'full-car estimator on {p["input"]} every '
                               f'{p["cycle_s"] * 1e3:g} ms -> vehicle/state')
        return SUCCESS

    def on_activate(self, state):
        """Publish the estimates from now on."""
        self.active = True
        return SUCCESS

    def on_deactivate(self, state):
        """Stop publishing (the controller's sensor timeout takes over)."""
        self.active = False
        return SUCCESS

    def _in_safe_reach(self, shutdown):
        return self.active

    def _teardown(self):
        if self.lane is not None:
            self.lane.close()
            self.lane = None
        self.subs = []
        if self.pub is not None:
            self.destroy_publisher(self.pub)
            self.pub = None
        with self.lock:
            self.core = None

    # --- callbacks ------------------------------------------------------------------------------
    def on_chassis(self, msg):
        """Run one bus cycle (the lane's thread)."""
        t = messages.stamp_to_seconds(msg.header.stamp)
        with self.lock:
            if self.core is None:
                return
            est = self.core.step(msg.sequence, t, msg.body_acceleration_m_s2,
                                 msg.suspension_travel_m)
        self._publish(est)

    def on_reading(self, sensor, value):
        """Keep one topic reading (accelerations with gravity removed) for the next cycle."""
        with self.lock:
            if self.core is not None:
                self.core.offer_reading(sensor, value)

    def on_position(self, corner, msg):
        """Keep a position reading; the clock corner's runs the cycle at its stamp."""
        value = msg.position[0] if len(msg.position) else math.nan
        self.on_reading(f'travel_{corner}', value)
        if corner != self.p['clock_corner']:
            return
        t = messages.stamp_to_seconds(msg.header.stamp)
        with self.lock:
            est = self.core.tick(t) if self.core is not None else None
        self._publish(est)

    def _publish(self, est):
        if est is None or not self.active or self.pub is None:
            return
        self.drops.publish(self.pub, messages.full_car_state_msg(est, self.msg))

    # --- status ---------------------------------------------------------------------------------
    def status(self):
        """Return the status dict (the core's, the lifecycle state and the drop counts)."""
        with self.lock:
            st = self.core.status() if self.core is not None else {}
        st.update(lifecycle=state_label(self), active=self.active, dropped=self.drops.counts())
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        problems = []
        if 'steps' not in st:
            problems.append((WARN, f'{st["lifecycle"]}: not configured'))
        elif not st['valid']:
            problems.append((WARN, f'estimate invalid: {st["reason"]}'))
        elif st['faults']:
            problems.append((WARN, 'sensors left out: ' + ', '.join(st['faults'])))
        return worst(problems or [(OK, 'ok')], st)


def main(args=None):
    """Entry point of ``vehicle_estimator_node``."""
    return run_managed(VehicleEstimatorNode, 'vehicle_estimator_node', args=args)


if __name__ == '__main__':
    sys.exit(main())
