"""
Stress: start node console scripts and send SIGTERM / SIGINT during start-up, count hangs.

Not a test and not timed: it counts outcomes. For each run one node's console script from
``.venv/bin`` is started (private ``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``,
``PYTHONFAULTHANDLER=1``), then signalled

* ``--when handlers`` (as ``tests/integration/test_node_signals.py``): as soon as
  ``/proc/PID/status`` shows the SIGTERM handler installed (polled every 2 ms), plus a random
  delay in ``[0, --delay-max]``;
* ``--when start``: a random delay in ``[0, --delay-max]`` after the process was started (a
  signal before the handlers exist kills the node by the default action: counted as
  ``early``, not as a failure).

A node that does not exit within ``--guard`` seconds is a hang: its native stacks are saved
with gdb (when installed), then SIGABRT makes faulthandler print every thread's Python stack
into the node's log, and the process group is killed. Logs of hangs and bad exits go to
``--out``. ``--burners N`` runs N ``python3 -c "while 1: pass"`` processes meanwhile (killed
by PID at the end). As root, ``--netns`` runs everything in a private network namespace with
only ``lo`` up (as tests/run_tests.sh does).

Usage::

    .venv/bin/python bench/stress_node_signals.py --runs 40 --burners 1 --netns
    .venv/bin/python bench/stress_node_signals.py --nodes rig_node --when start --delay-max 3
"""
import argparse
import collections
import os
from pathlib import Path
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / 'tests'), str(ROOT / 'tests' / 'integration')]
from test_node_signals import _catches  # noqa: E402 (the test's own /proc SigCgt check)

VENV_BIN = ROOT / '.venv' / 'bin'
NODES = {
    'rig_node': ['--ros-args', '-p', 'mode:=sim'],
    'identifier_node': [],
    'quarter_car_node': [],
    'semi_active_controller_node': [],
    'state_estimator_node': [],
    'can_bridge_node': [],
    'can_driver_sim': [],
    'mr-damper-record': ['--out', '{tmp}/run.mcap'],
}
NETNS = ('ip link set lo up && ip link set lo multicast on && '
         'ip route add 224.0.0.0/4 dev lo && exec "$@"')


def _phase(pid, log):
    """Where the node was when signalled: early (no handler), importing/starting, running."""
    if not _catches(pid, signal.SIGTERM):
        return 'early'
    text = log.read_text(errors='replace')
    return 'running' if '[INFO]' in text else 'starting'


def _dump_hang(proc, log, out, tag):
    """Save gdb's native stacks and faulthandler's Python stacks of a hung node."""
    out.mkdir(parents=True, exist_ok=True)
    if shutil.which('gdb'):
        with open(out / f'{tag}.gdb.txt', 'w') as fh:
            subprocess.run(['gdb', '-p', str(proc.pid), '-batch', '-ex',
                            'thread apply all bt'], stdout=fh, stderr=subprocess.STDOUT,
                           timeout=120)
    os.kill(proc.pid, signal.SIGABRT)   # PYTHONFAULTHANDLER=1: every thread's Python stack
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass


def _one(script, args, sig, when, delay_max, guard, rng, out, tag, env):
    """Start, signal and wait for one node; return (outcome, phase, exit code)."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        log = tmp / 'node.log'
        argv = [str(VENV_BIN / script)] + [a.replace('{tmp}', str(tmp)) for a in args]
        with open(log, 'w') as fh:
            proc = subprocess.Popen(argv, stdout=fh, stderr=subprocess.STDOUT,
                                    start_new_session=True, env=env)
        try:
            if when == 'handlers':
                end = time.monotonic() + guard
                while (not _catches(proc.pid, signal.SIGTERM) and proc.poll() is None
                       and time.monotonic() < end):
                    time.sleep(0.002)
            delay = rng.uniform(0.0, delay_max)
            if delay:
                time.sleep(delay)
            if proc.poll() is not None:
                outcome, phase = 'exited_before_signal', '-'
            else:
                phase = _phase(proc.pid, log)
                os.kill(proc.pid, sig)
                try:
                    rc = proc.wait(timeout=guard)
                    text = log.read_text(errors='replace')
                    if phase == 'early':
                        outcome = 'early'
                    elif rc == 0 and 'Traceback' not in text:
                        outcome = 'ok'
                    else:
                        outcome = 'bad_exit'
                except subprocess.TimeoutExpired:
                    outcome = 'hang'
                    _dump_hang(proc, log, out, tag)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        if outcome in ('hang', 'bad_exit', 'exited_before_signal'):
            out.mkdir(parents=True, exist_ok=True)
            shutil.copy(log, out / f'{tag}.log')
        return outcome, phase, proc.returncode


def main(argv=None):
    """Run the stress loop and print the counts."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--nodes', default=','.join(NODES),
                    help='comma-separated console scripts (default: all)')
    ap.add_argument('--runs', type=int, default=20, help='runs per node')
    ap.add_argument('--signal', choices=('SIGTERM', 'SIGINT', 'both'), default='SIGTERM')
    ap.add_argument('--when', choices=('handlers', 'start'), default='handlers')
    ap.add_argument('--delay-max', type=float, default=0.0,
                    help='random extra delay before the signal [s]')
    ap.add_argument('--guard', type=float, default=30.0, help='hang guard [s]')
    ap.add_argument('--burners', type=int, default=1, help='CPU burner processes')
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--out', default='/tmp/stress_node_signals', help='logs of failures')
    ap.add_argument('--netns', action='store_true',
                    help='re-run inside a private network namespace (root)')
    args = ap.parse_args(argv)
    if args.netns and not os.environ.get('STRESS_IN_NETNS'):
        os.environ['STRESS_IN_NETNS'] = '1'
        cmd = [sys.executable, __file__] + [a for a in (argv or sys.argv[1:])]
        os.execvp('unshare', ['unshare', '-n', 'sh', '-c', NETNS, 'netns', *cmd])
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONFAULTHANDLER='1',
               ROS_LOG_DIR=tempfile.mkdtemp(prefix='stress_ros_log_'))
    env.setdefault('ROS_DOMAIN_ID', str(random.Random().randrange(20, 220)))
    rng = random.Random(args.seed)
    nodes = [n for n in args.nodes.split(',') if n]
    sigs = {'SIGTERM': [signal.SIGTERM], 'SIGINT': [signal.SIGINT],
            'both': [signal.SIGTERM, signal.SIGINT]}[args.signal]
    out = Path(args.out)
    burners = [subprocess.Popen([sys.executable, '-c', 'while 1: pass'])
               for _ in range(args.burners)]
    counts = collections.defaultdict(collections.Counter)
    phases = collections.defaultdict(collections.Counter)
    load0 = os.getloadavg()
    t0 = time.monotonic()
    try:
        for run in range(args.runs):
            for script in nodes:
                sig = sigs[run % len(sigs)]
                tag = f'{script}-{sig.name}-{run}'
                outcome, phase, rc = _one(script, NODES[script], sig, args.when,
                                          args.delay_max, args.guard, rng, out, tag, env)
                counts[script][outcome] += 1
                phases[script][phase] += 1
                if outcome != 'ok':
                    print(f'run {run} {script} {sig.name}: {outcome} (phase {phase}, '
                          f'rc {rc})', flush=True)
    finally:
        for b in burners:
            b.kill()
            b.wait()
    load1 = os.getloadavg()
    print(f'\n{args.runs} runs per node, signal {args.signal}, when {args.when} + '
          f'U(0, {args.delay_max:g}) s, burners {args.burners}, guard {args.guard:g} s, '
          f'netns {bool(os.environ.get("STRESS_IN_NETNS"))}, '
          f'{time.monotonic() - t0:.0f} s wall')
    print(f'load average (1/5/15 min) before {load0[0]:.2f}/{load0[1]:.2f}/{load0[2]:.2f}, '
          f'after {load1[0]:.2f}/{load1[1]:.2f}/{load1[2]:.2f}; {os.cpu_count()} cores')
    print(f'{"node":30s} {"ok":>4s} {"hang":>5s} {"bad":>4s} {"early":>6s} {"gone":>5s}  phases')
    for script in nodes:
        c = counts[script]
        print(f'{script:30s} {c["ok"]:4d} {c["hang"]:5d} {c["bad_exit"]:4d} {c["early"]:6d} '
              f'{c["exited_before_signal"]:5d}  {dict(phases[script])}')
    return 1 if any(c['hang'] for c in counts.values()) else 0


if __name__ == '__main__':
    sys.exit(main())
