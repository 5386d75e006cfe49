"""
Soak benchmark: the whole suite for an hour (or ``--duration``), memory per process over time.

    .venv/bin/python bench/bench_soak.py [--duration 3600] [--warmup 120] [--out runs/soak]

Runs ``mr-damper-suite`` (the main job: virtual rig -> identifier -> quarter car,
sim config, real time) and samples, every ``--sample-s`` seconds with psutil, the resident
memory (RSS) of the launcher and of each of its child processes: ``mr-damper-record`` (which
records every topic into ``suite.mcap``), ``rig_node``, ``identifier_node`` and its fit process,
``quarter_car_node``. It keeps sampling
while the launcher writes the summary (the report phase). Printed:

- per process: RSS at the start (first sample after ``--warmup``) and at the end of the node
  run, and the least-squares slope [MB/s] over that span, against the target of at most
  0.01 MB/s;
- the launcher's RSS peak while it writes the summary and plots from the streamed files;
- messages lost (summary.json, target 0) and the fail-safe after start-up: control steps in
  fail-safe after the first step in normal mode (from the quarter car's streamed log, target 0);
- the figures measured before the logs were streamed (issue 8, a 10-minute run on this
  machine: quarter car +0.19 MB/s, launcher +0.32 MB/s, launcher 858 MB while writing the
  summary) next to the new ones.

Sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (and the launcher picks a domain of its own);
runs inside a private network namespace when ``unshare -n`` is permitted.
"""
import argparse
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time

import numpy as np
import psutil

from mr_damper_model.io.columnlog import ColumnReader

REPO = Path(__file__).resolve().parents[1]

TARGET_MB_S = 0.01
BEFORE = {'quarter_car_node': 0.19, 'launcher': 0.32}
NETNS = ('unshare', '-n', 'sh', '-c', 'ip link set lo up && ip link set lo multicast on && '
         'ip route add 224.0.0.0/4 dev lo && exec "$@"', 'netns')


def classify(proc):
    """Return a short name for a process of the suite (None: not one of ours)."""
    try:
        cmd = ' '.join(proc.cmdline())
    except psutil.Error:
        return None
    if 'mr_damper_model.live' in cmd:
        return 'identifier_fit_process'
    for name in ('rig_node', 'identifier_node', 'quarter_car_node', 'mr-damper-record'):
        if name in cmd:
            return name
    if 'mr-damper-suite' in cmd:
        return 'launcher'
    return None


def sample(root):
    """Return {name: rss_mb} of the launcher and its descendants."""
    out = {}
    try:
        procs = [root] + root.children(recursive=True)
    except psutil.Error:
        return out
    for p in procs:
        name = classify(p)
        if name is None:
            continue
        try:
            rss = p.memory_info().rss / 2 ** 20
        except psutil.Error:
            continue
        out[name] = out.get(name, 0.0) + rss
    return out


def netns_ok():
    """Return True when a private network namespace can be made here."""
    if shutil.which('unshare') is None:
        return False
    return subprocess.call([*NETNS, 'true'], stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL) == 0


def failsafe_after_startup(out):
    """Return (steps, seconds) in fail-safe after the first normal step, from the car's log."""
    log = ColumnReader(Path(out) / 'quarter_car_log')
    started, steps = False, 0
    for c in log.chunks(65536, ('mode',)):
        normal = c['mode'] > 0.5
        if not started:
            if not normal.any():
                continue
            normal = normal[int(np.argmax(normal)):]
            started = True
        steps += int(np.count_nonzero(~normal))
    return steps, steps * float(log.meta.get('dt', 1e-3)), started


def slope(t, y):
    """Least-squares slope of y against t (nan with fewer than 3 points)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if t.size < 3:
        return float('nan')
    return float(np.polyfit(t, y, 1)[0])


def main(argv=None):
    """Run the soak, print the figures; return 0 when every target is met, else 1."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--duration', type=float, default=3600.0, help='node run [s] (default 1 h)')
    p.add_argument('--warmup', type=float, default=120.0,
                   help='seconds excluded from the slope fit (start-up, first fits)')
    p.add_argument('--sample-s', type=float, default=5.0, help='RSS sampling period [s]')
    p.add_argument('--out', default=str(REPO / 'runs' / 'soak'))
    p.add_argument('--domain-id', type=int, default=None)
    args = p.parse_args(argv)
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    cmd = [str(Path(sys.executable).parent / 'mr-damper-suite'), '--duration',
           str(args.duration), '--out', args.out, '--progress-s', '300']
    if args.domain_id is not None:
        cmd += ['--domain-id', str(args.domain_id)]
    if netns_ok():
        cmd = [*NETNS, *cmd]
    print('bench_soak:', ' '.join(cmd), flush=True)
    print(f'bench_soak: machine load at start {os.getloadavg()}, {os.cpu_count()} CPUs',
          flush=True)
    t_start = time.monotonic()
    proc = subprocess.Popen(cmd, env=env)
    root = psutil.Process(proc.pid)
    times, rows = [], []
    report_peak = 0.0
    nodes_seen = False
    while proc.poll() is None:
        now = time.monotonic() - t_start
        s = sample(root)
        nodes = {k: v for k, v in s.items() if k != 'launcher'}
        if nodes:
            nodes_seen = True
            times.append(now)
            rows.append(s)
        elif nodes_seen and 'launcher' in s:
            report_peak = max(report_peak, s['launcher'])      # nodes gone: the report
        time.sleep(args.sample_s if nodes or not nodes_seen else 0.5)
    rc = proc.returncode
    load_end = os.getloadavg()
    t = np.asarray(times)
    names = sorted({k for r in rows for k in r})
    print(f'\nSoak: {args.duration:.0f} s of the main job (sim rig 2 kHz -> identifier -> quarter '
          f'car 1 kHz), RSS every {args.sample_s:g} s, slope fitted after {args.warmup:g} s; '
          f'load at end {load_end[0]:.2f}/{load_end[1]:.2f}/{load_end[2]:.2f}')
    print(f'{"process":24s} {"RSS start MB":>12s} {"RSS end MB":>11s} {"slope MB/s":>11s} '
          f'{"before MB/s":>11s}  target <= {TARGET_MB_S} MB/s')
    ok = rc == 0
    for name in names:
        sel = [(ti, r[name]) for ti, r in zip(t, rows) if name in r and ti >= args.warmup]
        if not sel:
            continue
        ts, ys = zip(*sel)
        sl = slope(ts, ys)
        good = sl <= TARGET_MB_S
        ok &= bool(good)
        before = BEFORE.get(name)
        print(f'{name:24s} {ys[0]:12.1f} {ys[-1]:11.1f} {sl:11.5f} '
              f'{"" if before is None else f"{before:.2f}":>11s}  {"ok" if good else "OVER"}')
    print(f'launcher RSS peak while writing the summary: {report_peak:.0f} MB '
          f'(before: 858 MB after 10 minutes)')
    try:
        summ = json.loads((Path(args.out) / 'summary.json').read_text())
        lost = summ.get('messages_lost')
        steps, secs, started = failsafe_after_startup(args.out)
        print(f'messages lost: {lost} (target 0); received by the identifier: '
              f'{(summ.get("messages") or {}).get("measurements_received_by_identifier")}')
        print(f'fail-safe after start-up: {steps} steps, {secs:.3f} s (target 0); '
              f'left fail-safe: {started}; parameter sets refused: '
              f'{(summ.get("failsafe") or {}).get("params_rejected")}')
        ok &= lost == 0 and steps == 0 and started
    except (OSError, ValueError) as exc:
        print(f'bench_soak: no summary: {exc}')
        ok = False
    print(f'launcher exit status {rc}; all targets met: {ok}')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
