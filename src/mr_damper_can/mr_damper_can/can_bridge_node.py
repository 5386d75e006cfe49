"""
CAN bridge node: coil current commands from ROS to the damper driver on CAN, its answers back.

``ros2 run mr_damper_can can_bridge_node --ros-args -p corners:=fl``

A thin node over :class:`mr_damper_can.bridge.CanBridge` (ROS-free): each ``std_msgs/Float64``
on a corner's ``mr_damper/current_command`` becomes one ``DAMPER_CMD_<C>`` frame (DBC range,
rolling counter, checksum); the driver's status and the chassis sensor frames, decoded by the
core in its bus reader thread, are published here. A timer calls the core's ``tick`` (timeouts,
re-sends). See docs/can.md.

Topics (relative; ``<c>/`` before each per-corner name with ``corner_namespaces:=true``)
-----------------------------------------------------------------------------------------
- sub ``mr_damper/current_command`` (std_msgs/Float64, A; reliable, depth 100);
- pub ``mr_damper/measured_current`` (std_msgs/Float64, A): the driver's measured coil current,
  one per ``DAMPER_STATUS_<C>`` frame (500 Hz);
- pub ``can/body_imu``, ``can/wheel_imu`` (sensor_msgs/Imu: vertical acceleration in
  ``linear_acceleration.z``, no orientation or rates: their covariances' first element -1),
  pub ``can/car_state`` (mr_damper_interfaces/QuarterCarState: the measured accelerations,
  suspension travel, measured and commanded current, the corner's fail-safe mode; fields the
  bus does not carry are NaN), each per sensor frame (500 Hz), with ``publish_sensors``;
- pub ``/diagnostics`` (status ``can_bridge``): :class:`mr_damper_can.bridge.BridgeHealth`.
"""
import math
import sys

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64

from mr_damper_can.bridge import BridgeHealth, CanBridge
from mr_damper_can.bus import make_bus, UDP_LOOPBACK
from mr_damper_can.codec import parse_corners
from mr_damper_interfaces.msg import QuarterCarState
from mr_damper_common import messages
from mr_damper_common.node_utils import (declare_parameters, DiagnosticsPublisher, DropCounter,
                                         node_time_s, Param, run_node, spin_node, STATUS_QOS)

#: Command subscription: reliable, depth 100 (each command becomes a frame of its own, so a
#: burst while the bridge's thread is busy is queued, not overwritten).
COMMAND_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)

#: The node's parameters (docs/nodes.md shows this table).
PARAMETERS = (
    Param('interface', UDP_LOOPBACK, 'python-can interface: udp_loopback (frames between the '
          'processes of this host, on the loopback device only), virtual (this process only), '
          'socketcan, pcan, ...'),
    Param('channel', '239.74.163.2:43113', 'Bus channel (udp_loopback: IPv4 multicast '
          'group:port; socketcan: can0, vcan0)'),
    Param('bitrate', 1000000, 'CAN bit rate of hardware interfaces [bit/s]', 10000, 1000000),
    Param('corners', 'fl', 'Corners bridged, comma-separated (fl, fr, rl, rr)'),
    Param('corner_namespaces', False, 'Topics of corner c under c/ (several corners); false: '
          'the one corner\'s topics without prefix'),
    Param('safe_current_a', 0.5, 'Current sent for a corner in fail-safe (driver fault, no '
          'command, status missing, bus off) [A], inside the DBC range 0..2.55', 0.0, 2.55,
          dynamic=True),
    Param('command_timeout_s', 0.05, 'No command for this long: the corner goes to fail-safe '
          '[s, wall clock]', 0.001, 3600.0, dynamic=True),
    Param('rx_timeout_s', 0.05, 'A cyclic frame (driver status, sensors) missing for this long '
          'is a timeout [s]', 0.001, 3600.0),
    Param('resend_period_s', 0.01, 'Re-send the current in force when a corner sent nothing for '
          'this long (the driver\'s keep-alive) [s]', 0.001, 10.0),
    Param('publish_sensors', True, 'Publish the chassis sensor frames (Imu, QuarterCarState)'),
    Param('log_file', '', 'Log every frame on the bus (python-can writer by extension: .blf, '
          '.asc, .log = candump; "" = no log)'),
    Param('diagnostics_period_s', 1.0, 'Period of the /diagnostics status [s]', 0.01, 60.0),
)


def imu_msg(accel_z, stamp_s, frame_id):
    """Return a ``sensor_msgs/Imu`` with only the vertical acceleration [m/s^2] known."""
    msg = Imu()
    messages.seconds_to_stamp(stamp_s, msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.orientation_covariance[0] = -1.0          # no orientation
    msg.angular_velocity_covariance[0] = -1.0     # no rates
    msg.linear_acceleration.x = math.nan
    msg.linear_acceleration.y = math.nan
    msg.linear_acceleration.z = float(accel_z)
    return msg


class CanBridgeNode(Node):
    """The bridge node (see the module docstring)."""

    def __init__(self, **node_kwargs):
        super().__init__('can_bridge', **node_kwargs)
        p = self.p = declare_parameters(self, PARAMETERS, self._on_set)
        corners = parse_corners(p['corners'])
        if len(corners) > 1 and not p['corner_namespaces']:
            raise ValueError('several corners need corner_namespaces:=true')
        self.prefix = {c: f'{c}/' if p['corner_namespaces'] else '' for c in corners}
        self.drops = DropCounter(self.get_logger())
        self.bus = make_bus(p['interface'], p['channel'], p['bitrate'])
        self.core = CanBridge(self.bus, corners, safe_current_a=p['safe_current_a'],
                              command_timeout_s=p['command_timeout_s'],
                              rx_timeout_s=p['rx_timeout_s'],
                              resend_period_s=p['resend_period_s'],
                              on_driver=self.on_driver, on_sensors=self.on_sensors)
        self.health_rules = BridgeHealth()
        self.measured_pub, self.state_pub, self.imu_pub = {}, {}, {}
        self.state_msg = {}     # corner -> its QuarterCarState, reused (its sequence counts)
        for c in corners:
            pre = self.prefix[c]
            self.drops.subscribe(self, Float64, f'{pre}mr_damper/current_command',
                                 lambda msg, c=c: self.core.command(c, msg.data), COMMAND_QOS)
            self.measured_pub[c] = self.create_publisher(
                Float64, f'{pre}mr_damper/measured_current', STATUS_QOS)
            if p['publish_sensors']:
                self.state_pub[c] = self.create_publisher(QuarterCarState, f'{pre}can/car_state',
                                                          STATUS_QOS)
                self.imu_pub[c] = {q: self.create_publisher(Imu, f'{pre}can/{q}_imu', STATUS_QOS)
                                   for q in ('body', 'wheel')}
        self.diagnostics = DiagnosticsPublisher(self, self.health,
                                                period_s=p['diagnostics_period_s'],
                                                hardware_id=f'can {p["interface"]} '
                                                f'{p["channel"]}', drops=self.drops)
        self.timer = self.create_timer(p['resend_period_s'] / 2.0, lambda: self.core.tick())
        self.core.start(log_file=p['log_file'] or None)
        self.get_logger().info(
            f'CAN bridge on {p["interface"]} {p["channel"]}: corners {", ".join(corners)}; '
            f'fail-safe {p["safe_current_a"]:g} A')

    def _on_set(self, changes):
        return self.core.reconfigure(**changes)

    def on_driver(self, status):
        """Publish a driver's measured current (bus reader thread)."""
        self.drops.publish(self.measured_pub[status.corner], Float64(data=status.current_a))

    def on_sensors(self, quantity, values, t):
        """Publish a decoded sensor frame (bus reader thread)."""
        if not self.state_pub:
            return
        stamp = node_time_s(self)
        for corner, value in values.items():
            if corner not in self.state_pub:
                continue
            if quantity in ('body_accel', 'wheel_accel'):
                kind = quantity.split('_')[0]
                self.drops.publish(self.imu_pub[corner][kind],
                                   imu_msg(value, stamp, f'{corner}_{kind}'))
            else:
                self.drops.publish_next(self.state_pub[corner],
                                        self.car_state(corner, self.core.latest(corner), stamp))

    def car_state(self, corner, latest, stamp_s):
        """Fill and return the corner's own (numbered) ``QuarterCarState`` from its bus values."""
        msg = self.state_msg.setdefault(corner, QuarterCarState())
        messages.seconds_to_stamp(stamp_s, msg.header.stamp)
        msg.header.frame_id = corner
        for field in ('body_displacement_m', 'body_velocity_m_s', 'wheel_displacement_m',
                      'wheel_velocity_m_s', 'suspension_velocity_m_s', 'damper_force_n',
                      'tyre_load_n', 'road_height_m'):
            setattr(msg, field, math.nan)
        msg.body_acceleration_m_s2 = latest['body_accel']
        msg.wheel_acceleration_m_s2 = latest['wheel_accel']
        msg.suspension_travel_m = latest['susp_pos']
        msg.current_command_a = latest['sent_a']
        msg.coil_current_a = latest['measured_a']
        normal = latest['mode'] == 'normal'
        msg.fail_safe_mode = QuarterCarState.MODE_NORMAL if normal else \
            QuarterCarState.MODE_FAIL_SAFE
        msg.fail_safe_reason = latest['reason']
        return msg

    def status(self):
        """Return the status dict (the core's and the drop counts)."""
        st = self.core.status()
        st['dropped'] = self.drops.counts()
        return st

    def health(self):
        """Return the node's :class:`~mr_damper_common.health.Health` (``/diagnostics``)."""
        return self.health_rules(self.status(), self.drops.counts())

    def finish(self):
        """
        At shutdown: stop the bus reader and the log, publish the final status, log its counts.

        The log line (``final counts: fl frames_sent=... commands=... resent=...``) holds the
        counts the frame log closed with, also when a loaded reader missed the final status.
        """
        self.core.stop()
        self.diagnostics.publish_final()
        corners = self.core.status()['corners']
        self.get_logger().info('final counts: ' + '; '.join(
            f'{corner} frames_sent={cs["frames_sent"]} commands={cs["commands"]} '
            f'resent={cs["resent"]}' for corner, cs in corners.items()))

    def destroy_node(self):
        """Stop the bus reader, close the log and the bus, then destroy the node."""
        if getattr(self, 'core', None) is not None:     # None: the constructor failed
            self.core.stop()
        if getattr(self, 'bus', None) is not None:
            self.bus.shutdown()
            self.bus = None
        return super().destroy_node()


def main(args=None):
    """Entry point of ``can_bridge_node``."""
    import can
    return run_node(CanBridgeNode, 'can_bridge_node', (ValueError, OSError, can.CanError),
                    run=lambda node: spin_node(node, events=True),
                    finish=lambda node: node.finish(), args=args)


if __name__ == '__main__':
    sys.exit(main())
