"""
Console scripts of the quarter_car_sim nodes: stop handlers first, then the node module.

See :func:`mr_damper_common.stop_flag.early_main` for why the order matters. The vehicle's
nodes moved to ``semi_active_control`` (``ros2 run semi_active_control <node>``); their old
names here keep working for one release, with a deprecation warning on stderr;
``full_car_controller_node`` was replaced by ``vehicle_controller_node`` and says so.
"""
import sys

from mr_damper_common.stop_flag import early_main


def quarter_car_node():
    """``ros2 run quarter_car_sim quarter_car_node``."""
    return early_main('quarter_car_sim.nodes.quarter_car_node')


def full_car_node():
    """``ros2 run quarter_car_sim full_car_node``."""
    return early_main('quarter_car_sim.nodes.full_car_node')


def _moved(executable):
    """Warn that ``executable`` moved to semi_active_control, then run it from there."""
    print(f'[WARN] quarter_car_sim {executable} is deprecated and goes in the next release: '
          f'use ros2 run semi_active_control {executable}', file=sys.stderr, flush=True)
    return early_main(f'semi_active_control.nodes.{executable}')


def semi_active_controller_node():
    """Run ``ros2 run quarter_car_sim semi_active_controller_node``: deprecated, it moved."""
    return _moved('semi_active_controller_node')


def state_estimator_node():
    """Run ``ros2 run quarter_car_sim state_estimator_node``: deprecated, it moved."""
    return _moved('state_estimator_node')


def full_car_controller_node():
    """Run ``ros2 run quarter_car_sim full_car_controller_node``: removed, say what replaces it."""
    print('[ERROR] quarter_car_sim full_car_controller_node (four corner-state streams in, four '
          'current streams out) was removed: its law, inverses and supervisors run in ros2 run '
          'semi_active_control vehicle_controller_node (one mr_damper_interfaces/FullCarState '
          'in on vehicle/state, one FullCarCommand out on vehicle/command; docs/vehicle.md); '
          'full_car_node controller:=external speaks to it', file=sys.stderr, flush=True)
    return 2
