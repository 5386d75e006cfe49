"""
Processes a test starts end with it: own process group, SIGTERM when the test process dies.

:func:`popen` starts a command in a session (process group) of its own whose leader gets SIGTERM
from the kernel if the test process dies (``mr_damper_bringup.processes.die_with_parent``);
:func:`stop_group` stops the whole group, not the leader alone; :func:`run` is
``subprocess.run`` that kills the group on its timeout. For ``mr-damper-suite``, whose nodes
run in sessions of their own, :func:`end_suite` stops the launcher's group and then waits until
every node process it started (``pids.json``) is gone, SIGKILLing those left after a hang guard.
Waits poll ``/proc``; their limits are hang guards, never a time budget.
"""
import json
import os
from pathlib import Path
import signal
import subprocess
import time

from mr_damper_bringup.processes import die_with_parent
from mr_damper_bringup.reaper import proc_stat


def popen(cmd, **kwargs):
    """``subprocess.Popen`` in a new session that gets SIGTERM when the test process dies."""
    return subprocess.Popen(cmd, start_new_session=True, preexec_fn=die_with_parent(), **kwargs)


def _signal_group(pid, sig):
    try:
        os.killpg(pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def stop_group(proc, sig=signal.SIGINT, timeout_s=10.0):
    """
    Stop ``proc`` and every process of its group: ``sig``, then SIGKILL after ``timeout_s``.

    The group's leader is ``proc`` (started by :func:`popen`). Returns its exit status.
    """
    if proc.poll() is None:
        _signal_group(proc.pid, sig)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            pass
    _signal_group(proc.pid, signal.SIGKILL)     # the rest of its group, if any is left
    if proc.poll() is None:
        proc.wait(timeout=30.0)
    return proc.returncode


def run(cmd, timeout, **kwargs):
    """
    Run ``cmd`` to its end in a process group of its own, its output captured as text.

    As ``subprocess`` does with ``capture_output=True, text=True``, but on ``timeout`` [s] (a
    hang guard) the whole group is killed and ``TimeoutExpired`` raised.
    """
    proc = popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        stop_group(proc, signal.SIGKILL)
        proc.communicate()
        raise
    finally:
        if proc.poll() is None:
            stop_group(proc, signal.SIGKILL)
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


def alive(pid):
    """Tell whether process ``pid`` exists and is not a zombie."""
    st = proc_stat(pid)
    return st is not None and st[0] not in ('Z', 'X')


def wait_gone(pids, guard_s=60.0, poll_s=0.05):
    """Wait until none of ``pids`` runs; return those still running after ``guard_s`` [s]."""
    end = time.monotonic() + guard_s
    left = [p for p in pids if alive(p)]
    while left and time.monotonic() < end:
        time.sleep(poll_s)
        left = [p for p in left if alive(p)]
    return left


def suite_pids(out):
    """Return the node process ids of a suite run (``OUT/pids.json``; [] before the first)."""
    try:
        return sorted(json.loads((Path(out) / 'pids.json').read_text()).values())
    except (OSError, ValueError):
        return []


def end_suite(proc, out=None, sig=signal.SIGKILL, guard_s=60.0):
    """
    Stop a launcher and make sure its nodes are gone; return the nodes that outlived it.

    The launcher's group gets ``sig`` (SIGKILL: nothing of it runs on); its nodes end by their
    parent-death signal and the launcher's reaper. Nodes still running after ``guard_s`` [s]
    are returned (a defect) and SIGKILLed with their groups, so nothing outlives the test.
    """
    stop_group(proc, sig)
    pids = suite_pids(out) if out is not None else []
    left = wait_gone(pids, guard_s)
    for pid in left:
        _signal_group(pid, signal.SIGKILL)
    wait_gone(left, 10.0)
    return left
