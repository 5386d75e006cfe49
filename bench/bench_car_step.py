#!/usr/bin/env python3
"""
CPU cost of the quarter-car node's control step, as ``mr-damper-suite`` runs it.

The car of ``config/suite_sim.yaml`` (skyhook through the supervised inverse of identified
Kwok-current parameters, Spencer "true" damper, ISO 8608 class C at 20 m/s, 1 kHz, state every
10 steps, every step in the trace log) is built by ``quarter_car_sim.runtime.quarter_car
.make_car_runtime`` and stepped by hand on a fake node clock: the runtime's whole step
(supervisor, law, inverse, car, plant, ride metrics, trace log), without ROS and without pacing.
The identified set is offered again every 0.2 s of car time (the identifier's hop), so the car
runs in normal mode. In the same run, the same car with the interpreted Spencer step
(``SpencerPlant(compiled=False)``, the path before the compiled one) and, alone, the plant step
and the clipping of the command both ways.

Figures are steps per CPU second (``time.process_time`` of this process: the machine is
shared, so wall time would measure the other processes), median of ``--repeats``; the load
average (``uptime``) is printed with them. ``cpu_share_at_rate_factor_4`` = the share of one
core the step alone takes at 4x real time (4,000 steps per second); the node's messages come on
top.

Usage::

    .venv/bin/python bench/bench_car_step.py [--steps 20000] [--repeats 5] [--json] [--profile]
"""
import argparse
import cProfile
import io
import json
import math
import os
from pathlib import Path
import pstats
import statistics
import subprocess
import tempfile
import time

import numpy as np
import yaml

from mr_damper_model.io.params_file import load_plant
from mr_damper_model.models import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.runtime.quarter_car import CarOutputs, make_car_runtime
from semi_active_control.supervision.failsafe import clip_current

SUITE_YAML = (Path(__file__).resolve().parents[1] / 'src' / 'mr_damper_bringup' / 'config'
              / 'suite_sim.yaml')
RATE_FACTOR = 4.0
HOP_S = 0.2


def suite_car_parameters():
    """Return the car's parameter values: the node's defaults, then suite_sim.yaml's."""
    from quarter_car_sim.nodes.quarter_car_node import PARAMETERS
    p = {spec.name: spec.default for spec in PARAMETERS}
    doc = yaml.safe_load(SUITE_YAML.read_text())
    for section in ('/**', 'quarter_car_node'):
        p.update((doc.get(section) or {}).get('ros__parameters') or {})
    p['real_time_factor'] = 0.0
    return p


def identified_set():
    """Return the identified parameter set the car is given (thesis Kwok-current)."""
    model, params = presets.thesis_kwok_current()
    return dict(params, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
                valid=1.0)


def make_car(p, log_dir, *, compiled):
    """Build the suite's car runtime; ``compiled``: the compiled or interpreted Spencer step."""
    clock = [0.0]
    supervisor = dict(timeout_s=p['param_timeout_s'], safe_current_a=p['safe_current_a'],
                      i_min_a=p['i_min_a'], i_max_a=p['i_max_a'],
                      hold_on_reject=p['hold_on_reject'],
                      min_current_span_a=p['min_current_span_a'])
    p = dict(p, log_file=str(Path(log_dir) / f'car_{"compiled" if compiled else "python"}'))
    rt = make_car_runtime(p, lambda: clock[0], CarOutputs(), supervisor=supervisor,
                          controller_options=p['controller_options'])
    if p['plant'] != 'spencer':
        raise SystemExit(f'this bench compares Spencer steps; the suite has plant {p["plant"]}')
    rt.car.plant = load_plant('spencer', p['truth_file'], compiled=compiled)
    rt.car.reset()
    return rt, clock


def run_steps(rt, clock, n, msg):
    """Run ``n`` control steps of the runtime, offering ``msg`` every hop; return CPU s."""
    dt = rt.dt
    hop = max(1, int(round(HOP_S / dt)))
    t0 = time.process_time()
    for _ in range(n):
        clock[0] += dt
        if rt.loop.steps % hop == 0:
            rt.sup.offer(msg, clock[0])
        rt.step()
    return time.process_time() - t0


def per_call_us(func, n, repeats):
    """Median CPU microseconds of one ``func()`` over ``repeats`` runs of ``n`` calls."""
    costs = []
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(n):
            func()
        costs.append((time.process_time() - t0) / n * 1e6)
    return statistics.median(costs)


def plant_step_us(compiled, n, repeats, dt=1e-3):
    """CPU us of one Spencer step on the thesis cam (30 mm, 1.1 Hz) at 1 A, median."""
    w = 2.0 * math.pi * presets.THESIS_CAM_FREQ_HZ
    amp = presets.THESIS_CAM_AMPLITUDE_M
    motion = [(amp * math.sin(w * k * dt), amp * w * math.cos(w * k * dt)) for k in range(n)]
    costs = []
    for _ in range(repeats):
        plant = make_plant('spencer', compiled=compiled)
        plant.step(dt, 0.0, 0.0, 1.0)       # compiled: loaded (or compiled) before the clock
        t0 = time.process_time()
        for x, v in motion:
            plant.step(dt, x, v, 1.0)
        costs.append((time.process_time() - t0) / n * 1e6)
    return statistics.median(costs)


def load_average():
    """Return ``uptime``'s line (the load averages)."""
    try:
        return subprocess.run(['uptime'], capture_output=True, text=True,
                              check=False).stdout.strip()
    except OSError:
        return 'load average: ' + ', '.join(f'{v:.2f}' for v in os.getloadavg())


def main(argv=None):
    """Run the benchmark; print a table (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--steps', type=int, default=20000, help='steps per repeat')
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--json', action='store_true')
    ap.add_argument('--profile', action='store_true',
                    help='also print the cProfile of the compiled path (top 20 by own time)')
    args = ap.parse_args(argv)
    p = suite_car_parameters()
    msg = identified_set()
    load_start = load_average()
    rows = {}
    profile_text = ''
    with tempfile.TemporaryDirectory() as log_dir:
        cars = {name: make_car(p, log_dir, compiled=name == 'compiled')
                for name in ('interpreted', 'compiled')}
        for rt, clock in cars.values():
            run_steps(rt, clock, 600, msg)      # settling, first model, kernels loaded
        rates = {name: [] for name in cars}
        for _ in range(args.repeats):
            for name, (rt, clock) in cars.items():   # interleaved: the same load for both
                rates[name].append(args.steps / run_steps(rt, clock, args.steps, msg))
        for name, (rt, clock) in cars.items():
            mode, _ = rt.loop.core.mode_reason()
            rate = statistics.median(rates[name])
            rows[name] = {'steps_per_cpu_s': rate, 'us_per_step': 1e6 / rate,
                          'cpu_share_at_rate_factor_4': RATE_FACTOR / (rt.dt * rate),
                          'mode_at_end': mode, 'steps': rt.loop.steps}
        if args.profile:
            rt, clock = cars['compiled']
            prof = cProfile.Profile()
            prof.runcall(run_steps, rt, clock, args.steps, msg)
            out = io.StringIO()
            pstats.Stats(prof, stream=out).sort_stats('tottime').print_stats(20)
            profile_text = out.getvalue()
        for rt, _ in cars.values():
            rt.close_log()
    n = max(1000, args.steps // 4)
    parts = {
        'spencer_step_interpreted_us': plant_step_us(False, n, args.repeats),
        'spencer_step_compiled_us': plant_step_us(True, n, args.repeats),
        # a 0-d array takes clip_current's array path, the one every scalar took before
        'clip_current_array_path_us': per_call_us(
            lambda: clip_current(np.array(1.2), 0.0, 2.0, 0.5), n, args.repeats),
        'clip_current_scalar_path_us': per_call_us(
            lambda: clip_current(1.2, 0.0, 2.0, 0.5), n, args.repeats),
    }
    result = {'load_start': load_start, 'load_end': load_average(), 'steps': args.steps,
              'repeats': args.repeats, 'car_step': rows, 'parts': parts,
              'speed_up': rows['compiled']['steps_per_cpu_s']
              / rows['interpreted']['steps_per_cpu_s']}
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f'quarter-car step as suite_sim.yaml runs it, {args.steps} steps x {args.repeats} '
          'repeats, median, CPU time of this process')
    print(f'load at start: {load_start}')
    print(f'{"Spencer step":12s} {"steps/CPU-s":>12s} {"us/step":>8s} {"CPU at 4x":>10s} mode')
    for name, r in rows.items():
        print(f'{name:12s} {r["steps_per_cpu_s"]:12.0f} {r["us_per_step"]:8.1f} '
              f'{100 * r["cpu_share_at_rate_factor_4"]:9.1f}% {r["mode_at_end"]}')
    print(f'speed-up compiled / interpreted: {result["speed_up"]:.2f}x')
    print('alone (median us): ' + ', '.join(f'{k} {v:.2f}' for k, v in parts.items()))
    print(f'load at end: {result["load_end"]}')
    if profile_text:
        print(profile_text)


if __name__ == '__main__':
    main()
