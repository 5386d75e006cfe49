"""
Parameters the CAN nodes share, declared once (``mr_damper_common.node_utils.Param``).

:data:`VEHICLE_BRIDGE_PARAMETERS`: the vehicle bus's, of ``vehicle_bridge_node`` and of the
vehicle computer in one loop (``semi_active_control``'s ``vehicle_computer_node``), so no
node module imports another. Imports ROS message types (through ``node_utils``).
"""
from mr_damper_can.bus import UDP_LOOPBACK
from mr_damper_common.node_utils import Param

#: The vehicle bus: interface, cycle, the safe frames, timeouts, the frame log.
VEHICLE_BRIDGE_PARAMETERS = (
    Param('interface', UDP_LOOPBACK, 'python-can interface: udp_loopback (the processes of this '
          'host, loopback only), socketcan, pcan, kvaser, vector, ...'),
    Param('channel', '239.74.163.2:43113', 'Bus channel (udp_loopback: group:port; socketcan: '
          'can0)'),
    Param('bitrate', 1000000, 'CAN bit rate of hardware interfaces [bit/s]', 10000, 1000000),
    Param('cycle_s', 0.002, 'Sensor and command cycle [s]: an answer\'s deadline', 1e-4, 1.0),
    Param('safe_period_s', 0.01, 'Period of the safe frames while inactive [s] (inside the '
          'drivers\' command timeout)', 1e-3, 1.0),
    Param('safe_current_a', 0.5, 'Current sent for every corner while inactive, and for a '
          'corner the bridge holds in fail-safe (driver fault, bus off, driver silent) [A]',
          0.0, 2.55),
    Param('rx_timeout_s', 0.05, 'A cyclic frame (driver status, sensors) missing this long is a '
          'timeout; a silent driver\'s corner goes to fail-safe [s]', 0.001, 3600.0),
    Param('command_timeout_s', 0.02, 'No command for this long is reported (command_timeout); '
          'nothing is sent in the controller\'s name [s]', 0.001, 3600.0),
    Param('log_file', '', 'Log every frame on the bus (python-can writer by extension: .blf, '
          '.asc, .log = candump; "" = none)'),
)


def open_vehicle_bridge(p, on_cycle):
    """
    Open the bus of :data:`VEHICLE_BRIDGE_PARAMETERS` values ``p`` and its bridge on it.

    Returns ``(bus, bridge)``; a bus that cannot be opened, or settings the bridge refuses,
    raise (``ValueError``, ``OSError``, ``can.CanError``) with the bus closed again.
    """
    from mr_damper_can.bus import close_bus, make_bus
    from mr_damper_can.vehicle_bridge import VehicleBridge
    bus = None
    try:
        bus = make_bus(p['interface'], p['channel'], p['bitrate'])
        return bus, VehicleBridge(bus, cycle_s=p['cycle_s'], safe_period_s=p['safe_period_s'],
                                  safe_current_a=p['safe_current_a'],
                                  rx_timeout_s=p['rx_timeout_s'],
                                  command_timeout_s=p['command_timeout_s'], on_cycle=on_cycle)
    except BaseException:
        close_bus(bus)
        raise
