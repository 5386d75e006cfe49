"""
Console scripts of the mr_damper_can nodes: stop handlers first, then the node module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters.
"""
from mr_damper_common.stop_flag import early_main


def can_bridge_node():
    """``ros2 run mr_damper_can can_bridge_node``."""
    return early_main('mr_damper_can.can_bridge_node')


def can_driver_sim():
    """``ros2 run mr_damper_can can_driver_sim``."""
    return early_main('mr_damper_can.can_driver_sim_node')


def vehicle_bridge_node():
    """``ros2 run mr_damper_can vehicle_bridge_node``."""
    return early_main('mr_damper_can.vehicle_bridge_node')


def vehicle_computer_node():
    """``ros2 run mr_damper_can vehicle_computer_node``."""
    return early_main('mr_damper_can.vehicle_computer_node')
