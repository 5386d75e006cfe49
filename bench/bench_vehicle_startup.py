#!/usr/bin/env python3
"""
Start-ups of the vehicle computer: how many reach the active chain, and how fast (issue 34).

A vehicle computer is started with the car, many times a day: each start-up must bring the
managed chain up (configure, then activate every node, by the lifecycle manager) and stay up.
This bench starts ``mr-damper-suite --config vehicle --duration D`` ``--runs`` times per layout
of the vehicle computer (``loop``: one ``vehicle_computer_node``; ``nodes``: bridge, estimator,
controller, each its own process), the layouts in turn, on the same machine, and reads each
run's summary:

- the run's exit status and the launcher's restarts (a node that died or hung);
- the chain (the lifecycle manager's counts): whether it came up (``ups``), the time from the
  manager's first turn to the first time every node was active (``first_up_s``), the
  transitions refused or unanswered (``failed``), the nodes it saw die (``deaths``);
- the control cycles answered, and the drivers' command timeouts after the computer took
  control.

Per layout it prints the start-ups that reached the active chain, ``first_up_s`` p50 / max, and
the sums of the rest; the layouts side by side. ``--set NODE.PARAM=VALUE`` goes to every run.

Usage::

    .venv/bin/python bench/bench_vehicle_startup.py [--runs 5] [--duration 12]
                                                    [--layouts loop,nodes] [--out DIR]
                                                    [--set NODE.PARAM=VALUE ...] [--json OUT]
"""
import argparse
import json
import os
from pathlib import Path
import statistics
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_vehicle import _run, suite_args  # noqa: E402

LAYOUTS = ('loop', 'nodes')


def startup(run):
    """Return one run's start-up figures from ``_run``'s result."""
    s = run.get('summary') or {}
    v = s.get('vehicle') or {}
    chain = v.get('chain') or {}
    return {'exit': run.get('exit'),
            'up': bool(chain.get('ups')),
            'first_up_s': chain.get('first_up_s'),
            'ups': chain.get('ups') or 0,
            'failed': chain.get('failed') or 0,
            'deaths': chain.get('deaths') or 0,
            'restarts': len(s.get('restarts') or ()),
            'cycles': v.get('control_cycles') or 0,
            'driver_timeouts': v.get('driver_command_timeouts') or 0}


def layout_figures(runs):
    """Return a layout's figures over its start-ups (``startup`` of each run)."""
    times = sorted(r['first_up_s'] for r in runs if r['first_up_s'] is not None)
    return {'runs': len(runs),
            'exit_0': sum(r['exit'] == 0 for r in runs),
            'up': sum(r['up'] for r in runs),
            'commanded': sum(r['up'] and r['cycles'] > 0 for r in runs),
            'first_up_p50_s': statistics.median(times) if times else None,
            'first_up_max_s': times[-1] if times else None,
            **{k: sum(r[k] for r in runs)
               for k in ('ups', 'failed', 'deaths', 'restarts', 'driver_timeouts')}}


def report(figures):
    """Print the layouts' figures side by side (a Markdown table)."""
    names = list(figures)

    def row(label, cell):
        print(f'| {label} | ' + ' | '.join(cell(figures[n]) for n in names) + ' |')

    def seconds(x):
        return '-' if x is None else f'{x:.2f} s'
    print('| start-ups | ' + ' | '.join(f'`{n}`' for n in names) + ' |')
    print('|---|' + '---|' * len(names))
    row('runs, exit 0', lambda f: f'{f["runs"]}, {f["exit_0"]}')
    row('chain up (every node active)', lambda f: f'{f["up"]} of {f["runs"]}')
    row('chain up and cycles answered', lambda f: f'{f["commanded"]} of {f["runs"]}')
    row('manager start -> chain up, p50 / max',
        lambda f: f'{seconds(f["first_up_p50_s"])} / {seconds(f["first_up_max_s"])}')
    row('times up (all runs)', lambda f: str(f['ups']))
    row('transitions refused or unanswered', lambda f: str(f['failed']))
    row('deaths the manager saw; launcher restarts',
        lambda f: f'{f["deaths"]}; {f["restarts"]}')
    row('driver command timeouts after activation', lambda f: str(f['driver_timeouts']))


def parse_args(argv=None):
    """Parse the command line."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--runs', type=int, default=5, help='start-ups per layout')
    ap.add_argument('--duration', type=float, default=12.0, help='seconds of each run')
    ap.add_argument('--layouts', default=','.join(LAYOUTS),
                    help='layouts to start, comma-separated (default %(default)s)')
    ap.add_argument('--out', default='runs/bench_vehicle_startup', help='run folders')
    ap.add_argument('--set', action='append', default=[], metavar='NODE.PARAM=VALUE',
                    help='a parameter of every run (repeatable)')
    ap.add_argument('--json', help='write the figures to this file')
    args = ap.parse_args(argv)
    args.layouts = tuple(x for x in args.layouts.split(',') if x)
    bad = set(args.layouts) - set(LAYOUTS)
    if bad or not args.layouts:
        ap.error(f'--layouts: choose from {", ".join(LAYOUTS)}, got {args.layouts}')
    if args.runs < 1 or not args.duration > 0:
        ap.error('--runs must be >= 1 and --duration > 0')
    return args


def main(argv=None):
    """Run the start-ups, layouts in turn; print and return 0."""
    args = parse_args(argv)
    print(f'vehicle start-ups: {args.runs} per layout ({", ".join(args.layouts)}), '
          f'{args.duration:g} s each; load {os.getloadavg()[0]:.2f}', flush=True)
    runs = {layout: [] for layout in args.layouts}
    for k in range(args.runs):
        for layout in args.layouts:
            base = ['--config', 'vehicle', '--vehicle-layout', layout, '--quiet']
            run = _run(f'{layout}_{k + 1}', suite_args(base, args.set), args.out,
                       args.duration)
            one = startup(run)
            runs[layout].append(one)
            print(f'  {layout} {k + 1}: exit {one["exit"]}, up {one["ups"]}x, first up '
                  f'{one["first_up_s"]} s, failed {one["failed"]}, deaths {one["deaths"]}, '
                  f'restarts {one["restarts"]}, cycles {one["cycles"]}', flush=True)
    figures = {layout: layout_figures(r) for layout, r in runs.items()}
    print(f'load at the end {os.getloadavg()[0]:.2f}\n')
    report(figures)
    if args.json:
        Path(args.json).write_text(json.dumps({'runs': runs, 'figures': figures}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
