"""
Tests of the node processes' lifetime (no ROS): parent-death signal, reaper, domain lock.

Real processes (``sleep``, small Python children); every wait polls ``/proc`` with a hang guard.
"""
import os
import signal
import subprocess
import sys
import textwrap

import pytest

from mr_damper_bringup.config import RIG, SuiteError
from mr_damper_bringup.launcher import take_domain
from mr_damper_bringup.processes import die_with_parent, DomainLock, is_rig, Reaper
from mr_damper_bringup.reaper import proc_stat, running
from process_helpers import alive, popen, stop_group, wait_gone

GUARD_S = 60.0

# a parent that starts ``sleep`` with die_with_parent, prints its pid and waits to be killed
_PARENT = textwrap.dedent('''
    import subprocess, sys, time
    from mr_damper_bringup.processes import die_with_parent
    child = subprocess.Popen(['sleep', '600'], start_new_session=True,
                             preexec_fn=die_with_parent())
    print(child.pid, flush=True)
    time.sleep(600)
''')


def test_a_child_dies_with_its_parent():
    """SIGKILL of the parent: the kernel sends the child SIGTERM (no orphan with ppid 1)."""
    parent = popen([sys.executable, '-c', _PARENT], stdout=subprocess.PIPE, text=True)
    child = None
    try:
        child = int(parent.stdout.readline())
        assert alive(child) and os.getpgid(child) == child      # its own session and group
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        assert wait_gone([child], GUARD_S) == []
    finally:
        stop_group(parent, signal.SIGKILL)
        if child is not None and alive(child):
            os.kill(child, signal.SIGKILL)


def test_a_child_whose_parent_died_before_the_prctl_kills_itself():
    """The race: the parent is gone when the child runs the preexec function."""
    child_fn = die_with_parent()            # made here: its parent is this process
    pid = os.fork()
    if pid == 0:                            # a middle process; its own child runs child_fn
        code = 1
        try:
            grandchild = os.fork()
            if grandchild == 0:
                child_fn()                  # getppid() is the middle process: kill itself
                os._exit(0)
            _, status = os.waitpid(grandchild, 0)
            code = 0 if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL else 1
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0


def _stubborn():
    """Start a node that ignores SIGTERM (as one frozen in the middleware), in its own group."""
    code = 'import signal, time\nsignal.signal(signal.SIGTERM, signal.SIG_IGN)\nprint(1, ' \
           'flush=True)\ntime.sleep(600)\n'
    proc = subprocess.Popen([sys.executable, '-c', code], stdout=subprocess.PIPE, text=True,
                            start_new_session=True)
    assert proc.stdout.readline().strip() == '1'          # its handler is in
    return proc


@pytest.mark.slow
def test_the_reaper_ends_the_nodes_of_a_launcher_that_is_gone(tmp_path):
    reaper = Reaper(tmp_path / 'reaper.log', grace_s=1.0)
    nodes = [subprocess.Popen(['sleep', '600'], start_new_session=True), _stubborn()]
    try:
        for p in nodes:
            reaper.watch(p.pid)
        reaper.close()                  # EOF, as when the launcher dies
        for p in nodes:
            p.wait(timeout=GUARD_S)
        assert reaper.proc.returncode == 0
        assert nodes[0].returncode == -signal.SIGTERM           # stopped cleanly
        assert nodes[1].returncode == -signal.SIGKILL           # after the grace
        log = (tmp_path / 'reaper.log').read_text()
        assert f'SIGKILL after 1 s to [{nodes[1].pid}]' in log, log
    finally:
        for p in nodes:
            stop_group(p, signal.SIGKILL)


def test_the_reaper_signals_nothing_after_a_clean_stop(tmp_path):
    reaper = Reaper(tmp_path / 'reaper.log', grace_s=1.0)
    node = subprocess.Popen(['sleep', '600'], start_new_session=True)
    reaper.watch(node.pid)
    node.terminate()
    node.wait()
    reaper.close()
    assert reaper.proc.returncode == 0 and (tmp_path / 'reaper.log').read_text() == ''


def test_a_reused_process_id_is_not_the_same_process():
    st = proc_stat(os.getpid())
    assert st is not None and running(os.getpid(), st[1])
    assert not running(os.getpid(), st[1] + 1)          # another start time: another process
    assert proc_stat(2 ** 22 + 12345) is None


def test_one_suite_per_domain_until_every_process_of_it_has_gone(tmp_path):
    first = DomainLock(42, tmp_path)
    assert first.acquire() and first.holder() == str(os.getpid())
    assert not DomainLock(42, tmp_path).acquire()           # a second launcher: refused
    assert DomainLock(43, tmp_path).acquire()               # another domain: free
    # a node that inherited the lock keeps it after its launcher let go
    node = subprocess.Popen(['sleep', '600'], pass_fds=(first.fd,), start_new_session=True)
    try:
        first.release()
        assert not DomainLock(42, tmp_path).acquire()
    finally:
        stop_group(node, signal.SIGKILL)
    assert DomainLock(42, tmp_path).acquire()


def test_take_domain_refuses_a_requested_domain_in_use_and_draws_a_free_one(tmp_path):
    held = DomainLock(100, tmp_path)
    assert held.acquire()
    with pytest.raises(SuiteError, match='ROS_DOMAIN_ID 100 is in use'):
        take_domain(100, tmp_path)
    domain, lock = take_domain(None, tmp_path)
    assert domain != 100 and lock.fd is not None
    assert not DomainLock(domain, tmp_path).acquire()


class _SlowRig:
    """A node process that exits only when waited for after its SIGINT (a loaded rig)."""

    def __init__(self, name, events):
        self.name, self.events, self.returncode = name, events, None

    def poll(self):
        return self.returncode

    def send_signal(self, sig):
        self.events.append(('signal', self.name, sig))

    def wait(self, timeout=None):
        self.returncode = 0
        self.events.append(('exited', self.name))
        return 0


def test_the_drain_starts_once_every_rig_has_exited_and_identifiers_stop_after_it(tmp_path):
    # corners fl and fr: the rigs get SIGINT in order, and the drain (whose first look records
    # which rigs had exited) comes only after both exited; the identifiers after the drain
    from mr_damper_bringup.processes import Suite
    events = []
    order = ['fl.mr_damper_rig', 'fr.mr_damper_rig', 'fl.mr_damper_identifier',
             'fr.mr_damper_identifier']
    suite = Suite(tmp_path / 'p.yaml', tmp_path, 0, nodes={n: 'x' for n in order}, dds={})
    for n in order:
        suite.procs[n] = _SlowRig(n, events)
        suite.logs[n] = open(tmp_path / f'{n}.log', 'w')

    def drained():
        events.append(('drain',))
        return True, None
    codes = suite.stop(order=order, last=(), then=(), drain_s=0.001, drained=drained)
    assert codes == {n: 0 for n in order}
    names = [e[:2] for e in events]
    assert names[:5] == [('signal', 'fl.mr_damper_rig'), ('signal', 'fr.mr_damper_rig'),
                         ('exited', 'fl.mr_damper_rig'), ('exited', 'fr.mr_damper_rig'),
                         ('drain',)]
    assert names[5:] == [('signal', 'fl.mr_damper_identifier'),
                         ('signal', 'fr.mr_damper_identifier'),
                         ('exited', 'fl.mr_damper_identifier'),
                         ('exited', 'fr.mr_damper_identifier')]
    assert all(e[2] == signal.SIGINT for e in events if e[0] == 'signal')


def test_is_rig_takes_the_rig_and_a_corner_s_rig_not_a_name_that_contains_it():
    assert is_rig(RIG) and is_rig(f'fl.{RIG}')
    not_rigs = (f'{RIG}_monitor', f'fl.{RIG}_x', f'fl.x{RIG}', f'{RIG}.identifier')
    assert not any(is_rig(n) for n in not_rigs)
