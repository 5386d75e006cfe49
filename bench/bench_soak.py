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
  0.01 MB/s (a restarted node is a new process: each life is fitted apart, the longest one is
  printed with the number of lives);
- how far the recorder was behind the stream (receive time less stamp of its own status,
  p50 / p99 / max) and the restarts (reason, silence, CPU share): a recorder that falls behind
  on a loaded machine holds its backlog in its DDS queues, whose memory keeps its high-water
  mark;
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

from mr_damper_common.recording.columnlog import ColumnReader

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
    """Return {(name, pid): rss_mb} of the launcher and its descendants (one key per life)."""
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
            out[(name, p.pid)] = p.memory_info().rss / 2 ** 20
        except psutil.Error:
            continue
    return out


def life_slopes(times, rows, warmup):
    """
    Return {name: (slope MB/s, start MB, end MB, span s, lives)} of each process kind.

    A restarted node is a new process (a new pid, memory from its start): the slope is fitted
    over each life after ``warmup`` [s] and the longest life's is reported, with the number of
    lives (a sum over lives would read a restart as a drop).
    """
    series = {}
    for t, row in zip(times, rows):
        for key, rss in row.items():
            series.setdefault(key, []).append((t, rss))
    out = {}
    for (name, _), pts in series.items():
        lives = sum(1 for key in series if key[0] == name)
        pts = [(t, y) for t, y in pts if t >= warmup]
        if len(pts) < 3:
            continue
        ts, ys = zip(*pts)
        span = ts[-1] - ts[0]
        if name not in out or span > out[name][3]:
            out[name] = (slope(ts, ys), ys[0], ys[-1], span, lives)
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


def recorder_lag(out):
    """
    Return (p50, p99, max) [s] of how far the recorder was behind, or None without a recording.

    Its own status is stamped when its timer fires and logged when its subscription takes it
    back: the difference is the backlog it was working through.
    """
    from mr_damper_bringup.recorder import recording_parts
    from mr_damper_model.io.bag_types import suite_typestore
    from mr_damper_common.recording.mcap_scan import McapScan
    ts = suite_typestore()
    lags = []
    for _, part in recording_parts(Path(out) / 'suite.mcap'):
        scan = McapScan(part)
        for _, msgtype, t_ns, raw in scan.messages({'/diagnostics'}):
            msg = scan.deserialize(raw, msgtype, ts)
            if any(st.name == 'mr_damper_record' for st in msg.status):
                stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
                lags.append(t_ns * 1e-9 - stamp)
    if not lags:
        return None
    return tuple(float(v) for v in np.percentile(lags, [50, 99, 100]))


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
        nodes = {k: v for k, v in s.items() if k[0] != 'launcher'}
        launcher = [v for k, v in s.items() if k[0] == 'launcher']
        if nodes:
            nodes_seen = True
            times.append(now)
            rows.append(s)
        elif nodes_seen and launcher:
            report_peak = max(report_peak, max(launcher))     # nodes gone: the report
        time.sleep(args.sample_s if nodes or not nodes_seen else 0.5)
    rc = proc.returncode
    load_end = os.getloadavg()
    t = np.asarray(times)
    print(f'\nSoak: {args.duration:.0f} s of the main job (sim rig 2 kHz -> identifier -> quarter '
          f'car 1 kHz), RSS every {args.sample_s:g} s, slope fitted after {args.warmup:g} s '
          f'over the longest life of each process; load at end '
          f'{load_end[0]:.2f}/{load_end[1]:.2f}/{load_end[2]:.2f}')
    print(f'{"process":24s} {"RSS start MB":>12s} {"RSS end MB":>11s} {"slope MB/s":>11s} '
          f'{"span s":>7s} {"lives":>5s} {"before MB/s":>11s}  target <= {TARGET_MB_S} MB/s')
    ok = rc == 0
    for name, (sl, y0, y1, span, lives) in sorted(life_slopes(t, rows, args.warmup).items()):
        good = sl <= TARGET_MB_S
        ok &= bool(good)
        before = BEFORE.get(name)
        print(f'{name:24s} {y0:12.1f} {y1:11.1f} {sl:11.5f} {span:7.0f} {lives:5d} '
              f'{"" if before is None else f"{before:.2f}":>11s}  {"ok" if good else "OVER"}')
    behind = recorder_lag(args.out)
    if behind is not None:
        print(f'recorder behind the stream (receive time - stamp of its own status): '
              f'p50 {behind[0]:.2f} s, p99 {behind[1]:.2f} s, max {behind[2]:.2f} s')
    try:
        sup = json.loads((Path(args.out) / 'restarts.json').read_text())
        print('restarts: ' + (', '.join(
            f'{r["node"]} ({r.get("reason")}, silent {r.get("silent_s", 0):.1f} s, CPU '
            f'{100 * (r.get("cpu_share") or 0):.1f} %)' for r in sup['restarts']) or 'none'))
    except (OSError, ValueError, KeyError):
        pass
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
