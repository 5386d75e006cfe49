"""
Check the numerical core of every package imports without ROS.

Style rule: thin nodes on a pure core.

Each core module is imported in a fresh interpreter, which must not load rclpy or any message
package. Node modules (``*_node.py``, among them the recorder and the launcher's monitor, and
every module of a ``nodes`` sub-package: what the nodes share and their console scripts),
``messages`` (message conversions), ``node_utils``, ``lifecycle_utils.py`` and
``node_parameters.py`` (parameters the nodes of a package share) are the only modules allowed
to.
"""
import subprocess
import sys

import pytest

from conftest import REPO

ROS_MODULES = {'messages', 'node_utils', 'lifecycle_utils', 'node_parameters'}
PACKAGES = ('mr_damper_common', 'mr_damper_model', 'mr_damper_rig', 'quarter_car_sim',
            'mr_damper_bringup', 'mr_damper_can', 'semi_active_control', 'mr_damper_gym')


def _core_modules():
    for pkg in PACKAGES:
        root = REPO / 'src' / pkg / pkg
        for path in sorted(root.rglob('*.py')):
            stem = path.stem
            parts = path.relative_to(root).with_suffix('').parts
            if (stem in ('__init__', '__main__') or stem.endswith('_node') or stem in ROS_MODULES
                    or 'nodes' in parts[:-1] or path.parent.name in ROS_MODULES):
                continue
            yield '.'.join((pkg,) + parts)


def _ros_modules_loaded_by(modules):
    """Import ``modules`` in one fresh interpreter; return the ROS modules it then holds."""
    code = (f'import sys, importlib; [importlib.import_module(m) for m in {modules!r}]; '
            "print(','.join(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('rclpy', 'std_msgs', 'sensor_msgs', 'builtin_interfaces'))))")
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, f'{modules} failed to import: {proc.stderr}'
    return [m for m in proc.stdout.strip().split(',') if m]


@pytest.mark.slow
def test_core_modules_do_not_import_ros():
    # all core modules in one interpreter (one start instead of one per module): importing
    # a module runs its imports whatever else is loaded, so one module pulling in ROS shows
    # here; only then is each imported alone, to name it
    modules = list(_core_modules())
    assert len(modules) > 50
    if _ros_modules_loaded_by(modules):
        culprits = {m: bad for m in modules if (bad := _ros_modules_loaded_by([m]))}
        assert not culprits, f'core modules pulled in ROS modules: {culprits}'


@pytest.mark.slow
def test_the_check_sees_a_module_that_imports_ros():
    assert 'rclpy' in _ros_modules_loaded_by(['mr_damper_common.node_utils'])
