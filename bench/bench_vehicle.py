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

Each run's CPU per process (``process_stats.json``: mean and p95 of one core = 100 %), and
the hypervisor's steal time per CPU during it (``/proc/stat``, sampled by the bench:
``bench/hypervisor_steal.py``) with the controller's deadline misses split between the
seconds in which no CPU lost a tick to the hypervisor and the others (from the run's
recorded ``/diagnostics``): on a virtual machine, a stretch of a few milliseconds stolen from
a vCPU is a run of missed cycles whatever the code.

First, the platform: with rt-tests' ``cyclictest`` on the PATH (``apt-get install rt-tests``),
``--platform-s`` seconds of one SCHED_FIFO thread per CPU woken every 1 ms, the machine alone
(the standard test of a real-time Linux box), before any suite runs: how late the kernel (and
a virtual machine's hypervisor) wakes a real-time thread, with nothing of the suite in the
way. Every wake-up later than a cycle's slack (2 ms less the loop's own response) is a cycle
no code on this machine answers in time: its count per minute bounds the answered fraction.

``--pinning``: the vehicle runs as the suite's YAML has them (``pinned``: ``cpu_affinity`` of
``full_car_node`` core 0, of ``vehicle_computer`` core 1), without that pinning (``unpinned``:
both set to ``''``), or each round's layout pinned then unpinned (``both``: the A/B pair side by
side in one table as well). ``--set NODE.PARAM=VALUE`` goes to every suite run (after the
pinning's own ``--set``: yours win).

Usage::

    .venv/bin/python bench/bench_vehicle.py [--duration 60] [--out runs/bench_vehicle]
                                            [--only loop|nodes|external] [--rounds N]
                                            [--pinning both|pinned|unpinned]
                                            [--set NODE.PARAM=VALUE ...] [--json OUT.json]
                                            [--platform-s 30]

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
sys.path.insert(0, str(Path(__file__).resolve().parent))
from hypervisor_steal import deadline_counts, quiet_split, StealSampler  # noqa: E402
SUITE = Path(sys.executable).with_name('mr-damper-suite')
#: The ``--set`` of each pinning of the vehicle runs (the YAML pins; ``''``, YAML's empty
#: string, is no pinning: the launcher parses a ``--set`` value as YAML)
PINNING_SETS = {'pinned': (),
                'unpinned': ("full_car_node.cpu_affinity=''", "vehicle_computer.cpu_affinity=''")}


#: Wake-up lateness thresholds of the platform's figures [us].
LATE_US = (500, 1000, 2000)
#: The vehicle's control cycle (``cycle_s`` of suite_vehicle.yaml) [s].
CYCLE_S = 0.002


def platform_latency(duration_s, priority=30, interval_us=1000):
    """
    Run ``cyclictest`` (rt-tests) on every CPU for ``duration_s``; return its figures.

    None when cyclictest is not installed. Else a dict: per CPU ``min_us``, ``avg_us``,
    ``max_us``, ``wakeups`` and ``late`` (wake-ups later than each of :data:`LATE_US`), and
    ``per_minute`` (the late wake-ups of all CPUs per minute and per CPU).
    """
    import shutil
    exe = shutil.which('cyclictest')
    if exe is None:
        return None
    cmd = [exe, '-m', '-q', '-S', '-p', str(priority), '-i', str(interval_us),
           '-D', f'{max(int(duration_s), 1)}s', '-h', '20000']
    print(f'$ {" ".join(cmd)}', flush=True)
    irq0 = device_interrupts()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    irq1 = device_interrupts()
    if proc.returncode != 0:
        print(proc.stderr[-2000:], file=sys.stderr)
        return {'error': proc.stderr.strip()[-500:] or f'exit {proc.returncode}'}
    out = parse_cyclictest(proc.stdout)
    out['device_interrupts'] = {name: [b - a for a, b in zip(irq0.get(name, [0] * len(n)), n)]
                                for name, n in irq1.items()
                                if sum(n) > sum(irq0.get(name, [0] * len(n)))}
    out['duration_s'] = float(duration_s)
    out['per_minute'] = {str(us): sum(c['late'][str(us)] for c in out['cpus']) * 60.0
                         / duration_s / max(len(out['cpus']), 1) for us in LATE_US}
    for c in out['cpus']:
        c['ceiling'] = answer_ceiling(c)
    return out


def answer_ceiling(cpu):
    """
    Return ``{response_us: fraction}``: the most cycles a loop on this CPU could answer in time.

    A thread woken every 1 ms samples the platform's stalls: the share of its wake-ups later
    than ``L`` is the share of the time a real-time thread there starts more than ``L`` late.
    A loop whose response takes ``r`` misses the cycle whenever it starts later than its
    2 ms cycle less ``r``, so it answers at most ``1 - late(2 ms - r) / wake-ups``, whatever
    its code: ``r = 0`` (:data:`LATE_US` 2000, an instant answer) and ``r = 1 ms`` (1000).
    """
    n = cpu['wakeups']
    return {str(2000 - us): (1.0 - cpu['late'][str(us)] / n if n else None)
            for us in (2000, 1000)}


def device_interrupts(text=None):
    """
    Return ``{device: [count per CPU]}`` of the numbered (device) lines of /proc/interrupts.

    A device's interrupts run on the CPU they are routed to before any thread there, real-time
    or not (``/proc/irq/<n>/smp_affinity``); ``{}`` where the file cannot be read.
    """
    if text is None:
        try:
            text = Path('/proc/interrupts').read_text()
        except OSError:
            return {}
    lines = text.splitlines()
    if not lines:
        return {}
    n_cpu = len(lines[0].split())
    out = {}
    for line in lines[1:]:
        parts = line.split()
        if not parts or not parts[0].rstrip(':').isdigit() or len(parts) < n_cpu + 1:
            continue
        counts = [int(x) for x in parts[1:n_cpu + 1] if x.isdigit()]
        if len(counts) == n_cpu:
            out[' '.join(parts[n_cpu + 1:]) or parts[0]] = counts
    return out


def parse_cyclictest(text):
    """
    Return per-thread figures of ``cyclictest -h`` output (its histogram and summary lines).

    ``{'cpus': [{'min_us', 'avg_us', 'max_us', 'wakeups', 'overflows', 'late': {'500': n,
    ...}}, ...]}``; wake-ups in the histogram's overflow (beyond its range) count as late
    beyond every threshold.
    """
    rows, summary = [], {}
    for line in text.splitlines():
        parts = line.split()
        if not parts:
            continue
        if line.startswith('#'):
            key, _, values = line[1:].partition(':')
            summary[key.strip()] = [int(v) for v in values.split() if v.isdigit()]
        elif all(p.isdigit() for p in parts) and len(parts) >= 2:
            rows.append([int(p) for p in parts])
    n = max((len(r) - 1 for r in rows), default=0)
    cpus = []
    for k in range(n):
        over = (summary.get('Histogram Overflows') or [0] * n)[k]
        cpus.append({
            'min_us': (summary.get('Min Latencies') or [None] * n)[k],
            'avg_us': (summary.get('Avg Latencies') or [None] * n)[k],
            'max_us': (summary.get('Max Latencies') or [None] * n)[k],
            'wakeups': sum(r[k + 1] for r in rows) + over, 'overflows': over,
            'late': {str(us): sum(r[k + 1] for r in rows if r[0] > us) + over
                     for us in LATE_US}})
    return {'cpus': cpus}


def report_platform(fig):
    """Print the platform's wake-up lateness (``platform_latency``)."""
    if fig is None:
        print('platform: cyclictest not installed (apt-get install rt-tests): not measured')
        return
    if 'error' in fig:
        print(f'platform: cyclictest failed: {fig["error"]}')
        return
    print(f'platform (cyclictest, {fig["duration_s"]:g} s, SCHED_FIFO, 1 ms, one thread per '
          f'CPU, nothing else of the bench running):')
    for k, c in enumerate(fig['cpus']):
        late = ', '.join(f'> {us / 1000:g} ms {c["late"][str(us)]}' for us in LATE_US)
        print(f'  CPU {k}: wake-up latency min {c["min_us"]} us, avg {c["avg_us"]} us, max '
              f'{c["max_us"]} us; of {c["wakeups"]} wake-ups late {late}')
    for name, counts in sorted((fig.get('device_interrupts') or {}).items(),
                               key=lambda kv: -sum(kv[1])):
        print(f'  device interrupts meanwhile, {name}: '
              + ', '.join(f'CPU {k} {n}' for k, n in enumerate(counts)))
    pm = fig['per_minute']
    print('  late wake-ups per CPU and minute: '
          + ', '.join(f'> {us / 1000:g} ms {pm[str(us)]:.1f}' for us in LATE_US)
          + ' (each one a cycle of 2 ms that a loop needing more than the rest of its cycle '
            'cannot answer in time: 30 per minute are 0.1 % of the cycles)')
    for k, c in enumerate(fig['cpus']):
        ceil = c.get('ceiling') or {}
        if ceil.get('0') is not None:
            print(f'  CPU {k}: the most cycles of 2 ms a loop there could answer in time: '
                  f'{ceil["0"] * 100:.3f} % answering at once, {ceil["1000"] * 100:.3f} % '
                  f'answering 1 ms after its frame (goal 99.9 %)')


def pinnings(choice):
    """Return the pinnings to run of ``--pinning`` (``both``: pinned, then unpinned)."""
    return ('pinned', 'unpinned') if choice == 'both' else (choice,)


def suite_args(base, sets=(), pinning=None):
    """
    Return the arguments of one suite run after ``--duration`` and ``--out``.

    ``base`` (configuration, layout), then the ``--set`` of ``pinning`` (None: none, the
    external controller's run), then those of ``sets`` (the bench's ``--set``, last: they win).
    """
    items = [*PINNING_SETS[pinning], *sets] if pinning else list(sets)
    return [*base, *(a for item in items for a in ('--set', item))]


def _run(name, args, out, duration):
    """Run one suite configuration; return its summary, process stats, wall time and load."""
    out = Path(out) / name
    cmd = [str(SUITE), '--duration', str(duration), '--out', str(out), '--no-plots',
           '--progress-s', '10', *args]
    load0 = os.getloadavg()
    t0 = time.monotonic()
    print(f'$ {" ".join(cmd)}', flush=True)
    with StealSampler() as steal:
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
            'load_end': load1[0], 'summary': summary, 'cpu': stats,
            'steal': steal_figures(steal, out / 'suite.mcap')}


def steal_figures(steal, mcap):
    """Return the run's steal share per CPU and its status intervals split by steal."""
    out = {'share': steal.shares()}
    try:
        out['split'] = quiet_split(deadline_counts(mcap), steal.samples)
    except Exception as exc:  # noqa: B902 - no recording, a status not read: no split
        out['error'] = f'{type(exc).__name__}: {exc}'
    return out


def report_steal(steal):
    """Print the hypervisor's steal during a run and the cycles on time with and without it."""
    if not steal:
        return
    print('  hypervisor steal (/proc/stat) during the run: ' + ', '.join(
        f'cpu{cpu} {share * 100:.2f} %' for cpu, share in steal['share'].items()))
    split = steal.get('split')
    if split is None:
        print(f'  deadline counts not read: {steal.get("error")}')
        return
    for side, words in (('quiet', 'without steal'), ('stolen', 'with steal')):
        d = split[side]
        print(f'  status intervals {words}: {d["intervals"]}, cycles {d["cycles"]}, misses '
              f'{d["misses"]}, on time {_fmt(d["on_time"], 100, " %", 4)}')


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


def watchdog_trips(v):
    """Return ``(trips, seconds on the safe current)`` of the deadline watchdog, or (None, 0)."""
    deadline = v.get('deadline') or {}
    trips = (deadline.get('entries') or {}).get('deadline_misses')
    safe_s = (deadline.get('failsafe_s') or {}).get('deadline_misses')
    if not isinstance(trips, int) or not isinstance(safe_s, (int, float)):
        return None, 0.0
    return trips, float(safe_s)


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
    trips, safe_s = watchdog_trips(v)
    if trips is not None:
        per = f', {safe_s / trips * 1e3:.0f} ms a trip' if trips else ''
        print(f'  watchdog trips {trips}, {safe_s:.2f} s on the safe current{per}')
    print(f'  sensor frame -> command frame p50 {_fmt(lat.get("p50"), 1e3, " ms")}, p99 '
          f'{_fmt(lat.get("p99"), 1e3, " ms")} (goal <= 2 ms), max '
          f'{_fmt(lat.get("max"), 1e3, " ms")}')
    cpu = v.get('reader_cpu_per_cycle_s') or {}
    mean = cpu.get('mean')
    share = mean / CYCLE_S if isinstance(mean, (int, float)) else None
    print(f'  bus reader thread CPU per cycle mean / p50 / p99 {_fmt(mean, 1e3)} / '
          f'{_fmt(cpu.get("p50"), 1e3)} / {_fmt(cpu.get("p99"), 1e3, " ms")} (the mean '
          f'{_fmt(share, 100, " %")} of a core at {CYCLE_S * 1e3:g} ms)')
    ex = v.get('execution_s')
    if ex:
        p50 = [(ex.get(stage) or {}).get('p50_s') for stage in ex]
        total = (sum(p50) if all(isinstance(x, float) for x in p50) else None)
        rec = v.get('reception_s') or {}
        print('  loop execution p50 / p99: ' + ', '.join(
            f'{stage} {_fmt(h.get("p50_s"), 1e3)} / {_fmt(h.get("p99_s"), 1e3, " ms")}'
            for stage, h in ex.items())
            + f'; the stages\' p50s add up to {_fmt(total, 1e3, " ms")} of the response\'s '
              f'p50 {_fmt(lat.get("p50"), 1e3, " ms")}')
        print(f'  reception (bus time to the loop\'s start) p50 / p99 '
              f'{_fmt(rec.get("p50_s"), 1e3)} / {_fmt(rec.get("p99_s"), 1e3, " ms")}; cycles '
              f'queued behind the one before {v.get("cycles_queued")}')
        misses = v.get('loop_misses') or {}
        print('  cycles the loop finished after their deadline, by cause: '
              + (', '.join(f'{k} {n}' for k, n in misses.items()) or 'none counted')
              + f' (of {sum(misses.values())})')
    print(f'  frames lost {v.get("frames_lost")}, messages lost {v.get("messages_lost")}')
    print(f'  a_v {_fmt(v.get("a_v"))}, passive {_fmt(v.get("a_v_passive"))}, lock-step '
          f'{_fmt(v.get("a_v_lockstep"))}, vs lock-step '
          f'{_fmt(v.get("a_v_vs_lockstep"), 100, " %")} (goal within 3 %)')
    print(f'  all safe {v.get("all_safe")}, chain {v.get("chain")}')
    report_steal(run.get('steal'))
    for row in _cpu_rows(run['cpu']):
        print(row)


def _vehicle_figures(run):
    """Return ``[(figure, value, goal)]`` of a vehicle run, the rows of :func:`compare`."""
    v = run['summary'].get('vehicle') or {}
    lat = v.get('sensor_to_command_s') or {}
    ms = [_fmt(lat.get(k), 1e3) for k in ('p50', 'p99', 'max')]
    frames = v.get('frames_lost')
    frames = frames.get('total') if isinstance(frames, dict) else frames
    rows = [
        ('exit, load start -> end', f'{run["exit"]}, {run["load_start"]:.1f} -> '
         f'{run["load_end"]:.1f}', ''),
        ('control cycles', f'{v.get("control_cycles")}', ''),
        ('answered within the cycle', _fmt(v.get('answered_fraction'), 100, ' %', 4),
         '>= 99.9 %'),
        ('unanswered', f'{v.get("unanswered")}', 'counted'),
        ('sensor frame -> command frame p50 / p99 / max', ' / '.join(ms) + ' ms',
         'p99 <= 2 ms'),
        ('loop execution p50 / p99 [ms]: ' + ', '.join(v.get('execution_s') or {}),
         ', '.join(f'{_fmt(h.get("p50_s"), 1e3)} / {_fmt(h.get("p99_s"), 1e3)}'
                   for h in (v.get('execution_s') or {}).values()) or 'n/a', ''),
        ('controller deadline misses', f'{v.get("deadline_misses")}', 'counted'),
        ('driver command timeouts after activation', f'{v.get("driver_command_timeouts")}',
         '0'),
        ('frames lost on the bus', f'{frames}', 'counted'),
        ('a_v / passive / lock-step [m/s^2]',
         f'{_fmt(v.get("a_v"))} / {_fmt(v.get("a_v_passive"))} / '
         f'{_fmt(v.get("a_v_lockstep"))} ({_fmt(v.get("a_v_vs_lockstep"), 100, " %")})',
         'within 3 %')]
    for name, d in run['cpu'].items():
        if isinstance(d, dict) and 'cpu_mean_percent' in d:
            rows.append((f'CPU mean {name}, one core = 100 %',
                         f'{d["cpu_mean_percent"]:.1f} %', ''))
    if 'nodes_total_cpu_cores' in run['cpu']:
        rows.append(('nodes in all [cores]', f'{run["cpu"]["nodes_total_cpu_cores"]:.2f}', ''))
    return rows


def compare(runs):
    """Print the figures of vehicle runs (``{label: run}``) side by side, a markdown table."""
    tables = {label: {f: (value, goal) for f, value, goal in _vehicle_figures(run)}
              for label, run in runs.items()}
    figures = list(dict.fromkeys(f for t in tables.values() for f in t))
    print('| figure | ' + ' | '.join(runs) + ' | goal |')
    print('|---|' + '---|' * len(runs) + '---|')
    for f in figures:
        cells = [tables[label].get(f, ('n/a', ''))[0] for label in runs]
        goal = next((t[f][1] for t in tables.values() if f in t), '')
        print(f'| {f} | ' + ' | '.join(cells) + f' | {goal} |')


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
    report_steal(run.get('steal'))
    for row in _cpu_rows(run['cpu']):
        print(row)


def parse_args(argv=None):
    """Return the bench's options."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--duration', type=float, default=60.0, help='each run [s, real time]')
    p.add_argument('--out', default=str(REPO / 'runs' / 'bench_vehicle'))
    p.add_argument('--only', choices=('loop', 'nodes', 'external'))
    p.add_argument('--rounds', type=int, default=1,
                   help='runs of each vehicle layout, in turn (loop, nodes, loop, ...)')
    p.add_argument('--pinning', choices=('both', 'pinned', 'unpinned'), default='pinned',
                   help='vehicle runs with the YAML\'s cpu_affinity (pinned), without it '
                        '(unpinned), or each pinned then unpinned, side by side (both); '
                        'default %(default)s')
    p.add_argument('--set', action='append', default=[], metavar='NODE.PARAM=VALUE',
                   help='passed to every mr-damper-suite run (repeatable)')
    p.add_argument('--json', help='write every figure to this file')
    p.add_argument('--platform-s', type=float, default=30.0,
                   help='cyclictest on every CPU first, for this long (0: not) [s]')
    return p.parse_args(argv)


def main(argv=None):
    """Run the bench; return the exit status."""
    args = parse_args(argv)
    results = {}
    if args.platform_s > 0:
        results['platform'] = platform_latency(args.platform_s)
        report_platform(results['platform'])
    for k in range(args.rounds):
        tag = f'_{k + 1}' if args.rounds > 1 else ''
        for layout in ('loop', 'nodes'):
            if args.only not in (None, layout):
                continue
            pair = {}
            for pinning in pinnings(args.pinning):
                name = (f'vehicle_{layout}' + ('' if args.pinning == 'pinned' else f'_{pinning}')
                        + tag)
                base = ['--config', 'vehicle', '--vehicle-layout', layout]
                results[name] = _run(name, suite_args(base, args.set, pinning), args.out,
                                     args.duration)
                print(f'[{name}]')
                report_vehicle(results[name])
                pair[pinning] = results[name]
            if len(pair) > 1:
                print(f'[vehicle_{layout}{tag}: pinned against unpinned]')
                compare(pair)
    if args.only in (None, 'external'):
        results['external'] = _run(
            'external', suite_args(['--config', 'full-car', '--external-controller'], args.set),
            args.out, args.duration)
        report_external(results['external'])
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))
    return 0 if all(r['exit'] == 0 for n, r in results.items() if n != 'platform') else 1


if __name__ == '__main__':
    sys.exit(main())
