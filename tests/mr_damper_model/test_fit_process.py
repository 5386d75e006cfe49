"""The fit child process (``python -m mr_damper_model.live``) against what a node meets."""
import os
import signal
import time

import pytest

from live_records import cam_record
from mr_damper_model.live import FitProcess, fit_data, LiveConfig

DET = dict(budget_s=0.0, hop_s=1.0, maxiter=40)


@pytest.fixture
def proc():
    p = FitProcess()
    yield p
    p.close()


@pytest.mark.slow
def test_the_child_is_in_its_own_session(proc):
    # Ctrl-C in a terminal reaches the node's process group, not the child: the node ends it
    proc.warm_up()
    assert os.getsid(proc._proc.pid) == proc._proc.pid != os.getsid(0)


@pytest.mark.slow
def test_a_killed_child_fails_one_call_then_is_replaced(proc):
    data, _, _ = cam_record(currents=(1.0,), hold_s=1.0)
    cfg = LiveConfig(warm_start=False, **DET)
    proc.warm_up()
    first = proc._proc.pid
    os.kill(first, signal.SIGKILL)
    try:
        proc(data, 'kwok', cfg)      # found dead before the call (replaced) or during it
    except RuntimeError as exc:
        assert 'fit process failed' in str(exc)
    assert proc(data, 'kwok', cfg).parameters == fit_data(data, 'kwok', cfg).parameters
    assert proc.alive() and proc._proc.pid != first


def _ended(pid):
    """Return True when the process is gone or a zombie (ended, not yet reaped)."""
    try:
        os.kill(pid, 0)
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] == 'Z'
    except (ProcessLookupError, FileNotFoundError):
        return True


@pytest.mark.slow
def test_close_ends_the_child(proc):
    proc.warm_up()
    pid = proc._proc.pid
    proc.close(wait_s=5.0)
    assert not proc.alive()
    for _ in range(3000):              # hang guard only: close() kills after wait_s
        if _ended(pid):
            break
        time.sleep(0.01)
    assert _ended(pid)


@pytest.mark.slow
def test_the_child_ends_when_its_node_is_killed():
    # a node killed with SIGKILL cannot close its child: the child ends when its stdin closes
    import subprocess
    import sys
    code = ('import time\nfrom mr_damper_model.live import FitProcess\np = FitProcess()\n'
            'p.warm_up()\nprint(p._proc.pid, flush=True)\ntime.sleep(600)\n')
    from process_helpers import popen, stop_group
    node = popen([sys.executable, '-c', code], stdout=subprocess.PIPE, text=True)
    try:
        child = int(node.stdout.readline())
        assert not _ended(child)
        node.kill()
        node.wait()
        for _ in range(3000):          # hang guard only
            if _ended(child):
                break
            time.sleep(0.01)
        assert _ended(child)
    finally:
        stop_group(node, signal.SIGKILL)


@pytest.mark.slow
def test_a_request_cut_off_by_the_shutdown_ends_the_child_quietly():
    # the node's shutdown may close the child's stdin while a request is half written: the
    # child ends with status 0 and no traceback ("pickle data was truncated" at the stop)
    import pickle
    import subprocess
    import sys
    child = subprocess.Popen([sys.executable, '-m', 'mr_damper_model.live'],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, start_new_session=True)
    try:
        request = pickle.dumps(('x' * 100_000, 'kwok', None, None),
                               protocol=pickle.HIGHEST_PROTOCOL)
        child.stdin.write(request[:len(request) // 2])
        child.stdin.close()
        err = child.stderr.read()            # to its end: the child has exited
        child.wait(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 0, err
    assert b'Traceback' not in err, err
