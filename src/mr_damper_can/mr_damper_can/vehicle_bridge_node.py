"""
Vehicle bridge node (managed): a full car's chassis bus to ROS and the four currents back.

``ros2 run mr_damper_can vehicle_bridge_node --ros-args -p interface:=socketcan -p channel:=can0``

A lifecycle node over the ROS-free :class:`mr_damper_can.vehicle_bridge.VehicleBridge`: each
sensor cycle of the bus (``CHASSIS_BODY_ACCEL``, ``_WHEEL_ACCEL``, ``_SUSP_POS``) becomes one
``ChassisSensors`` message, each ``FullCarCommand`` one ``DAMPER_CMD_ALL`` frame at once, with
the sensor cycle it answers. See docs/can.md and docs/vehicle.md.

Lifecycle: **configure** opens the bus (python-can) and starts reading it; the bridge is then
inactive: it publishes the sensor cycles and sends the safe current with every fail-safe bit
every ``safe_period_s``, whatever comes on ``vehicle/command``. **activate** forwards the
commands (and nothing else: a silent controller leaves the drivers to their own timeout).
**deactivate** sends the safe current at once and every ``safe_period_s`` after. **cleanup**
stops reading and closes the bus (the drivers then fall back on their own timeout and safe
current).

Topics (relative)
-----------------
- pub ``vehicle/chassis_sensors`` (mr_damper_interfaces/ChassisSensors, one per sensor cycle;
  reliable, KEEP_LAST 2; stamp: the cycle's bus time);
- sub ``vehicle/command`` (mr_damper_interfaces/FullCarCommand; reliable, KEEP_LAST 2), on a
  lane of its own;
- pub ``~/heartbeat`` (std_msgs/Header, the lifecycle state in ``frame_id``);
- pub ``/diagnostics`` (status ``vehicle_bridge``): the bridge's status (faults, per corner
  mode and driver status, cycles answered on time, bus-to-bus latency, frames lost).
"""
import sys
import threading

from rclpy.lifecycle import LifecycleNode

from mr_damper_can.bridge import BridgeHealth
from mr_damper_can.bus import close_bus
from mr_damper_can.node_parameters import open_vehicle_bridge, VEHICLE_BRIDGE_PARAMETERS
from mr_damper_common import messages
from mr_damper_common.health import WARN, worst
from mr_damper_common.lifecycle_utils import (apply_scheduling, FAILURE, MANAGED_PARAMETERS,
                                              managed_services, run_managed, SafeTransitions,
                                              state_label, SUCCESS)
from mr_damper_common.node_utils import declare_parameters, FastLane, VEHICLE_QOS
from mr_damper_interfaces.msg import ChassisSensors, FullCarCommand
from semi_active_control.runtime import failsafe_flags

#: The node's parameters.
PARAMETERS = VEHICLE_BRIDGE_PARAMETERS + MANAGED_PARAMETERS


class VehicleBridgeNode(SafeTransitions, LifecycleNode):
    """Thin lifecycle node over :class:`VehicleBridge` (see the module docstring)."""

    def __init__(self, **node_kwargs):
        super().__init__('vehicle_bridge', **node_kwargs)
        self.p = declare_parameters(self, PARAMETERS)
        self.health_rules = BridgeHealth()
        self.lock = threading.Lock()
        self.bus = None
        self.core = None
        self.lane = None
        self.cmd_sub = None
        self.pub = None
        self.timer = None
        self.msg = ChassisSensors()
        managed_services(self, self.p, f'can {self.p["interface"]} {self.p["channel"]}')

    # --- lifecycle ------------------------------------------------------------------------------
    def on_configure(self, state):
        """Open the bus and read it; inactive: the safe current on every corner."""
        import can
        p = self.p
        try:
            self.bus, core = open_vehicle_bridge(p, self.on_cycle)
        except (ValueError, OSError, can.CanError) as exc:
            self.get_logger().error(f'cannot open the bus: {exc}')
            return FAILURE
        self.pub = self.create_publisher(ChassisSensors, 'vehicle/chassis_sensors', VEHICLE_QOS)
        with self.lock:
            self.core = core
        self.lane = FastLane(self, 'commands')
        self.cmd_sub = self.lane.node.create_subscription(FullCarCommand, 'vehicle/command',
                                                          self.on_command, VEHICLE_QOS)
        self.timer = self.create_timer(p['safe_period_s'] / 2.0, lambda: core.tick())
        core.start(log_file=p['log_file'] or None)
        self.lane.start()
        apply_scheduling(self, p)
        self.get_logger().info(f'vehicle bridge on {p["interface"]} {p["channel"]}: cycle '
                               f'{p["cycle_s"] * 1e3:g} ms, safe {p["safe_current_a"]:g} A')
        return SUCCESS

    def on_activate(self, state):
        """Forward the commands."""
        self.core.activate()
        return SUCCESS

    def on_deactivate(self, state):
        """Send the safe current on every corner at once; stop forwarding."""
        self.core.deactivate()
        return SUCCESS

    def _in_safe_reach(self, shutdown):
        return self.core is not None and (self.core.active or not shutdown)

    def _teardown(self):
        if self.timer is not None:
            self.destroy_timer(self.timer)
            self.timer = None
        if self.lane is not None:
            self.lane.close()
            self.lane = None
        if self.core is not None:
            self.core.stop()
        if self.pub is not None:
            self.destroy_publisher(self.pub)
            self.pub = None
        self.bus = close_bus(self.bus)

    # --- callbacks ------------------------------------------------------------------------------
    def on_cycle(self, cycle):
        """Publish one sensor cycle (the bus reader's thread)."""
        pub = self.pub
        if pub is not None:
            self.drops.publish(pub, messages.chassis_sensors_msg(cycle, self.p['cycle_s'],
                                                                 self.msg))

    def on_command(self, msg):
        """Send one command as one frame (the lane's thread)."""
        _, cycle, currents, modes = messages.full_car_command_fields(msg)
        core = self.core
        if core is not None:
            core.command_all(currents, failsafe_flags(modes), cycle)

    # --- status ---------------------------------------------------------------------------------
    def status(self):
        """Return the status dict (the core's, the lifecycle state and the drop counts)."""
        core = self.core
        st = core.status() if core is not None else {}
        st.update(lifecycle=state_label(self), dropped=self.drops.counts())
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.status()
        if 'corners' not in st:
            return worst([(WARN, f'{st["lifecycle"]}: bus not open')], st)
        return self.health_rules(st, self.drops.counts())


def main(args=None):
    """Entry point of ``vehicle_bridge_node``."""
    return run_managed(VehicleBridgeNode, 'vehicle_bridge_node', args=args)


if __name__ == '__main__':
    sys.exit(main())
