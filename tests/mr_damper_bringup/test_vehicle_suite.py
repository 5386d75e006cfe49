"""Tests of mr_damper_bringup.vehicle_suite: the vehicle configuration's nodes and stop order."""
from mr_damper_bringup.vehicle_suite import CHAINS, FULL_CAR, LAYOUTS, MANAGER, STOP_ORDER, \
    vehicle_nodes


def test_the_car_has_exited_before_the_vehicle_computer_is_stopped_in_either_layout():
    # two groups (Suite.stop's ``order`` then ``then``: each group has exited before the next
    # is signalled): the manager (it would bring a stopped node back) and the plant first, so
    # that the computer's end (its safe frame, then silence) does not reach the drivers as
    # command timeouts counted against the run
    first, then = STOP_ORDER
    assert set(first) == {MANAGER, FULL_CAR}
    for layout in LAYOUTS:
        assert set(vehicle_nodes(layout)) - set(first) <= set(then), layout
        assert set(CHAINS[layout]) <= set(then), layout
    # within the three-node chain: the controller ends before the bridge it commands through
    assert then.index('vehicle_controller') < then.index('vehicle_bridge')
