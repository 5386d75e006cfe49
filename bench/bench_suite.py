"""
Benchmark of the whole suite over ROS 2: 60 s at 1 kHz, real time (not collected by pytest).

    .venv/bin/python bench/bench_suite.py [--duration 60] [--out runs/bench_suite]

Runs ``mr-damper-suite`` (virtual rig -> identifier -> quarter car, the shipped sim
configuration, seeds fixed in it) and prints:

- messages lost (target 0): measurements the identifier did not receive (against the samples in
  the stamp span of ``mr-damper-record``'s copy, whose own gaps are listed too);
- quarter-car control-loop period jitter p99 (target <= 2 ms) and lateness against the schedule;
- time from measurement to current command: inside the car (state read -> command published)
  and through identification (newest sample of a window -> its parameters received; the car's
  next 1 ms step uses them);
- CPU (percent of one core, psutil, sampled every second) and peak memory per node (target: the
  three nodes together under 1.5 cores of this 2-core machine).
"""
import argparse
import json
from pathlib import Path
import subprocess
import sys

REPO = Path(__file__).resolve().parents[1]


def main(argv=None):
    """Run the benchmark and print the figures; return 0."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--duration', type=float, default=60.0)
    p.add_argument('--out', default=str(REPO / 'runs' / 'bench_suite'))
    p.add_argument('--extra', nargs=argparse.REMAINDER, default=[],
                   help='further mr-damper-suite options')
    args = p.parse_args(argv)
    cmd = [str(Path(sys.executable).parent / 'mr-damper-suite'), '--duration',
           str(args.duration), '--out', args.out, '--no-plots', '--progress-s', '10',
           *args.extra]
    print('bench_suite:', ' '.join(cmd), flush=True)
    rc = subprocess.call(cmd)
    s = json.loads((Path(args.out) / 'summary.json').read_text())
    loop = s.get('loop_full_run') or {}
    per, lat = loop.get('period', {}), loop.get('latency', {})
    procs = s.get('processes', {})
    m2p = s.get('measurement_to_parameters_s') or {}
    ident = s.get('identification', {})
    ride = s.get('ride', {})

    def f(x, fmt='.3f'):
        return 'n/a' if x is None else format(x, fmt)
    print('\n=== bench_suite: figures ===')
    print(f'run status {rc}; wall duration {f(s.get("duration_s"), ".1f")} s; '
          f'simulated {f(loop.get("sim_time_s"), ".1f")} s')
    print(f'messages lost: {s.get("messages_lost")} (target 0)   {s.get("messages")}')
    print(f'control loop period p50 {f(per.get("p50_ms"))} ms, p99 {f(per.get("p99_ms"))} ms, '
          f'jitter p99 {f(per.get("jitter_p99_ms"))} ms (target <= 2), '
          f'max {f(per.get("jitter_max_ms"))} ms')
    q = s.get('loop') or {}
    late = q.get('lateness') or {}
    print(f'lateness against the 1 ms schedule (last 5000 steps): p50 {f(late.get("p50_ms"))} '
          f'ms, p99 {f(late.get("p99_ms"))} ms')
    print(f'state read -> current command published: p50 {f(lat.get("p50_ms"))} ms, '
          f'p99 {f(lat.get("p99_ms"))} ms')
    print(f'newest sample of a window -> its parameters at the car: p50 '
          f'{f(m2p.get("p50"))} s, p99 {f(m2p.get("p99"))} s ({m2p.get("n", 0)} updates)')
    print(f'identification: {ident.get("updates")} updates, {ident.get("valid_updates")} valid, '
          f'first valid after {f(ident.get("first_valid_s"), ".1f")} s, final NRMSE '
          f'{f(ident.get("nrmse_percent"), ".2f")} %')
    if ride.get('skyhook') and ride.get('passive'):
        print(f'ride: Wk RMS live {ride["controller"]} {ride["skyhook"]["rms_body_accel_wk"]:.4f}'
              f' vs passive {ride["passive"]["rms_body_accel_wk"]:.4f} m/s^2 '
              f'({f(ride.get("wk_improvement_percent"), ".1f")} % better); fail-safe '
              f'{f(s.get("failsafe_s"), ".2f")} s')
    for name, st in procs.items():
        if isinstance(st, dict):
            print(f'  {name:22s} CPU mean {st["cpu_mean_percent"]:6.1f} %  p95 '
                  f'{st["cpu_p95_percent"]:6.1f} %  RSS peak {st["rss_peak_mb"]:6.1f} MB')
    print(f'three nodes together: {f(procs.get("nodes_total_cpu_cores"), ".2f")} cores '
          '(target < 1.5)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
