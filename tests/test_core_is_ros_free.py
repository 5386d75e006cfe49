"""
Check the numerical core of every package imports without ROS.

Style rule: thin nodes on a pure core.

Each core module is imported in a fresh interpreter, which must not load rclpy or any message
package. Node modules (``*_node.py``, among them the recorder and the launcher's monitor),
``messages.py`` (message conversions) and ``node_utils.py`` are the only modules allowed to.
"""
import subprocess
import sys

import pytest

from conftest import REPO

ROS_MODULES = {'messages', 'node_utils'}
PACKAGES = ('mr_damper_common', 'mr_damper_model', 'mr_damper_rig', 'quarter_car_sim',
            'mr_damper_bringup', 'mr_damper_can')


def _core_modules():
    for pkg in PACKAGES:
        root = REPO / 'src' / pkg / pkg
        for path in sorted(root.glob('*.py')) + sorted(root.glob('*/*.py')):
            stem = path.stem
            if stem in ('__init__', '__main__') or stem.endswith('_node') or stem in ROS_MODULES:
                continue
            yield '.'.join((pkg,) + path.relative_to(root).with_suffix('').parts)


@pytest.mark.parametrize('module', list(_core_modules()))
def test_core_module_does_not_import_ros(module):
    code = (f'import sys, importlib; importlib.import_module({module!r}); '
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
            "('rclpy', 'std_msgs', 'sensor_msgs', 'builtin_interfaces')); "
            'print(bad); sys.exit(1 if bad else 0)')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, f'{module} pulled in ROS modules: {proc.stdout} {proc.stderr}'
