"""
Simulated damper driver and chassis sensor cluster ECU on the CAN bus, as a node.

``ros2 run mr_damper_can can_driver_sim --ros-args -p corners:=fl,fr,rl,rr``

A thin node over :class:`mr_damper_can.driver_sim.SimulatedEcu` (ROS-free; it reads the bus and
runs its 2-ms cycle in threads of its own). ROS is only its control panel: fault injection,
optional sensor values from a simulated car, and ``/diagnostics``. See docs/can.md.

Topics (relative)
-----------------
- sub ``can_driver_sim/inject_fault`` (std_msgs/String ``"<corner>:<fault>"``, e.g.
  ``"fl:open_load"``, ``"fl:none"`` clears; faults: see ``driver_sim``); a bad request is
  logged and counted (``dropped.bad_fault_request``);
- sub ``quarter_car/car_state`` (mr_damper_interfaces/QuarterCarState) per corner (``<c>/``
  before it with ``corner_namespaces``) with ``sensor_source:=car_state``: the sensor cluster
  sends that car's body and wheel accelerations and suspension travel;
- pub ``/diagnostics`` (status ``can_driver_sim``): per corner command frames received, bad
  checksums, counter jumps, frames missed, target and coil current, injected fault.
"""
import sys

from std_msgs.msg import String
from rclpy.node import Node

from mr_damper_can.bus import make_bus, UDP_LOOPBACK
from mr_damper_can.codec import parse_corners
from mr_damper_can.driver_sim import EcuHealth, SimulatedEcu
from mr_damper_interfaces.msg import QuarterCarState
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, DropCounter,
                                         Param, run_node, spin_node, STATUS_QOS)

#: The node's parameters (docs/nodes.md shows this table).
PARAMETERS = (
    Param('interface', UDP_LOOPBACK, 'python-can interface (as can_bridge_node)'),
    Param('channel', '239.74.163.2:43113', 'Bus channel (as can_bridge_node)'),
    Param('bitrate', 1000000, 'CAN bit rate of hardware interfaces [bit/s]', 10000, 1000000),
    Param('corners', 'fl,fr,rl,rr', 'Driver channels, comma-separated (fl, fr, rl, rr)'),
    Param('corner_namespaces', False, 'Car state of corner c under c/ (sensor_source '
          'car_state)'),
    Param('tau_s', 0.01, 'Coil current time constant (first-order lag) [s]', 1e-4, 10.0),
    Param('safe_current_a', 0.0, 'The driver\'s own current without a valid command [A]',
          0.0, 2.55),
    Param('command_timeout_s', 0.05, 'No valid command for this long: the driver\'s safe '
          'current and FLT_CMD_TIMEOUT [s]', 0.001, 3600.0),
    Param('status_period_s', 0.002, 'Period of DAMPER_STATUS frames [s] (DBC: 2 ms)',
          1e-4, 1.0),
    Param('sensor_period_s', 0.002, 'Period of the CHASSIS sensor frames [s] (DBC: 2 ms)',
          1e-4, 1.0),
    Param('sensor_source', 'synthetic', 'Sensor cluster values: synthetic (known sines), '
          'car_state (quarter_car/car_state), none (no sensor frames)'),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
)
SENSOR_SOURCES = ('synthetic', 'car_state', 'none')


class CanDriverSimNode(Node):
    """The simulated ECU node (see the module docstring)."""

    def __init__(self, **node_kwargs):
        super().__init__('can_driver_sim', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS)
        corners = parse_corners(p['corners'])
        if p['sensor_source'] not in SENSOR_SOURCES:
            raise ValueError(f'sensor_source must be one of {", ".join(SENSOR_SOURCES)}, got '
                             f'{p["sensor_source"]!r}')
        self.drops = DropCounter(self.get_logger())
        self.bus = make_bus(p['interface'], p['channel'], p['bitrate'])
        self.ecu = SimulatedEcu(self.bus, corners, tau_s=p['tau_s'],
                                safe_current_a=p['safe_current_a'],
                                command_timeout_s=p['command_timeout_s'],
                                status_period_s=p['status_period_s'],
                                sensor_period_s=p['sensor_period_s'],
                                sensors=p['sensor_source'] != 'none')
        self.health_rules = EcuHealth()
        self.create_subscription(String, 'can_driver_sim/inject_fault', self.on_fault,
                                 STATUS_QOS)
        if p['sensor_source'] == 'car_state':
            for c in corners:
                pre = f'{c}/' if p['corner_namespaces'] else ''
                self.create_subscription(
                    QuarterCarState, f'{pre}quarter_car/car_state',
                    lambda m, c=c: self.ecu.set_sensors(c, m.body_acceleration_m_s2,
                                                        m.wheel_acceleration_m_s2,
                                                        m.suspension_travel_m), STATUS_QOS)
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id='simulated damper driver',
                                                drops=self.drops)
        self.ecu.start()
        self.get_logger().info(f'simulated damper driver on {p["interface"]} {p["channel"]}: '
                               f'corners {", ".join(corners)}, tau {p["tau_s"]:g} s')

    def on_fault(self, msg):
        """Inject ``"<corner>:<fault>"``; a bad request is logged and counted."""
        corner, _, fault = msg.data.partition(':')
        try:
            self.ecu.inject(corner.strip(), fault.strip())
        except ValueError as exc:
            self.drops.count('bad_fault_request', 1, str(exc))
            return
        self.get_logger().warning(f'fault injected: {msg.data}')

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        st = self.ecu.status()
        st['dropped'] = self.drops.counts()
        return self.health_rules(st)

    def finish(self):
        """At shutdown: stop the ECU (taking the frames still queued), publish the final status."""
        self.ecu.stop(drain=True)
        self.diagnostics.publish_final()

    def destroy_node(self):
        """Stop the ECU's threads and close the bus, then destroy the node."""
        if getattr(self, 'ecu', None) is not None:     # None: the constructor failed
            self.ecu.stop()
        if getattr(self, 'bus', None) is not None:
            self.bus.shutdown()
            self.bus = None
        return super().destroy_node()


def main(args=None):
    """Entry point of ``can_driver_sim``."""
    import can
    return run_node(CanDriverSimNode, 'can_driver_sim', (ValueError, OSError, can.CanError),
                    run=lambda node: spin_node(node, events=True),
                    finish=lambda node: node.finish(), args=args)


if __name__ == '__main__':
    sys.exit(main())
