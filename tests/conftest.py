"""
Test-wide set-up: keep ROS 2 on loopback and on a domain of this run's own.

This runs before any test module imports rclpy, so every node a test creates (in this process or
in a subprocess that inherits the environment) uses a private domain and the suite's Fast DDS
loopback profile (``mr_damper_bringup.network``: every DDS socket on 127.0.0.1; or LOCALHOST
discovery when the profile cannot be used), as mr-damper-suite gives its nodes.
"""
import gzip
import importlib
import os
import random
import sys
import tempfile
from pathlib import Path

from mr_damper_bringup.network import apply, dds_environment  # no ROS import

apply(dds_environment(environ={}))
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(20, 220)))
# pytest-xdist (`run_tests.sh --fast`): each worker process its own domain, next to the run's
_WORKER = os.environ.get('PYTEST_XDIST_WORKER', '')   # 'gw0', 'gw1', ...
if _WORKER.startswith('gw'):
    os.environ['ROS_DOMAIN_ID'] = str(
        20 + (int(os.environ['ROS_DOMAIN_ID']) - 20 + 1 + int(_WORKER[2:])) % 201)
os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='ros_log_'))

REPO = Path(__file__).resolve().parents[1]

# The test folders mirror the packages (tests/semi_active_control/laws/...). With tests/ on
# sys.path (pytest.ini: pythonpath, for the helpers next to this file) such a folder would be
# found first and taken for a namespace package of the same name, hiding the installed one and
# its sub-packages: import each package of src/ once, without tests/ on the path, so the real
# one is the one in sys.modules.
_TESTS = str(REPO / 'tests')
_SAVED_PATH = list(sys.path)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != _TESTS]
for _package in sorted(p.parent.name for p in (REPO / 'src').glob('*/setup.py')):
    importlib.import_module(_package)
sys.path[:] = _SAVED_PATH

# measured Quiroz damper tests shipped in the repository, gzip-compressed DAQ CSVs
QUIROZ_DIR = REPO / 'data' / 'quiroz_mr_damper'
# console scripts of the editable installs live next to the interpreter running the tests
VENV_BIN = Path(sys.executable).parent


def csv_text(path):
    """Return a DAQ CSV's text, decompressed for a ``.csv.gz`` (to build altered copies)."""
    path = Path(path)
    if path.name.endswith('.gz'):
        return gzip.decompress(path.read_bytes()).decode('utf-8')
    return path.read_text()


_INTEGRATION_DIR = Path(__file__).resolve().parent / 'integration'


def pytest_collection_modifyitems(config, items):
    """Mark every test of ``tests/integration`` ``integration`` (``-m`` selects by folder too)."""
    import pytest
    for item in items:
        if _INTEGRATION_DIR in Path(item.path).resolve().parents:
            item.add_marker(pytest.mark.integration)


def pytest_sessionstart(session):
    """
    Compile (or load from numba's cache) the Spencer plant's step before the first test.

    The car and rig nodes build a Spencer plant, whose step is compiled on first use; in a fresh
    checkout a node process would otherwise spend the compilation in its start-up, inside a
    test's waits. Here it goes into the cache once (``mr_damper_model.models.compiled``).
    """
    from mr_damper_model.models.plant import make_plant
    make_plant('spencer')
