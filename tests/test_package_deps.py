"""
Every package declares in its package.xml what its code imports (issue 9), so the two cannot drift.

The modules a package's Python code imports (``ast``: every ``import`` and absolute ``from``
import, at module level or inside functions; the standard library and the package itself left
out; ``setup.py`` left out) must each be an ``exec_depend`` or ``depend`` of its package.xml:
under the rosdep key of :data:`ROSDEP_KEYS` for third-party Python modules, under its own name
for ROS packages (a ROS package's Python module has the package's name).
"""
import ast
import sys
import xml.etree.ElementTree as ET

import pytest

from conftest import REPO

#: rosdep key of each third-party Python module the suite uses (pip names in requirements.txt)
ROSDEP_KEYS = {'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'control': 'python3-control',
               'yaml': 'python3-yaml', 'rosbags': 'python3-rosbags', 'mcap': 'python3-mcap',
               'matplotlib': 'python3-matplotlib', 'numba': 'python3-numba',
               'psutil': 'python3-psutil', 'pytest': 'python3-pytest', 'can': 'python3-can',
               'cantools': 'python3-cantools', 'dask': 'python3-dask',
               'distributed': 'python3-distributed', 'gymnasium': 'python3-gymnasium'}

PACKAGES = sorted(p.parent for p in (REPO / 'src').glob('*/package.xml')
                  if (p.parent / p.parent.name).is_dir())


def imported_modules(package_dir):
    """Return ``{top-level module: [files importing it]}`` of a package's Python code."""
    found = {}
    for path in sorted((package_dir / package_dir.name).rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top not in sys.stdlib_module_names and top != package_dir.name:
                    found.setdefault(top, []).append(path.name)
    return found


def declared_dependencies(package_dir):
    """Return the run-time dependencies (``depend``, ``exec_depend``) of a package.xml."""
    root = ET.parse(package_dir / 'package.xml').getroot()
    return {e.text.strip() for tag in ('depend', 'exec_depend') for e in root.iter(tag)}


def test_the_packages_are_found():
    names = {p.name for p in PACKAGES}
    assert {'mr_damper_model', 'mr_damper_rig', 'quarter_car_sim', 'mr_damper_can'} <= names


@pytest.mark.parametrize('package_dir', PACKAGES, ids=lambda p: p.name)
def test_package_xml_declares_every_import(package_dir):
    declared = declared_dependencies(package_dir)
    missing = {}
    for module, files in imported_modules(package_dir).items():
        key = ROSDEP_KEYS.get(module, module)
        if key not in declared:
            missing[key] = sorted(set(files))
    assert not missing, (f'{package_dir.name}/package.xml does not declare (key: importing '
                         f'files): {missing}')


def test_the_check_sees_a_missing_dependency(tmp_path):
    # a package importing scipy and rclpy that declares only rclpy is caught
    pkg = tmp_path / 'demo_pkg'
    (pkg / 'demo_pkg').mkdir(parents=True)
    (pkg / 'demo_pkg' / 'core.py').write_text(
        'import math\n\nimport rclpy\n\n\ndef f():\n    from scipy import signal\n'
        '    from demo_pkg import core\n    return signal, core, math, rclpy\n')
    (pkg / 'package.xml').write_text('<package format="3"><name>demo_pkg</name>'
                                     '<exec_depend>rclpy</exec_depend></package>')
    assert set(imported_modules(pkg)) == {'rclpy', 'scipy'}
    assert declared_dependencies(pkg) == {'rclpy'}


def test_workspace_dependencies_point_one_way():
    # mr_damper_model <- quarter_car_sim <- mr_damper_rig (and whatever sits on top): the
    # declared dependencies among the workspace's packages have no cycle
    names = {p.parent.name for p in (REPO / 'src').glob('*/package.xml')}
    deps = {p.parent.name: declared_dependencies(p.parent) & names
            for p in (REPO / 'src').glob('*/package.xml')}
    assert 'mr_damper_rig' not in deps['quarter_car_sim']
    assert 'quarter_car_sim' not in deps['mr_damper_rig']
    assert not deps['mr_damper_common'] - {'mr_damper_interfaces'}
    assert not deps['mr_damper_model'] - {'mr_damper_interfaces', 'mr_damper_common'}
    done, path = set(), []

    def visit(name):
        assert name not in path, f'dependency cycle: {" -> ".join(path + [name])}'
        if name in done:
            return
        path.append(name)
        for dep in sorted(deps[name]):
            visit(dep)
        path.pop()
        done.add(name)

    for name in sorted(deps):
        visit(name)


#: What the vehicle side may never import: the simulator and the fitting stack (issue 33).
VEHICLE_FORBIDDEN = ('quarter_car_sim', 'mr_damper_rig', 'mr_damper_bringup', 'mr_damper_can',
                     'mr_damper_model.identification', 'mr_damper_model.live',
                     'mr_damper_model.io', 'mr_damper_model.tools', 'mr_damper_model.nodes')
#: ... except the parameter file format: a vehicle reads its dampers' end-of-line records.
VEHICLE_ALLOWED = ('mr_damper_model.io.params_file',)


def imported_names(path):
    """
    Return ``[(line, module)]`` of every import of a file, module and function level (ast).

    ``from package import name`` gives ``package.name`` too (a sub-module imported that way).
    """
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append((node.lineno, node.module))
            out += [(node.lineno, f'{node.module}.{a.name}') for a in node.names]
    return out


def forbidden_imports(package_dir, forbidden):
    """Return ``['file:line module']`` of the imports of ``forbidden`` (or below) in a package."""
    bad = []
    for path in sorted((package_dir / package_dir.name).rglob('*.py')):
        for line, name in imported_names(path):
            if any(name == a or name.startswith(a + '.') for a in VEHICLE_ALLOWED):
                continue
            if any(name == f or name.startswith(f + '.') for f in forbidden):
                bad.append(f'{path.relative_to(package_dir)}:{line} {name}')
    return bad


def test_the_vehicle_side_imports_neither_the_simulator_nor_the_fitting_stack():
    bad = forbidden_imports(REPO / 'src' / 'semi_active_control', VEHICLE_FORBIDDEN)
    assert not bad, 'semi_active_control imports what a vehicle does not run:\n' + '\n'.join(bad)


def test_the_forbidden_import_check_sees_function_level_and_from_imports(tmp_path):
    pkg = tmp_path / 'demo_pkg'
    (pkg / 'demo_pkg').mkdir(parents=True)
    (pkg / 'demo_pkg' / 'law.py').write_text(
        'import math\n\n\ndef f():\n    from mr_damper_model import identification\n'
        '    import quarter_car_sim.plant.road\n    return identification, math\n')
    (pkg / 'demo_pkg' / 'ok.py').write_text('from mr_damper_model.models import inverse\n'
                                            'from mr_damper_model.io.params_file import x\n')
    assert forbidden_imports(pkg, VEHICLE_FORBIDDEN) == [
        'demo_pkg/law.py:5 mr_damper_model.identification',
        'demo_pkg/law.py:6 quarter_car_sim.plant.road']


def test_the_layers_point_one_way():
    # mr_damper_common <- mr_damper_model <- semi_active_control <- quarter_car_sim <- the rest
    names = {p.parent.name for p in (REPO / 'src').glob('*/package.xml')}
    deps = {p.parent.name: declared_dependencies(p.parent) & names
            for p in (REPO / 'src').glob('*/package.xml')}
    assert not deps['semi_active_control'] - {'mr_damper_interfaces', 'mr_damper_common',
                                              'mr_damper_model'}
    # (mr_damper_can: the simulated damper drivers of the car on a CAN bus)
    assert deps['quarter_car_sim'] - {'mr_damper_interfaces'} <= {
        'mr_damper_common', 'mr_damper_model', 'semi_active_control', 'mr_damper_can'}
    users = {name for name, d in deps.items() if 'semi_active_control' in d}
    assert 'mr_damper_model' not in users and 'mr_damper_common' not in users
