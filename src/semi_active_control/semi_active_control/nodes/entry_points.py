"""
Console scripts of the semi_active_control nodes: stop handlers first, then the node module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters.
"""
from mr_damper_common.stop_flag import early_main


def semi_active_controller_node():
    """``ros2 run semi_active_control semi_active_controller_node``."""
    return early_main('semi_active_control.nodes.semi_active_controller_node')


def state_estimator_node():
    """``ros2 run semi_active_control state_estimator_node``."""
    return early_main('semi_active_control.nodes.state_estimator_node')


def vehicle_estimator_node():
    """``ros2 run semi_active_control vehicle_estimator_node``."""
    return early_main('semi_active_control.nodes.vehicle_estimator_node')


def vehicle_controller_node():
    """``ros2 run semi_active_control vehicle_controller_node``."""
    return early_main('semi_active_control.nodes.vehicle_controller_node')


def lifecycle_manager():
    """``ros2 run semi_active_control lifecycle_manager``."""
    return early_main('semi_active_control.nodes.lifecycle_manager_node')
