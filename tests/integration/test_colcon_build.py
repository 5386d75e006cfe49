"""
``colcon build`` of the workspace (colcon from the venv, pip only) gives what ``ros2 run`` runs.

``ros2 run PKG EXE`` executes ``install/PKG/lib/PKG/EXE``: the build must produce that file for
every node, and each must start from the install (sourcing ``install/setup.bash``, so the
packages come from the install tree, not from the editable checkout). The message package
``mr_damper_interfaces`` (ament_cmake + rosidl) builds the standard way too, with colcon's cmake
plugin, against the ROS 2 wheels of the venv (the prefix a full install would source).
"""
import os
from pathlib import Path
import shlex
import signal
import subprocess
import sys
import time

import pytest

from conftest import REPO, VENV_BIN
from integration.ros_helpers import console_scripts, python_packages
from process_helpers import popen, run, stop_group

pytestmark = [pytest.mark.integration, pytest.mark.slow]

#: every console script of every package (its setup.py): what `ros2 run` can start
NODES = [(pkg, exe) for pkg in python_packages() for exe in sorted(console_scripts(pkg))]


@pytest.fixture(scope='module')
def install(tmp_path_factory):
    ws = tmp_path_factory.mktemp('colcon_ws')
    prefix = sys.prefix   # the venv: its ROS 2 wheels are this build's underlay
    env = dict(os.environ, PATH=f'{VENV_BIN}{os.pathsep}{os.environ["PATH"]}',
               AMENT_PREFIX_PATH=prefix, CMAKE_PREFIX_PATH=prefix)
    out = subprocess.run([str(VENV_BIN / 'colcon'), '--log-base', str(ws / 'log'), 'build',
                          '--base-paths', str(REPO / 'src'), '--build-base', str(ws / 'build'),
                          '--install-base', str(ws / 'install'),
                          '--cmake-args', f'-DPython3_EXECUTABLE={sys.executable}',
                          '-DBUILD_TESTING=OFF'],
                         cwd=ws, env=env, capture_output=True, text=True, timeout=1000)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return ws / 'install'


def in_install(install, command):
    """Run ``command`` in bash after sourcing the install's setup.bash (no ``set -u``)."""
    return ['bash', '-c', f'source {shlex.quote(str(install / "setup.bash"))} && {command}']


@pytest.mark.parametrize('pkg, exe', NODES)
def test_executable_is_where_ros2_run_looks(install, pkg, exe):
    path = install / pkg / 'lib' / pkg / exe
    assert path.is_file() and os.access(path, os.X_OK)
    assert (install / pkg / 'share' / pkg / 'package.xml').is_file()
    assert (install / pkg / 'share' / 'ament_index' / 'resource_index' / 'packages'
            / pkg).is_file()


def test_packages_come_from_the_install(install):
    out = subprocess.run(in_install(install, f'{VENV_BIN / "python"} -c "import mr_damper_rig, '
                                    'mr_damper_model, quarter_car_sim as q, '
                                    'mr_damper_bringup as b; '
                                    'print(mr_damper_rig.__file__, mr_damper_model.__file__, '
                                    'q.__file__, b.__file__)"'),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    for path in out.stdout.split():
        assert Path(path).is_relative_to(install), path


def test_bringup_launch_file_and_configs_come_from_the_install(install, tmp_path):
    pkg = 'mr_damper_bringup'
    share = install / pkg / 'share' / pkg
    assert (share / 'launch' / 'suite.launch.py').is_file()
    names = ('suite_sim.yaml', 'suite_replay.yaml', 'suite_hil.yaml')
    for name in names:
        assert (share / 'config' / name).read_text() == \
            (REPO / 'src' / pkg / 'config' / name).read_text()
    # the launcher finds the installed configs (ament index), not the checkout's
    code = 'from mr_damper_bringup.config import CONFIG_DIR; print(CONFIG_DIR)'
    out = subprocess.run(in_install(install, f'{VENV_BIN / "python"} -c {shlex.quote(code)}'),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert Path(out.stdout.strip()) == share / 'config'
    # both console scripts start from the install: a bad command line is refused (exit 2)
    for exe, args in (('mr-damper-suite', '--duration -1'),
                      ('mr-damper-record', f'--out {tmp_path / "not_mcap.txt"}')):
        out = run(in_install(install, f'{install / pkg / "lib" / pkg / exe} {args}'), 60)
        assert out.returncode == 2, (exe, out.stdout + out.stderr)
        assert 'Traceback' not in out.stderr, out.stderr


def test_interfaces_come_from_the_install(install):
    pkg = 'mr_damper_interfaces'
    share = install / pkg / 'share' / pkg
    for name in ('KwokParameters', 'QuarterCarState'):
        assert (share / 'msg' / f'{name}.msg').read_text() == \
            (REPO / 'src' / pkg / 'msg' / f'{name}.msg').read_text()
        assert (share / 'msg' / f'{name}.idl').is_file()
    assert (install / pkg / 'share' / 'ament_index' / 'resource_index' / 'packages'
            / pkg).is_file()
    code = ('import mr_damper_interfaces.msg as m; '
            'from rclpy.serialization import serialize_message as s, deserialize_message as d; '
            'k = m.KwokParameters(c0=1.5, reason="ok"); '
            'assert d(s(k), m.KwokParameters) == k; print(m.__file__)')
    out = subprocess.run(in_install(install, f'{VENV_BIN / "python"} -c {shlex.quote(code)}'),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert Path(out.stdout.strip()).is_relative_to(install / pkg), out.stdout


def test_can_dbc_comes_from_the_install(install):
    pkg = 'mr_damper_can'
    dbc = REPO / 'src' / pkg / pkg / 'dbc' / 'mr_damper.dbc'
    assert (install / pkg / 'share' / pkg / 'dbc' / 'mr_damper.dbc').read_text() == \
        dbc.read_text()
    code = ('from mr_damper_can.codec import dbc_path, load_database; '
            'print(dbc_path(), len(load_database().messages))')
    out = subprocess.run(in_install(install, f'{VENV_BIN / "python"} -c {shlex.quote(code)}'),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    path, n = out.stdout.split()
    frames = sum(line.startswith('BO_ ') for line in dbc.read_text().splitlines())
    assert Path(path).is_relative_to(install / pkg) and int(n) == frames > 0, out.stdout


def test_rig_node_from_install_runs_and_reports_bad_file(install, tmp_path):
    exe = install / 'mr_damper_rig' / 'lib' / 'mr_damper_rig' / 'rig_node'
    missing = tmp_path / 'missing.csv'
    out = run(in_install(install, f'{exe} --ros-args -p mode:=csv -p file:={missing}'), 60)
    assert out.returncode == 2, out.stdout + out.stderr
    assert f'{missing}: cannot read file' in out.stderr


@pytest.mark.parametrize('exe', ['semi_active_controller_node', 'state_estimator_node'])
def test_moved_nodes_old_names_still_run_with_a_warning(install, exe):
    # the vehicle's nodes moved to semi_active_control (issue 33): `ros2 run quarter_car_sim
    # <exe>` still starts them for one release, saying so on stderr (run with this venv's
    # interpreter: the script's `python3` is a vehicle computer's ROS Python)
    old = install / 'quarter_car_sim' / 'lib' / 'quarter_car_sim' / exe
    assert old.is_file() and os.access(old, os.X_OK)
    out = subprocess.run(in_install(install, f'{VENV_BIN / "python"} {old} --ros-args '
                                    '-p rate_hz:=-1.0'),
                         capture_output=True, text=True, timeout=120)
    assert 'deprecated' in out.stderr and f'ros2 run semi_active_control {exe}' in out.stderr
    assert out.returncode == 2, out.stdout + out.stderr      # the node ran: bad parameter
    assert 'Traceback' not in out.stderr, out.stderr


def test_the_removed_full_car_controller_says_what_replaces_it(install):
    # full_car_controller_node (four corner streams) gave way to vehicle_controller_node (one
    # FullCarState in, one FullCarCommand out, issue 35): its old name exits 2 saying so
    old = install / 'quarter_car_sim' / 'lib' / 'quarter_car_sim' / 'full_car_controller_node'
    out = subprocess.run(in_install(install, f'{VENV_BIN / "python"} {old}'),
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2, out.stdout + out.stderr
    assert 'semi_active_control vehicle_controller_node' in out.stderr, out.stderr
    assert not (install / 'semi_active_control' / 'lib' / 'semi_active_control'
                / 'full_car_controller_node').exists()


@pytest.mark.parametrize('pkg, exe, ready', [
    ('mr_damper_model', 'identifier_node', 'identifying'),
    ('quarter_car_sim', 'quarter_car_node', ' Hz (x'),     # 'skyhook at 1000 Hz (x1 real time)'
])
def test_long_running_nodes_start_from_install(install, tmp_path, pkg, exe, ready):
    log = tmp_path / f'{exe}.log'
    with open(log, 'w') as fh:
        proc = popen(in_install(install, f'exec {install / pkg / "lib" / pkg / exe}'),
                     stdout=fh, stderr=subprocess.STDOUT)
    try:
        end = time.monotonic() + 30.0
        while time.monotonic() < end and proc.poll() is None:
            if ready in log.read_text():
                break
            time.sleep(0.2)
        assert proc.poll() is None, log.read_text()
        assert ready in log.read_text()
    finally:
        stop_group(proc, signal.SIGINT, 15.0)
    assert 'Traceback' not in log.read_text(), log.read_text()
    assert proc.returncode == 0, log.read_text()
