"""The launcher's ProcessStats reads a node's main thread (its spin thread) apart from the rest."""
import os
import signal
import subprocess
import sys
import time

import pytest

from mr_damper_bringup.processes import ProcessStats

pytest.importorskip('psutil')

#: A process with two threads: one spins, the other blocks reading stdin. ``MAIN_SPINS``: the
#: main thread spins (a node at work), else the worker does (a starved spin thread).
CHILD = r'''
import os, sys, threading
def spin():
    x = 0
    while True:
        x += 1
def block():
    sys.stdin.read()
if os.environ['MAIN_SPINS'] == '1':
    threading.Thread(target=block, daemon=True).start()
    print('ready', flush=True)
    spin()
else:
    threading.Thread(target=spin, daemon=True).start()
    print('ready', flush=True)
    block()
'''

#: Only a guard against a hung test, never a figure the test checks [s].
GUARD_S = 300.0


class OneProcessSuite:
    """What ProcessStats asks of the launcher's Suite: the processes and whether they run."""

    def __init__(self, proc):
        self.procs = {'node': proc}

    def alive(self, name):
        return self.procs[name].poll() is None


def sample_until(stats, cpu_s):
    """Sample until the process used ``cpu_s`` more CPU [s]; return both samples."""
    stats.sample()
    first = stats.cpu_seconds['node']
    guard = time.monotonic() + GUARD_S
    while True:
        time.sleep(0.05)
        stats.sample()
        last = stats.cpu_seconds['node']
        if last[1] - first[1] >= cpu_s:
            return first, last
        assert time.monotonic() < guard, 'the spinning thread got no CPU'


@pytest.mark.parametrize('main_spins', [False, True])
def test_the_main_threads_cpu_time_is_sampled_apart(tmp_path, main_spins):
    proc = subprocess.Popen([sys.executable, '-c', CHILD], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, start_new_session=True,
                            env={**os.environ, 'MAIN_SPINS': '1' if main_spins else '0'})
    stats = ProcessStats(OneProcessSuite(proc), tmp_path)
    try:
        assert proc.stdout.readline() == b'ready\n'
        first, last = sample_until(stats, 0.3)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        stats.close()
    process_s, main_s = last[1] - first[1], last[2] - first[2]
    assert last[0] > first[0] and process_s >= 0.3
    if main_spins:
        assert main_s > 0.8 * process_s         # nearly all of it in the main thread
    else:
        assert main_s < 0.1 * process_s         # blocked: the worker used it all
