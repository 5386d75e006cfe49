"""
Vehicle computer node (managed): the chassis bus in, four damper currents out, in one loop.

``ros2 run mr_damper_can vehicle_computer_node --ros-args -p interface:=socketcan
-p channel:=can0 -p "model_files:=['fl.json','fr.json','rl.json','rr.json']"``

The vehicle computer of docs/vehicle.md in one process and one control path, as ros2_control's
controller manager runs read -> update -> write: each sensor cycle of the bus
(:class:`mr_damper_can.vehicle_bridge.VehicleBridge`) goes, in the bus reader's thread,
through the full-car estimator, the law with its four inverses and supervisors and the
deadline supervision (:class:`semi_active_control.runtime.VehicleLoop`), and its command leaves
as one ``DAMPER_CMD_ALL`` frame before anything is published. The same cores and rules as the
three-node chain (``vehicle_bridge_node``, ``vehicle_estimator_node``,
``vehicle_controller_node``), and their parameters; no middleware in the control path.

Lifecycle: the filter is designed when the node starts; **configure** opens the bus, starts the
filter at rest and loads each corner's model (a file that cannot be read or a record marked
invalid leaves its corner on the safe current); inactive, the bridge sends the safe current
with every fail-safe bit every ``safe_period_s``. **activate** commands from the next cycle.
**deactivate** sends one frame with every corner on the safe current, then the safe frames.
**cleanup** closes the bus (the drivers fall back on their own timeout).

Topics (relative), published after a cycle's frame has left (every ``publish_every``-th cycle),
for recording and monitoring:

- pub ``vehicle/chassis_sensors`` (ChassisSensors), ``vehicle/state`` (FullCarState, while
  active), ``vehicle/command`` (FullCarCommand: every command sent, the deactivation's and the
  sensor timeout's included); reliable, KEEP_LAST 2;
- sub ``<c>/mr_damper/kwok_parameters`` (KwokParameters; latched) for each live corner;
- sub ``full_car/road_preview`` (RoadPreview) with ``controller:=preview-look-ahead``;
- pub ``~/heartbeat``, ``/diagnostics`` (status ``vehicle_computer``: ``bridge``,
  ``estimator``, ``controller`` as the three nodes report them, and ``loop``).
"""
import sys

from rclpy.lifecycle import LifecycleNode

from mr_damper_can.bridge import BridgeHealth
from mr_damper_can.bus import close_bus
from mr_damper_can.node_parameters import open_vehicle_bridge, VEHICLE_BRIDGE_PARAMETERS
from mr_damper_common import messages
from mr_damper_common.health import OK, WARN, worst
from mr_damper_common.lifecycle_utils import (apply_scheduling, FAILURE, MANAGED_PARAMETERS,
                                              managed_services, run_managed, SafeTransitions,
                                              state_label, SUCCESS)
from mr_damper_common.node_utils import (CONTROL_QOS, declare_parameters, LATCHED_QOS,
                                         merge_parameters, node_time_s, Param, VEHICLE_QOS)
from mr_damper_interfaces.msg import (ChassisSensors, FullCarCommand, FullCarState,
                                      KwokParameters, RoadPreview)
from semi_active_control.car.full_car import CORNERS
from semi_active_control.nodes.common import (identified_set_or_error,
                                              log_model_verdicts, log_refused_parameters,
                                              make_vehicle_controller, make_vehicle_estimator,
                                              road_preview_or_error,
                                              vehicle_controller_problems,
                                              VEHICLE_CONTROLLER_PARAMETERS,
                                              VEHICLE_ESTIMATOR_PARAMETERS)
from semi_active_control.runtime import VehicleLoop


#: The node's parameters: the bus's, the filter's, the controller's (``cycle_s`` and
#: ``safe_current_a`` once: the bus's), its topics', then the managed node's.
PARAMETERS = merge_parameters(VEHICLE_BRIDGE_PARAMETERS, VEHICLE_ESTIMATOR_PARAMETERS,
                              VEHICLE_CONTROLLER_PARAMETERS, (
                                  Param('publish_every', 1, 'Publish the sensors, the state and '
                                        'the law\'s command of every n-th cycle (as '
                                        'ros2_control\'s state_publish_rate; the deactivation\'s '
                                        'and the sensor timeout\'s commands always) [cycles]',
                                        1, 100000),),
                              MANAGED_PARAMETERS)


class VehicleComputerNode(SafeTransitions, LifecycleNode):
    """Thin lifecycle node over :class:`VehicleBridge` and :class:`VehicleLoop` (module doc)."""

    def __init__(self, **node_kwargs):
        super().__init__('vehicle_computer', **node_kwargs)
        self.p = declare_parameters(self, PARAMETERS)
        self.health_rules = BridgeHealth()
        self.estimator = make_vehicle_estimator(self.p)     # the design: before the node is up
        self.bus = None
        self.bridge = None
        self.loop = None
        self.pubs = None
        self.subs = []
        self.cycle_timers = []
        self.msgs = (ChassisSensors(), FullCarState(), FullCarCommand())
        managed_services(self, self.p, f'vehicle computer on {self.p["interface"]} '
                                       f'{self.p["channel"]}')

    # --- lifecycle ------------------------------------------------------------------------------
    def on_configure(self, state):
        """Open the bus, start the filter at rest, load the models; the safe frames."""
        import can
        p = self.p
        try:
            controller = make_vehicle_controller(p)
        except ValueError as exc:
            self.get_logger().error(f'configure refused: {exc}')
            return FAILURE
        try:
            self.bus, bridge = open_vehicle_bridge(p, self.on_cycle)
        except (ValueError, OSError, can.CanError) as exc:
            self.get_logger().error(f'cannot open the bus: {exc}')
            return FAILURE
        loop = VehicleLoop(self.estimator, controller, bridge.command_all)
        log_model_verdicts(self.get_logger(), loop.configure(node_time_s(self)))
        self.pubs = tuple(self.create_publisher(t, name, VEHICLE_QOS) for t, name in (
            (ChassisSensors, 'vehicle/chassis_sensors'), (FullCarState, 'vehicle/state'),
            (FullCarCommand, 'vehicle/command')))
        models = controller.models
        self.subs = [
            self.create_subscription(KwokParameters, f'{c}/mr_damper/kwok_parameters',
                                     lambda m, i=i: self.on_params(i, m), LATCHED_QOS)
            for i, c in enumerate(CORNERS) if models.source(i) == 'live']
        if controller.preview is not None:
            self.subs.append(self.drops.subscribe(self, RoadPreview, 'full_car/road_preview',
                                                  self.on_preview, CONTROL_QOS))
        self.bridge, self.loop = bridge, loop
        self.cycle_timers = [self.create_timer(p['safe_period_s'] / 2.0, lambda: bridge.tick()),
                             self.create_timer(p['check_period_s'], self.on_check)]
        apply_scheduling(self, p)
        # the loop runs in the bus reader: one above the process's other threads (timers,
        # statuses, the middleware), so a frame's arrival preempts them
        prio = int(p['realtime_priority'])
        bridge.start(log_file=p['log_file'] or None,
                     reader_priority=min(prio + 1, 99) if prio > 0 else 0)
        self.get_logger().info(
            f'vehicle computer on {p["interface"]} {p["channel"]}: {controller.controller.name}'
            f' every {p["cycle_s"] * 1e3:g} ms, safe {p["safe_current_a"]:g} A; models: '
            + ', '.join(f'{c} {models.source(c)}' for c in CORNERS))
        return SUCCESS

    def on_activate(self, state):
        """Command from the next cycle on."""
        self.bridge.activate()
        self.loop.activate(node_time_s(self))
        return SUCCESS

    def on_deactivate(self, state):
        """One frame with every corner on the safe current, then the safe frames."""
        now = node_time_s(self)
        self._publish_command(self.loop.deactivate(now), now)
        self.bridge.deactivate()
        return SUCCESS

    def _in_safe_reach(self, shutdown):
        return self.loop is not None and (self.loop.active or not shutdown)

    def _teardown(self):
        for timer in self.cycle_timers:
            self.destroy_timer(timer)
        self.cycle_timers = []
        for sub in self.subs:
            self.destroy_subscription(sub)
        self.subs = []
        if self.bridge is not None:
            self.bridge.stop()
        for pub in self.pubs or ():
            self.destroy_publisher(pub)
        self.pubs = None
        self.loop = self.bridge = None
        self.bus = close_bus(self.bus)

    # --- callbacks ------------------------------------------------------------------------------
    def on_cycle(self, cycle):
        """Run one sensor cycle to its frame, then publish it (the bus reader's thread)."""
        loop, pubs = self.loop, self.pubs
        if loop is None or pubs is None:
            return
        now = node_time_s(self)
        est, cmd = loop.cycle(cycle.sequence, cycle.t_bus, cycle.body_accel, cycle.susp_pos,
                              now)
        if cycle.sequence % self.p['publish_every']:
            return
        sensors_msg, state_msg, _ = self.msgs
        self.drops.publish(pubs[0], messages.chassis_sensors_msg(cycle, self.p['cycle_s'],
                                                                 sensors_msg))
        if est is not None and loop.active:
            self.drops.publish(pubs[1], messages.full_car_state_msg(est, state_msg))
        if cmd is not None:
            self._publish_command(cmd, now)

    def on_check(self):
        """Sensor timeout: the safe command while no cycle comes (timer)."""
        loop = self.loop
        if loop is not None:
            now = node_time_s(self)
            cmd = loop.check(now)
            if cmd is not None:
                self._publish_command(cmd, now)

    def on_params(self, i, msg):
        """Offer a live identifier's set to corner ``i``."""
        values = identified_set_or_error(msg)
        loop = self.loop
        log_refused_parameters(self.get_logger(), CORNERS[i], loop.offer_parameters(
            i, values, node_time_s(self)) if loop else None)

    def on_preview(self, msg):
        """Hand a road-preview frame to the law (a message that does not decode is counted)."""
        fields = road_preview_or_error(msg, self.get_logger())
        loop = self.loop
        if loop is not None:
            loop.offer_preview(fields)

    def _publish_command(self, cmd, now):
        pubs = self.pubs
        if pubs is not None:
            self.drops.publish(pubs[2], messages.full_car_command_msg(cmd, now, self.msgs[2]))

    # --- status ---------------------------------------------------------------------------------
    def status(self):
        """Return the status dict: ``bridge``, ``estimator``, ``controller``, ``loop``."""
        loop, bridge = self.loop, self.bridge
        lifecycle = state_label(self)
        st = loop.status(node_time_s(self)) if loop is not None else {}
        if bridge is not None:
            st['bridge'] = bridge.status()
        for part in ('bridge', 'estimator', 'controller'):
            st.setdefault(part, {})['lifecycle'] = lifecycle
        st.update(lifecycle=lifecycle, dropped=self.drops.counts())
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        if 'corners' not in st['bridge']:
            return worst([(WARN, f'{st["lifecycle"]}: bus not open')], st)
        bus = self.health_rules(st['bridge'], self.drops.counts())
        problems = vehicle_controller_problems(st['controller'])
        return worst([(bus.level, bus.message)] + (problems or [(OK, 'ok')]), st)


def main(args=None):
    """Entry point of ``vehicle_computer_node``."""
    return run_managed(VehicleComputerNode, 'vehicle_computer_node', args=args)


if __name__ == '__main__':
    sys.exit(main())
