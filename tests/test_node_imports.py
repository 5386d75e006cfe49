"""
A node pulls in only what it uses, and no node module imports another.

Each node module is imported in a fresh interpreter (as ``ros2 run`` starts it); the rig, the
car, the controller, the estimator and the CAN nodes must not load the model-fitting and
file stacks (the identification and live packages, numba, rosbags, mcap, matplotlib, Dask),
which live in ``mr_damper_model``; what every node needs is in ``mr_damper_common``, what the
vehicle's and the simulated cars' nodes share in ``semi_active_control.nodes.common``. The
vehicle's corner controller and estimator also start without the design libraries (python-
control, scipy.signal: seconds of start-up), which their laws load only when they design.
"""
import ast
import subprocess
import sys

import pytest

from conftest import REPO


FITTING_STACK = ('mr_damper_model.identification', 'mr_damper_model.live', 'numba', 'rosbags',
                 'mcap', 'matplotlib', 'dask', 'distributed')
NODES = ('mr_damper_rig.rig_node', 'quarter_car_sim.nodes.quarter_car_node',
         'semi_active_control.nodes.semi_active_controller_node',
         'semi_active_control.nodes.state_estimator_node', 'quarter_car_sim.nodes.full_car_node',
         'mr_damper_can.can_bridge_node',
         'mr_damper_can.can_driver_sim_node', 'mr_damper_can.vehicle_bridge_node',
         'mr_damper_can.vehicle_computer_node',
         'semi_active_control.nodes.vehicle_estimator_node',
         'semi_active_control.nodes.vehicle_controller_node',
         'semi_active_control.nodes.lifecycle_manager_node')


#: Vehicle nodes whose start loads no design library (a law that designs loads it then).
LIGHT_NODES = ('semi_active_control.nodes.semi_active_controller_node',
               'semi_active_control.nodes.state_estimator_node')
DESIGN_LIBRARIES = ('control', 'scipy.signal')


def node_modules():
    """Return ``{module: path}`` of every node module of src/ (a ``*_node.py`` file)."""
    out = {}
    for path in sorted((REPO / 'src').glob('*/*/**/*_node.py')):
        pkg_dir = path.relative_to(REPO / 'src').parts[0]
        rel = path.relative_to(REPO / 'src' / pkg_dir).with_suffix('')
        out['.'.join(rel.parts)] = path
    return out


def imports_of(path):
    """Return the modules a file imports (module and function level; ``from a import b``: a.b)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module)
            out.update(f'{node.module}.{a.name}' for a in node.names)
    return out


def test_no_node_module_imports_another():
    nodes = node_modules()
    assert set(NODES) <= set(nodes)
    bad = {m: sorted(imports_of(p) & (set(nodes) - {m})) for m, p in nodes.items()}
    bad = {m: found for m, found in bad.items() if found}
    assert not bad, f'node modules importing node modules (share through a core): {bad}'


def test_the_check_sees_a_node_importing_a_node(tmp_path):
    path = tmp_path / 'car_node.py'
    path.write_text('def main():\n    from quarter_car_sim.nodes import quarter_car_node\n')
    assert 'quarter_car_sim.nodes.quarter_car_node' in imports_of(path)


def loaded(modules, watch):
    """Import ``modules`` in one fresh interpreter; return those of ``watch`` then loaded."""
    code = (f'import importlib, sys; [importlib.import_module(m) for m in {modules!r}]; '
            f'print(",".join(m for m in {watch!r} if m in sys.modules))')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    return [m for m in proc.stdout.strip().split(',') if m]


@pytest.mark.slow
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


@pytest.mark.slow
def test_light_vehicle_nodes_start_without_the_design_libraries():
    culprits = {m: found for m in LIGHT_NODES if (found := loaded([m], DESIGN_LIBRARIES))}
    assert not culprits, f'vehicle nodes loading design libraries at start: {culprits}'
