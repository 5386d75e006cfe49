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

With ``--rate-factors 1,2,4,8`` (and ``--samples-per-message 1,20``) it runs the suite once per
combination, ``--duration`` record seconds each (the wall time is shorter at higher rate
factors; ``--wall``: wall seconds each, as ``mr-damper-suite --duration``), and prints one
table: samples lost, parameter updates, sample -> parameters at the car p50 / p99, fail-safe
time, CPU per process. ``samples_per_message`` 1 sends one DDS message per DAQ sample,
as the rig did before batching: the before / after of the batched measurement stream in one run.
"""
import argparse
import json
import os
from pathlib import Path
import subprocess
import sys

REPO = Path(__file__).resolve().parents[1]


def run_suite(duration, out, extra):
    """Run mr-damper-suite once; return (exit status, summary dict)."""
    cmd = [str(Path(sys.executable).parent / 'mr-damper-suite'), '--duration',
           str(duration), '--out', str(out), '--no-plots', '--progress-s', '10', *extra]
    print('bench_suite:', ' '.join(cmd), flush=True)
    rc = subprocess.call(cmd, stdout=subprocess.DEVNULL if '--quiet' in extra else None)
    path = Path(out) / 'summary.json'
    return rc, (json.loads(path.read_text()) if path.exists() else {})


def _f(x, fmt='.3f'):
    return 'n/a' if x is None else format(x, fmt)


def print_one(rc, s):
    """Print the figures of one run (the default single run)."""
    f = _f
    loop = s.get('loop_full_run') or {}
    per, lat = loop.get('period', {}), loop.get('latency', {})
    procs = s.get('processes', {})
    m2p = s.get('measurement_to_parameters_s') or {}
    ident = s.get('identification', {})
    ride = s.get('ride', {})
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


def sweep(args):
    """Run every (samples per message, rate factor) combination; print one table."""
    rows = []
    for spm in (int(k) for k in args.samples_per_message.split(',')):
        for rf in (float(r) for r in args.rate_factors.split(',')):
            out = Path(args.out) / f'spm{spm}_rf{rf:g}'
            wall = args.duration if args.wall else args.duration / rf
            rc, s = run_suite(wall, out,
                              ['--rate-factor', str(rf), '--quiet',
                               '--set', f'mr_damper_rig.samples_per_message={spm}',
                               *args.extra])
            rows.append((spm, rf, rc, s))
    print('\n=== bench_suite: rate factors ('
          f'{"wall" if args.wall else "record"} seconds {args.duration:g} each; '
          f'load at the end {os.getloadavg()[0]:.2f}, '
          f'{os.cpu_count()} cores) ===')
    names = sorted({n for *_, s in rows for n, v in s.get('processes', {}).items()
                    if isinstance(v, dict)})
    print('samples/msg  rate  exit  lost  updates  sample->params p50 / p99 s  fail-safe s  '
          'car x real time: run / p50  '
          + '  '.join(f'{n[:12]:>12s}' for n in names) + '   (CPU % of one core)')
    for spm, rf, rc, s in rows:
        m2p = s.get('measurement_to_parameters_s') or {}
        loop = s.get('loop_full_run') or {}
        rtf = (f'{_f(loop.get("real_time_factor_measured"), ".2f"):>9s} / '
               f'{_f(loop.get("real_time_factor_median"), ".2f"):<5s}')
        procs = s.get('processes', {})
        cpu = '  '.join(f'{procs[n]["cpu_mean_percent"]:12.1f}' if isinstance(
            procs.get(n), dict) else f'{"-":>12s}' for n in names)
        print(f'{spm:11d}  {rf:4g}  {rc:4d}  {_f(s.get("messages_lost"), "d"):>4s}  '
              f'{_f(m2p.get("n"), "d"):>7s}  '
              f'{_f(m2p.get("p50")):>10s} / {_f(m2p.get("p99")):<10s}   '
              f'{_f(s.get("failsafe_s"), ".2f"):>10s}  {rtf:>26s}  {cpu}')
    return 0


def main(argv=None):
    """Run the benchmark and print the figures; return 0."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--duration', type=float, default=60.0,
                   help='record seconds of each run (wall: duration / rate factor)')
    p.add_argument('--wall', action='store_true',
                   help='with --rate-factors: --duration is the wall seconds of each run '
                        '(as mr-damper-suite --duration), not its record seconds')
    p.add_argument('--out', default=str(REPO / 'runs' / 'bench_suite'))
    p.add_argument('--rate-factors', default='',
                   help='e.g. 1,2,4,8: one run per rate factor (and batch size), one table')
    p.add_argument('--samples-per-message', default='1,20',
                   help='with --rate-factors: rig batch sizes to compare')
    p.add_argument('--extra', nargs=argparse.REMAINDER, default=[],
                   help='further mr-damper-suite options')
    args = p.parse_args(argv)
    if args.rate_factors:
        return sweep(args)
    rc, s = run_suite(args.duration, args.out, args.extra)
    print_one(rc, s)
    return 0


if __name__ == '__main__':
    sys.exit(main())
