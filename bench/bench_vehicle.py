#!/usr/bin/env python3
"""
The vehicle computer in real time (issue 34) against the full car's external controller.

Runs, one after the other on the same machine (the figures depend on the load: the bench prints
``os.getloadavg`` before and after each run):

1. ``mr-damper-suite --config vehicle --duration D``, once per layout of the vehicle computer
   (``--vehicle-layout loop``: one ``vehicle_computer_node``, the control path in one thread;
   ``nodes``: bridge, estimator and controller, each its own process; in turn, ``--rounds``
   times): the simulated car (the plant, its sensors and drivers on a loopback CAN bus) and
   the vehicle computer. From its summary's ``vehicle`` section: control cycles,
   the fraction answered within the cycle (bus to bus), the controller's deadline misses,
   the drivers' command timeouts after the vehicle computer took control, sensor frame to
   command frame p50 / p99, frames lost, a_v against passive and lock-step;
2. ``mr-damper-suite --config full-car --external-controller --duration D``: the same
   controller node on the car's true state, without sensors, estimator and bus: the car
   publishes one ``vehicle/state`` per 2 ms cycle and ``vehicle_controller_node`` answers with
   one ``vehicle/command`` (the four rig / identifier stacks run too: that configuration's
   models are live); from its summary: the car's cycles, the states the controller answered,
   states lost, deadline misses, the car's command timeouts, the body's a_v.

Each run's CPU per process (``process_stats.json``: mean and p95 of one core = 100 %).

Usage::

    .venv/bin/python bench/bench_vehicle.py [--duration 60] [--out runs/bench_vehicle]
                                            [--only loop|nodes|external] [--rounds N]
                                            [--json OUT.json]

Goals of issue 34 (two cores, the suite alone on the machine): the controller answers at
least 99.9 % of control cycles within their period, 0 driver command timeouts after activation,
sensor frame to command frame p99 at most 2 ms, a_v within 3 % of a_v_lockstep.
"""
import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import time

REPO = Path(__file__).resolve().parents[1]
SUITE = Path(sys.executable).with_name('mr-damper-suite')


def _run(name, args, out, duration):
    """Run one suite configuration; return its summary, process stats, wall time and load."""
    out = Path(out) / name
    cmd = [str(SUITE), '--duration', str(duration), '--out', str(out), '--no-plots',
           '--progress-s', '10', *args]
    load0 = os.getloadavg()
    t0 = time.monotonic()
    print(f'$ {" ".join(cmd)}', flush=True)
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    wall = time.monotonic() - t0
    load1 = os.getloadavg()
    if proc.returncode != 0:
        print(proc.stdout[-3000:], proc.stderr[-3000:], file=sys.stderr)
    summary = json.loads((out / 'summary.json').read_text()) \
        if (out / 'summary.json').is_file() else {}
    stats = json.loads((out / 'process_stats.json').read_text()) \
        if (out / 'process_stats.json').is_file() else {}
    return {'exit': proc.returncode, 'wall_s': wall, 'load_start': load0[0],
            'load_end': load1[0], 'summary': summary, 'cpu': stats}


def _cpu_rows(stats):
    rows = []
    for name, d in stats.items():
        if isinstance(d, dict) and 'cpu_mean_percent' in d:
            rows.append(f'  {name:24s} cpu mean {d["cpu_mean_percent"]:6.1f} %  p95 '
                        f'{d["cpu_p95_percent"]:6.1f} %  rss peak {d["rss_peak_mb"]:6.1f} MB')
    if 'nodes_total_cpu_cores' in stats:
        rows.append(f'  nodes in all: {stats["nodes_total_cpu_cores"]:.2f} cores')
    return rows


def _fmt(value, scale=1.0, unit='', digits=3):
    if not isinstance(value, (int, float)):
        return 'n/a'
    return f'{value * scale:.{digits}g}{unit}'


def report_vehicle(run):
    """Print the vehicle run's figures against the goals."""
    v = run['summary'].get('vehicle') or {}
    lat = v.get('sensor_to_command_s') or {}
    print(f'vehicle: exit {run["exit"]}, load {run["load_start"]:.1f} -> '
          f'{run["load_end"]:.1f}, wall {run["wall_s"]:.0f} s')
    print(f'  control cycles {v.get("control_cycles")}, answered within the cycle '
          f'{_fmt(v.get("answered_fraction"), 100, " %", 4)} (goal >= 99.9 %), unanswered '
          f'{v.get("unanswered")}')
    print(f'  deadline misses {v.get("deadline_misses")}, driver command timeouts after '
          f'activation {v.get("driver_command_timeouts")} (goal 0)')
    print(f'  sensor frame -> command frame p50 {_fmt(lat.get("p50"), 1e3, " ms")}, p99 '
          f'{_fmt(lat.get("p99"), 1e3, " ms")} (goal <= 2 ms), max '
          f'{_fmt(lat.get("max"), 1e3, " ms")}')
    print(f'  frames lost {v.get("frames_lost")}, messages lost {v.get("messages_lost")}')
    print(f'  a_v {_fmt(v.get("a_v"))}, passive {_fmt(v.get("a_v_passive"))}, lock-step '
          f'{_fmt(v.get("a_v_lockstep"))}, vs lock-step '
          f'{_fmt(v.get("a_v_vs_lockstep"), 100, " %")} (goal within 3 %)')
    print(f'  all safe {v.get("all_safe")}, chain {v.get("chain")}')
    for row in _cpu_rows(run['cpu']):
        print(row)


def report_external(run):
    """Print the external-controller run's figures."""
    fc = run['summary'].get('full_car') or {}
    ext = fc.get('external_controller') or {}
    print(f'full-car external controller: exit {run["exit"]}, load {run["load_start"]:.1f} -> '
          f'{run["load_end"]:.1f}, wall {run["wall_s"]:.0f} s')
    states = ext.get('car_states')
    answered = ext.get('states_answered') or 0
    print(f'  car states {states}, answered {answered} '
          f'({_fmt(answered / states if states else None, 100, " %")}), states '
          f'{ext.get("states")}, deadline misses {ext.get("deadline_misses")}, all safe '
          f'{ext.get("all_safe")}, car command timeouts {ext.get("car_command_timeouts")}')
    live, passive = fc.get('live') or {}, fc.get('passive') or {}
    print(f'  a_v live {_fmt(live.get("a_v"))}, passive {_fmt(passive.get("a_v"))}')
    for row in _cpu_rows(run['cpu']):
        print(row)


def main(argv=None):
    """Run the bench; return the exit status."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--duration', type=float, default=60.0, help='each run [s, real time]')
    p.add_argument('--out', default=str(REPO / 'runs' / 'bench_vehicle'))
    p.add_argument('--only', choices=('loop', 'nodes', 'external'))
    p.add_argument('--rounds', type=int, default=1,
                   help='runs of each vehicle layout, in turn (loop, nodes, loop, ...)')
    p.add_argument('--json', help='write every figure to this file')
    args = p.parse_args(argv)
    results = {}
    for k in range(args.rounds):
        for layout in ('loop', 'nodes'):
            if args.only in (None, layout):
                name = f'vehicle_{layout}' + (f'_{k + 1}' if args.rounds > 1 else '')
                results[name] = _run(name, ['--config', 'vehicle', '--vehicle-layout', layout],
                                     args.out, args.duration)
                print(f'[{name}]')
                report_vehicle(results[name])
    if args.only in (None, 'external'):
        results['external'] = _run('external', ['--config', 'full-car', '--external-controller'],
                                   args.out, args.duration)
        report_external(results['external'])
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))
    return 0 if all(r['exit'] == 0 for r in results.values()) else 1


if __name__ == '__main__':
    sys.exit(main())
