"""
Benchmark: every documented configuration of ``mr-damper-suite``, one row each.

Runs each configuration README and docs/ describe for ``--duration`` wall seconds (60 by
default), one after the other, and prints from each run's ``summary.json`` (its ``control``
section, :mod:`mr_damper_bringup.report.control`; nothing is computed here):

- ``valid``: when every identifier had published its first valid set [s since the recording
  began];
- ``normal``: when the car (every corner of it) first commanded on a model [s, same clock];
- ``fail-safe``: the share of the car's time after that on the safe current [%];
- ``lost``: measurement samples the identifiers did not get;
- ``rtf``: car time over wall time while the road ran;
- the live ride against passive at the safe current and at 0 A on the same road: the
  Wk-weighted RMS body acceleration [m/s^2] of the quarter car, the ISO 2631-1 total value
  a_v [m/s^2] of the full car ('-': no comparison, e.g. car corners).

Also the machine, the load average before and after each run (a loaded machine slows the car
and the identifiers: say the load with every figure), the exit status and the output folder.

Usage::

    .venv/bin/python bench/bench_configs.py [--duration 60] [--only hil,full-car-external]
        [--out bench_out/configs]
"""
import argparse
import json
import os
from pathlib import Path
import platform
import signal
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parents[1]

#: name -> the suite's options (README, docs/nodes.md, docs/*.md), in the order of the docs
CONFIGS = {
    'sim': [],
    'replay': ['--config', 'replay'],
    'can': ['--config', 'can'],
    'sensing-vehicle': ['--sensing', 'vehicle'],
    'external-controller': ['--external-controller'],
    'hil': ['--config', 'hil'],
    'corners': ['--corners', 'fl,fr'],
    'full-car': ['--config', 'full-car'],
    'full-car-external': ['--config', 'full-car', '--external-controller'],
}
#: wall seconds a run may take beyond its duration (start-up, stop, report) before the hang
#: guard stops its process group
GUARD_S = 300.0


def machine():
    """Return a one-line description of the machine."""
    model = ''
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return f'{platform.node()}: {model or platform.processor()}, {os.cpu_count()} cores, ' \
           f'Python {platform.python_version()}'


def run(name, options, duration, out, bin_dir):
    """Run one configuration; return (exit status, summary dict or None, loads, wall s)."""
    folder = out / name
    cmd = [str(bin_dir / 'mr-damper-suite'), *options, '--duration', f'{duration:g}',
           '--out', str(folder), '--no-plots', '--progress-s', '30']
    load0 = os.getloadavg()[0]
    t0 = time.monotonic()
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / 'bench_stdout.txt', 'w') as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
        try:
            status = proc.wait(timeout=duration + GUARD_S)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                status = proc.wait(timeout=30.0)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                status = proc.wait()
            status = f'hang guard ({status})'
    wall = time.monotonic() - t0
    summary = None
    if (folder / 'summary.json').is_file():
        summary = json.loads((folder / 'summary.json').read_text())
    return status, summary, (load0, os.getloadavg()[0]), wall


def _s(x, fmt='.1f'):
    return '-' if x is None else format(x, fmt)


def row(name, status, summary, loads, wall):
    """Return the printed row of one run."""
    c = (summary or {}).get('control') or {}
    ride = c.get('ride') or {}
    fs = c.get('failsafe_fraction')
    ride_txt = '-'
    if ride.get('live') is not None:
        ride_txt = (f'{ride["metric"]} {_s(ride.get("live"), ".3f")} / '
                    f'{_s(ride.get("passive"), ".3f")} / {_s(ride.get("passive_0a"), ".3f")}')
    return (f'{name:20s} {_s(c.get("first_valid_set_s")):>6s} {_s(c.get("first_normal_s")):>7s} '
            f'{_s(None if fs is None else 100 * fs):>9s} {_s(c.get("samples_lost"), "d"):>6s} '
            f'{_s(c.get("real_time_factor"), ".2f"):>5s}  {ride_txt:32s} '
            f'{loads[0]:5.1f}-{loads[1]:<5.1f} {status} ({wall:.0f} s)')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--duration', type=float, default=60.0, help='wall seconds per run')
    ap.add_argument('--only', default='', help=f'comma-separated subset of {",".join(CONFIGS)}')
    ap.add_argument('--out', default=str(ROOT / 'bench_out' / 'configs'),
                    help='folder of the runs (one sub-folder each)')
    ap.add_argument('--bin-dir', default=str(Path(sys.executable).parent),
                    help='folder of the console scripts (the venv\'s bin)')
    args = ap.parse_args()
    names = [n for n in args.only.split(',') if n] or list(CONFIGS)
    unknown = [n for n in names if n not in CONFIGS]
    if unknown:
        ap.error(f'unknown configurations {unknown}; known: {", ".join(CONFIGS)}')
    out = Path(args.out)
    print(f'machine: {machine()}')
    print(f'{len(names)} configurations, {args.duration:g} s each; times in s since the '
          'recording began, to the status period (1 s)')
    print(f'{"configuration":20s} {"valid":>6s} {"normal":>7s} {"fail-safe":>9s} {"lost":>6s} '
          f'{"rtf":>5s}  {"ride live / passive safe / 0 A":32s} {"load":11s} exit')
    for name in names:
        status, summary, loads, wall = run(name, CONFIGS[name], args.duration, out,
                                           Path(args.bin_dir))
        print(row(name, status, summary, loads, wall), flush=True)
    print(f'outputs: {out}/<configuration>/ (summary.json, bench_stdout.txt)')


if __name__ == '__main__':
    main()
