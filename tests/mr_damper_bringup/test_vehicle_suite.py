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


def test_the_suites_vehicle_controller_has_the_coil_settings_the_offline_chain_assumes():
    # simulate_vehicle_chain's default supervision (COIL_SETTINGS) is the suite's vehicle
    # computer's, so bench_vehicle_chain's runs answer as the live loop does
    from mr_damper_bringup.config import load_config, node_params
    from semi_active_control.supervision import COIL_SETTINGS
    p = node_params(load_config('vehicle'), 'vehicle_controller')
    assert {k: p[k] for k in COIL_SETTINGS} == COIL_SETTINGS
