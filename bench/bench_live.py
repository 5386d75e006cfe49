"""
Benchmark: the simulated rig at 1 kHz in real time into the identifier node, over ROS 2.

Starts ``rig_node`` (sim, Spencer truth, thesis cam, current steps 0..2 A, real time) and
``identifier_node`` (default parameters) as separate processes on LOCALHOST discovery and a
private domain, runs for ``--duration`` seconds and prints:

- measurements lost (rig published - identifier received; target 0),
- stamp -> identifier receipt latency p50 / p99 (target p99 <= 5 ms; the rig stamps with the
  wall clock in real-time mode),
- parameter update rate (target >= 5 Hz) and the share of valid updates,
- compute time per window (mean / max),
- CPU (share of one core) and peak memory (VmHWM) per node, child processes included (the
  identifier's fit process) (target: rig + identifier < 1 core).

Usage::

    .venv/bin/python bench/bench_live.py --duration 60
"""
import argparse
import json
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import threading
import time


def _peak_rss_mb(pid):
    try:
        with open(f'/proc/{pid}/status') as fh:
            for line in fh:
                if line.startswith('VmHWM:'):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float('nan')


def _tree_cpu(proc):
    """CPU seconds of a process and its live children, per pid."""
    out = {}
    for p in [proc] + proc.children(recursive=True):
        try:
            out[p.pid] = sum(p.cpu_times()[:2])
        except Exception:   # noqa: BLE001 - a child may just have exited
            pass
    return out


def _tree_peak_mb(proc):
    return sum(_peak_rss_mb(p.pid) for p in [proc] + proc.children(recursive=True))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--duration', type=float, default=60.0, help='run time [s] (default 60)')
    ap.add_argument('--domain', type=int, default=None, help='ROS_DOMAIN_ID (default random)')
    ap.add_argument('--plant', default='spencer', help='spencer | kwok-current')
    ap.add_argument('--realtime-priority', type=int, default=0,
                    help='SCHED_FIFO priority of both nodes (0: normal; needs root)')
    ap.add_argument('--ident-param', action='append', default=[], metavar='NAME:=VALUE',
                    help='extra identifier parameter (repeatable), e.g. hop_s:=0.5')
    ap.add_argument('--json', action='store_true', help='print the figures as one JSON object')
    args = ap.parse_args(argv)

    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ['ROS_DOMAIN_ID'] = str(args.domain if args.domain is not None
                                      else random.randint(20, 220))
    import numpy as np
    import psutil
    import rclpy
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from diagnostic_msgs.msg import DiagnosticArray
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.messages import health_from_diagnostic, identified_set_from_msg

    bin_dir = Path(sys.executable).parent
    rclpy.init(args=[])   # not sys.argv: our own options are no ROS arguments
    node = rclpy.create_node('bench_live')
    latest = {}
    updates = []
    p99s = []   # stamp-age p99 of each status (each over the identifier's last 10 000 samples)

    def on_diagnostics(msg):
        for st in msg.status:
            if st.name == 'mr_damper_identifier':   # the identifier's status values
                latest['ident'] = health_from_diagnostic(st).values
                age = latest['ident'].get('stamp_age_ms')
                if age and age.get('n', 0) >= 10000:
                    p99s.append(age['p99'])
            elif st.name == 'mr_damper_rig':
                latest['rig'] = health_from_diagnostic(st).values

    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    node.create_subscription(
        KwokParameters, '/mr_damper/kwok_parameters',
        lambda m: updates.append((time.monotonic(), identified_set_from_msg(m).to_dict())),
        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.VOLATILE))
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            rclpy.spin_once(node, timeout_sec=0.05)

    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()

    logs = {name: open(f'/tmp/bench_live_{name}.log', 'w') for name in ('rig', 'ident')}
    rt = ['-p', f'realtime_priority:={args.realtime_priority}']
    # diagnostics at 5 Hz, as the JSON status was (the stamp-age p99 series keeps its density)
    extra = ['-p', 'diagnostics_period_s:=0.2']
    extra += [a for kv in args.ident_param for a in ('-p', kv)]
    ident = subprocess.Popen([str(bin_dir / 'identifier_node'), '--ros-args', *rt, *extra],
                             stdout=logs['ident'],
                             stderr=subprocess.STDOUT)
    rig = subprocess.Popen([str(bin_dir / 'rig_node'), '--ros-args', '-p', 'mode:=sim',
                            '-p', f'plant:={args.plant}', '-p', 'rate_factor:=1.0',
                            '-p', 'wait_for_subscribers:=1',
                            '-p', f'duration_s:={args.duration + 3.0!r}', *rt],
                           stdout=logs['rig'], stderr=subprocess.STDOUT)
    procs = {'rig_node': psutil.Process(rig.pid), 'identifier_node': psutil.Process(ident.pid)}
    # wait for the stream to start, then measure over the duration
    t_wait = time.monotonic()
    while latest.get('rig', {}).get('samples_published', 0) == 0:
        if time.monotonic() - t_wait > 60 or rig.poll() is not None:
            print('bench_live: the rig did not start', file=sys.stderr)
            break
        time.sleep(0.05)
    cpu0 = {k: _tree_cpu(p) for k, p in procs.items()}
    t0 = time.monotonic()
    n_updates0 = len(updates)
    next_print = t0 + 10.0
    while time.monotonic() - t0 < args.duration:
        time.sleep(0.2)
        if time.monotonic() >= next_print and not args.json:
            s = latest.get('ident', {})
            print(f'  t={time.monotonic() - t0:5.1f} s  received {s.get("samples_received")}  '
                  f'windows fitted {s.get("windows_fitted")}  valid {s.get("last_valid")}',
                  flush=True)
            next_print += 10.0
    wall = time.monotonic() - t0
    cpu = {}
    for k, p in procs.items():
        now = _tree_cpu(p)
        cpu[k] = sum(v - cpu0[k].get(pid, 0.0) for pid, v in now.items()) / wall
    peak = {k: _tree_peak_mb(p) for k, p in procs.items()}
    in_run = [u for u in updates[n_updates0:] if u[0] <= t0 + wall]
    n_updates = len(in_run)
    # the rig ends by itself (duration_s) with a final status; the identifier then drains
    rig.wait(timeout=60)
    end = time.monotonic() + 20.0
    while time.monotonic() < end and (
            latest.get('ident', {}).get('samples_received', 0)
            < latest.get('rig', {}).get('samples_published', 0)):
        time.sleep(0.1)
    time.sleep(0.5)
    s, r = latest.get('ident', {}), latest.get('rig', {})
    ident.send_signal(signal.SIGINT)
    ident.wait(timeout=15)
    stop.set()
    spinner.join(timeout=5)
    node.destroy_node()
    rclpy.try_shutdown()
    valid = sum(1 for _, u in in_run if u['valid'])
    ages = s.get('stamp_age_ms') or {}
    figures = {
        'duration_s': wall,
        'samples_published': r.get('samples_published'),
        'samples_received': s.get('samples_received'),
        'measurements_lost': (r.get('samples_published', 0) or 0)
        - (s.get('samples_received', 0) or 0),
        'effective_rate_hz': r.get('effective_rate_hz'),
        'latency_ms_p50': ages.get('p50'), 'latency_ms_p99': ages.get('p99'),
        'latency_ms_max': ages.get('max'),
        'latency_ms_p99_10s_median': float(np.median(p99s)) if p99s else None,
        'latency_ms_p99_10s_worst': float(np.max(p99s)) if p99s else None,
        'parameter_updates_hz': (n_updates - 1) / (in_run[-1][0] - in_run[0][0])
        if n_updates > 1 else 0.0, 'valid_fraction': valid / max(n_updates, 1),
        'windows_fitted': s.get('windows_fitted'),
        'windows_superseded': s.get('windows_superseded'),
        'compute_s_mean': s.get('compute_s_mean'), 'compute_s_max': s.get('compute_s_max'),
        'last_nrmse_percent': s.get('last_nrmse_percent'),
        'cpu_cores': cpu, 'cpu_cores_total': sum(cpu.values()), 'peak_rss_mb': peak,
    }
    if args.json:
        print(json.dumps(figures, indent=2))
        return 0

    def fmt(v, spec='.2f'):
        return 'n/a' if v is None else format(v, spec)

    print(f'rig -> identifier, {wall:.1f} s at 1 kHz real time ({args.plant} truth, '
          f'realtime priority {args.realtime_priority}: rig {r.get("realtime")}, '
          f'identifier {s.get("realtime")})')
    print(f'  measurements lost       {figures["measurements_lost"]} of '
          f'{figures["samples_published"]} (target 0); rig rate '
          f'{fmt(figures["effective_rate_hz"], ".1f")} Hz')
    print(f'  latency stamp->receipt  p50 {fmt(figures["latency_ms_p50"])} ms, '
          f'p99 {fmt(figures["latency_ms_p99"])} ms, max {fmt(figures["latency_ms_max"])} ms '
          '(target p99 <= 5 ms; last 10 s)')
    print(f'  p99 over 10-s spans     median {fmt(figures["latency_ms_p99_10s_median"])} ms, '
          f'worst {fmt(figures["latency_ms_p99_10s_worst"])} ms')
    print(f'  parameter updates       {figures["parameter_updates_hz"]:.2f} Hz (target >= 5), '
          f'{100 * figures["valid_fraction"]:.0f} % valid; windows superseded '
          f'{figures["windows_superseded"]}')
    print(f'  compute per window      mean {fmt(figures["compute_s_mean"], ".3f")} s, '
          f'max {fmt(figures["compute_s_max"], ".3f")} s; last NRMSE '
          f'{fmt(figures["last_nrmse_percent"])} %')
    for k in procs:
        print(f'  {k:<16}        CPU {100 * cpu[k]:5.1f} % of a core, peak RSS '
              f'{peak[k]:.0f} MB (with child processes)')
    print(f'  rig + identifier        {100 * figures["cpu_cores_total"]:.1f} % of a core '
          '(target < 100 %)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
