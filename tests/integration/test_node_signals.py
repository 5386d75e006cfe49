"""
Every node's console script exits 0 on SIGINT or SIGTERM, also while it is still starting up.

The stop handlers are installed before the node module is imported
(``mr_damper_common.stop_flag.early_main``). The test waits until the process catches SIGTERM
(Python itself never does, so the bit in ``/proc/PID/status`` ``SigCgt`` says our handler is
in), then signals at once: on any machine that is while rclpy, scipy and control are still
being imported. Before the early handlers, a SIGINT in that window was swallowed inside an
import and the node ran on until killed. Order of events and exit codes only; the waits are
hang guards.
"""
import os
import signal
import subprocess
import time

import pytest

from conftest import VENV_BIN
from process_helpers import popen, stop_group

pytestmark = [pytest.mark.integration]

GUARD_S = 90.0
SCRIPTS = {
    'rig_node': ['--ros-args', '-p', 'mode:=sim'],
    'identifier_node': [],
    'quarter_car_node': [],
    'mr-damper-record': ['--out', '{tmp}/run.mcap'],
    'can_bridge_node': [],
    'can_driver_sim': [],
}


def _catches(pid, signum):
    """Return True once process ``pid`` has a handler for ``signum`` (/proc SigCgt)."""
    try:
        with open(f'/proc/{pid}/status') as fh:
            for line in fh:
                if line.startswith('SigCgt:'):
                    return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    except OSError:
        pass
    return False


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize('script', sorted(SCRIPTS))
def test_signal_during_start_up_exits_0(tmp_path, script, sig):
    args = [a.replace('{tmp}', str(tmp_path)) for a in SCRIPTS[script]]
    log = tmp_path / 'node.log'
    with open(log, 'w') as fh:
        proc = popen([str(VENV_BIN / script), *args], stdout=fh, stderr=subprocess.STDOUT)
    try:
        end = time.monotonic() + GUARD_S
        while not _catches(proc.pid, signal.SIGTERM) and proc.poll() is None \
                and time.monotonic() < end:
            time.sleep(0.002)
        assert proc.poll() is None, log.read_text()
        assert _catches(proc.pid, signal.SIGTERM), 'stop handlers never installed'
        os.kill(proc.pid, sig)
        rc = proc.wait(timeout=GUARD_S)
    finally:
        stop_group(proc, signal.SIGKILL)
    text = log.read_text()
    assert 'Traceback' not in text, text
    assert rc == 0, text


_STUCK_RECORDER = '''
import sys, time
import rclpy.node
from mr_damper_common.node_utils import spinning

def destroy_node(self):
    print('destroying', file=sys.stderr, flush=True)
    while True:
        time.sleep(0.01)            # the middleware's teardown, never returning

rclpy.node.Node.destroy_node = destroy_node
spinning.TEARDOWN_GUARD_S = 0.5
spinning.TEARDOWN_WATCHDOG_S = 3600.0
from mr_damper_bringup import record_node
sys.exit(record_node.main(['mr-damper-record', '--out', sys.argv[1], '--duration', '0.5',
                           '--parameters-period-s', '0']))
'''


def test_a_recorder_stuck_in_its_teardown_exits_0_with_a_complete_file(tmp_path):
    # a recorder SIGKILLed in rclpy's teardown failed a CI run: the file and the count line
    # come first, then the middleware gets its guard time and the process leaves without it
    from mr_damper_common.recording.mcap_scan import McapScan
    out = tmp_path / 'stuck.mcap'
    proc = popen([str(VENV_BIN / 'python'), '-c', _STUCK_RECORDER, str(out)],
                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _, err = proc.communicate(timeout=GUARD_S)          # hang guard only
    finally:
        stop_group(proc, signal.SIGKILL)
    assert proc.returncode == 0, err
    # in this order: the count line, the teardown, the guard's line with every thread's stack
    written = err.index(f'written to {out}')
    assert written < err.index('destroying') < err.index('did not tear the node down'), err
    assert 'in destroy_node' in err, err
    scan = McapScan(out)
    n = sum(1 for _ in scan.messages())
    assert scan.complete is True and n > 0, scan.summary()
