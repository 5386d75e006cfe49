"""
A node pulls in only what it uses: no node but the identifier loads the fitting stack.

Each node module is imported in a fresh interpreter (as ``ros2 run`` starts it); the rig, the
car, the controller, the estimator and the CAN nodes must not load the model-fitting and
file stacks (the identification and live packages, numba, rosbags, mcap, matplotlib, Dask),
which live in
``mr_damper_model`` behind lazy imports; what every node needs is in ``mr_damper_common``.
"""
import subprocess
import sys

import pytest


FITTING_STACK = ('mr_damper_model.identification', 'mr_damper_model.live', 'numba', 'rosbags',
                 'mcap', 'matplotlib', 'dask', 'distributed')
NODES = ('mr_damper_rig.rig_node', 'quarter_car_sim.quarter_car_node',
         'quarter_car_sim.semi_active_controller_node', 'quarter_car_sim.state_estimator_node',
         'quarter_car_sim.full_car_node', 'quarter_car_sim.full_car_controller_node',
         'mr_damper_can.can_bridge_node',
         'mr_damper_can.can_driver_sim_node', 'mr_damper_can.vehicle_bridge_node',
         'semi_active_control.nodes.vehicle_estimator_node',
         'semi_active_control.nodes.vehicle_controller_node',
         'semi_active_control.nodes.lifecycle_manager_node')


def loaded(modules, watch):
    """Import ``modules`` in one fresh interpreter; return those of ``watch`` then loaded."""
    code = (f'import importlib, sys; [importlib.import_module(m) for m in {modules!r}]; '
            f'print(",".join(m for m in {watch!r} if m in sys.modules))')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    return [m for m in proc.stdout.strip().split(',') if m]


def test_nodes_do_not_load_the_fitting_stack():
    # every node module in one interpreter (one start instead of one per node): a node that
    # loads the stack at import does so whatever else is loaded; only then each alone, to name it
    if loaded(NODES, FITTING_STACK):
        culprits = {m: found for m in NODES if (found := loaded([m], FITTING_STACK))}
        assert not culprits, f'nodes loading the fitting stack: {culprits}'


@pytest.mark.slow
def test_the_check_sees_a_module_that_loads_it():
    # the identifier node fits: it loads the live identifier and the fitting code at import
    found = loaded(['mr_damper_model.nodes.identifier_node'], FITTING_STACK)
    assert {'mr_damper_model.identification', 'mr_damper_model.live'} <= set(found)
