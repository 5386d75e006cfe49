"""
The launcher keeps its nodes alive and takes them with it (issue 32, sections 1, 2 and 5).

Real ``mr-damper-suite`` runs (sim config, until stopped) on real topics:

- a node frozen with SIGSTOP (its spin thread, and every other thread, blocked: no status on
  ``/diagnostics``) is SIGKILLed and restarted with the reason ``hung``; the other nodes run on
  untouched (same processes, exit 0 at the stop);
- every DDS socket of every process of the suite is bound to 127.0.0.1 (the shipped Fast DDS
  loopback profile);
- a second launcher on the same ROS domain is refused (exit 2) and touches nothing;
- SIGKILL of the launcher takes every node with it, one frozen node included (SIGTERM from the
  kernel, SIGKILL from the reaper), and frees the domain.

Order of events and counts only; every wait is a hang guard.
"""
import json
import os
import re
import signal

import psutil
import pytest

from conftest import VENV_BIN
from integration.ros_helpers import SuiteRun
from mr_damper_bringup.config import IDENT, QC, RECORDER, RIG
from mr_damper_bringup.processes import DomainLock
from mr_damper_bringup.supervisor import HANG_IDLE_SHARE, HANG_TIMEOUT_S
from process_helpers import run, wait_gone

pytestmark = [pytest.mark.integration, pytest.mark.slow]

PROGRESS = r'^\[ *\d+\.\d s\] recorded [1-9]'


def t_sim(line):
    """Return the car's simulated time [s] of a progress line."""
    return float(re.search(r't_sim (-?\d+\.\d+) s', line).group(1))


def inet_sockets(pids):
    """Return ``{pid: [local address, ...]}`` of the IPv4 / IPv6 sockets of the processes."""
    out = {}
    for pid in pids:
        try:
            out[pid] = [c.laddr.ip for c in psutil.Process(pid).net_connections(kind='inet')]
        except psutil.NoSuchProcess:
            continue
    return out


def test_a_frozen_node_is_killed_and_restarted_as_hung_while_the_others_run(tmp_path):
    out = tmp_path / 'hung'
    with SuiteRun(out, '--restart-backoff-s', '0.2') as suite:
        suite.wait_for(PROGRESS)                     # the stream is being recorded
        suite.wait_for(r't_sim')                     # the car sends its status
        before = suite.pids()
        # DDS on loopback: every socket of the launcher and of every node on 127.0.0.1
        socks = inet_sockets([suite.proc.pid, *before.values()])
        assert set(socks) == {suite.proc.pid, *before.values()}
        assert all(socks.values()), socks                           # each one has sockets
        assert {ip for ips in socks.values() for ip in ips} == {'127.0.0.1'}, socks
        t_before = 0.0
        while t_before < 3.0:                        # a few s of the car's time: a new car's
            t_before = t_sim(suite.wait_for(r't_sim'))      # statuses start below it
        os.kill(before[QC], signal.SIGSTOP)          # the car freezes, as in the middleware
        suite.wait_for(f'{QC} hung: no status for')
        suite.wait_for(f'restarted {QC}')
        while not t_sim(suite.wait_for(r't_sim')) < t_before:
            pass                                     # the new car's status: its time anew
        rc = suite.stop()
    assert suite.left == [], 'nodes outlived the launcher'
    text = suite.text()
    assert rc == 0, text[-4000:]
    assert 'died (exit' not in text, text[-4000:]
    after = json.loads((out / 'pids.json').read_text())
    assert after[QC] != before[QC]
    assert {n: p for n, p in after.items() if n != QC} == \
        {n: p for n, p in before.items() if n != QC}            # the others never restarted
    sup = json.loads((out / 'restarts.json').read_text())
    assert [(r['node'], r['reason'], r['signal']) for r in sup['restarts']] == \
        [(QC, 'hung', 'SIGKILL')]
    assert sup['restarts'][0]['silent_s'] > HANG_TIMEOUT_S
    assert sup['restarts'][0]['cpu_share'] < HANG_IDLE_SHARE          # stopped: idle
    assert sup['restarts'][0]['spin_cpu_share'] < HANG_IDLE_SHARE     # and its spin thread
    assert sup['gave_up'] is None
    assert set(sup['exit_codes']) == {QC, RIG, IDENT, RECORDER}
    assert all(c == 0 for c in sup['exit_codes'].values()), sup['exit_codes']
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['restart_counts'] == {QC: 1}
    assert f'{QC} hung at' in text                  # the summary line of the restart


def test_a_killed_launcher_takes_every_node_with_it_and_frees_its_domain(tmp_path):
    out = tmp_path / 'killed'
    domain = os.environ['ROS_DOMAIN_ID']
    with SuiteRun(out) as suite:
        suite.wait_for(PROGRESS)
        pids = suite.pids()
        procs = list(pids.values())
        for pid in pids.values():                   # the identifier's fit process too
            procs += [c.pid for c in psutil.Process(pid).children(recursive=True)]
        # a second launcher on the same domain is refused before it writes anything
        second = tmp_path / 'second'
        got = run([str(VENV_BIN / 'mr-damper-suite'), '--domain-id', domain, '--duration', '5',
                   '--out', str(second), '--no-plots'], 120)
        assert got.returncode == 2, got.stdout + got.stderr
        assert f'ROS_DOMAIN_ID {domain} is in use by another mr-damper-suite' in got.stderr
        assert f'launcher pid {suite.proc.pid}' in got.stderr
        assert not (second / 'pids.json').exists()
        assert not DomainLock(domain).acquire()
        os.kill(pids[IDENT], signal.SIGSTOP)        # one node that cannot act on SIGTERM
        os.kill(suite.proc.pid, signal.SIGKILL)
        suite.proc.wait()
        assert wait_gone(procs, 120.0) == []        # hang guard; no orphan with ppid 1
    assert suite.left == []
    lock = DomainLock(domain)
    try:
        assert lock.acquire()                       # released with the last process
    finally:
        lock.release()
    # the stopped node was SIGKILLed by the reaper (on a loaded machine others may have been too:
    # their clean stop took longer than the grace)
    log = (out / 'logs' / 'reaper.log').read_text()
    killed = re.search(r'SIGKILL after [\d.]+ s to \[([\d, ]*)\]', log)
    assert killed and str(pids[IDENT]) in killed.group(1).split(', '), log
