"""
Console scripts of the quarter_car_sim nodes: stop handlers first, then the node module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters.
"""
from mr_damper_common.stop_flag import early_main


def quarter_car_node():
    """``ros2 run quarter_car_sim quarter_car_node``."""
    return early_main('quarter_car_sim.quarter_car_node')


def semi_active_controller_node():
    """``ros2 run quarter_car_sim semi_active_controller_node``."""
    return early_main('quarter_car_sim.semi_active_controller_node')


def state_estimator_node():
    """``ros2 run quarter_car_sim state_estimator_node``."""
    return early_main('quarter_car_sim.state_estimator_node')


def full_car_node():
    """``ros2 run quarter_car_sim full_car_node``."""
    return early_main('quarter_car_sim.full_car_node')


def full_car_controller_node():
    """``ros2 run quarter_car_sim full_car_controller_node``."""
    return early_main('quarter_car_sim.full_car_controller_node')
