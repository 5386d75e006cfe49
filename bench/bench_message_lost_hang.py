"""
Stress: a flooded depth-1 reader with and without MESSAGE_LOST armed; count the frozen runs.

The scenario of ``tests/integration/flood_take.py`` (issue 32, section 1).

Not a test and not timed: it counts outcomes. Each run is one ``flood_take.py take`` process
(its own ``ROS_DOMAIN_ID``, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) with its writer in
its process group; a run that has not ended after ``--guard`` seconds is hung: with gdb
installed its native stacks are read first, and a hang whose stacks hold both sides of the
inversion of ros2/rmw_fastrtps#890 (``get_sample_lost_status`` under ``take_event``, and
``update_sample_lost`` under ``on_sample_lost``) is counted as ``inversion``; then the group is
killed. Modes: ``armed`` (the suite before the fix: the event armed on the subscription),
``counted`` (the suite now: ``DropCounter.subscribe``, losses from the sequence numbers).

Usage::

    .venv/bin/python bench/bench_message_lost_hang.py --runs 10
    .venv/bin/python bench/bench_message_lost_hang.py --runs 20 --modes armed
"""
import argparse
import os
from pathlib import Path
import random
import shutil
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / 'tests'), str(ROOT / 'tests' / 'integration')]
from flood_take import run_take  # noqa: E402 (the test's own scenario and runner)

MODES = {'armed': ['--arm-message-lost'], 'counted': []}
RELIABILITY = {'best_effort': [], 'reliable': ['--reliable']}


def _stacks(pid):
    """Return the native stacks of every thread of ``pid`` (gdb), or '' without gdb."""
    if shutil.which('gdb') is None:
        return ''
    try:
        return subprocess.run(['gdb', '-p', str(pid), '-batch', '-ex', 'thread apply all bt 40'],
                              capture_output=True, text=True, timeout=120).stdout
    except subprocess.TimeoutExpired:
        return ''


def main():
    """Run the stress and print the counts per mode and reliability."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--runs', type=int, default=10, help='runs per mode and reliability')
    parser.add_argument('--iterations', type=int, default=1000,
                        help='take-loop iterations of a run (as the test)')
    parser.add_argument('--guard', type=float, default=120.0, help='hang guard of a run [s]')
    parser.add_argument('--modes', nargs='+', default=list(MODES), choices=list(MODES))
    parser.add_argument('--reliability', nargs='+', default=list(RELIABILITY),
                        choices=list(RELIABILITY))
    args = parser.parse_args()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    domains = random.Random(os.getpid()).sample(range(20, 220), 200)
    print(f'{os.uname().nodename}, load {os.getloadavg()[0]:.1f} at start; '
          f'{args.runs} runs each, {args.iterations} iterations, guard {args.guard:g} s')
    print(f'{"mode":8s} {"reliability":12s} {"runs":>5s} {"hung":>5s} {"inversion":>9s} '
          f'{"failed":>6s}')
    k = 0
    for mode in args.modes:
        for rel in args.reliability:
            hung = inversion = failed = 0
            for _ in range(args.runs):
                os.environ['ROS_DOMAIN_ID'] = str(domains[k % len(domains)])
                k += 1
                stacks = []
                run = run_take(args.iterations, *MODES[mode], *RELIABILITY[rel],
                               guard_s=args.guard, on_hang=lambda pid: stacks.append(_stacks(pid)))
                if run.hung:
                    hung += 1
                    text = ''.join(stacks)
                    inversion += ('get_sample_lost_status' in text
                                  and 'update_sample_lost' in text)
                elif run.returncode != 0 or not run.counts('done'):
                    failed += 1
            print(f'{mode:8s} {rel:12s} {args.runs:5d} {hung:5d} {inversion:9d} {failed:6d}',
                  flush=True)
    print(f'load {os.getloadavg()[0]:.1f} at the end')


if __name__ == '__main__':
    main()
