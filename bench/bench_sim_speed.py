#!/usr/bin/env python3
"""
Simulation speed of the quarter car: real-time factor on ISO 8608 class C, 20 m/s, 60 s, 1 kHz.

Targets (issue 3): kwok-current plant >= 50x faster than real time, Spencer plant >= 5x, with
the controller and the inverse model in the loop. Also printed: the cost of one plant step alone
(``DamperPlant.step`` on the thesis cam motion at 1 kHz, the rig's and the car's inner call).
Timing: median of ``--repeats`` runs of ``quarter_car_sim.simulate.quarter_car.simulate`` (whole
call: car, plant, controller, inverse, logging and conversion to arrays; road generation excluded).
The machine is shared: figures are noisy.

Usage::

    .venv/bin/python bench/bench_sim_speed.py [--duration 60] [--repeats 3] [--json]
"""
import argparse
import json
import math
import statistics
import time

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from semi_active_control.laws import Passive, Skyhook
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import iso8608
from quarter_car_sim.simulate.quarter_car import make_inverse, simulate

TARGETS = {'kwok-current': 50.0, 'spencer': 5.0}


def main(argv=None):
    """Run the benchmark and print a table (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--json', action='store_true')
    args = ap.parse_args(argv)
    params = QuarterCarParams()
    road = iso8608('C', 20.0, args.duration, 1e-3, rng=1)
    _, truth = presets.thesis_kwok_current()
    inverse = make_inverse(truth)
    rows = []
    for plant_name in ('kwok-current', 'spencer'):
        plant = make_plant(plant_name)
        for ctl in (Passive(0.0), Skyhook()):
            walls = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                simulate(params, road, ctl, plant, inverse=inverse, settle_s=0.0)
                walls.append(time.perf_counter() - t0)
            wall = statistics.median(walls)
            rows.append({'plant': plant_name, 'controller': ctl.name, 'wall_s': wall,
                         'us_per_step': wall / road.n * 1e6,
                         'real_time_factor': args.duration / wall,
                         'target': TARGETS[plant_name],
                         'met': args.duration / wall >= TARGETS[plant_name]})
    plant_us = {name: _plant_step_us(name, args.repeats) for name in ('kwok-current', 'spencer')}
    if args.json:
        print(json.dumps({'simulate': rows, 'plant_step_us': plant_us}, indent=1))
        return
    print(f'ISO 8608 C, 20 m/s, {args.duration:g} s at 1 kHz ({road.n} steps), '
          f'median of {args.repeats}')
    print(f'{"plant":13s} {"controller":13s} {"wall s":>7s} {"us/step":>8s} {"x real":>7s} '
          f'{"target":>6s}')
    for r in rows:
        print(f'{r["plant"]:13s} {r["controller"]:13s} {r["wall_s"]:7.2f} '
              f'{r["us_per_step"]:8.1f} {r["real_time_factor"]:7.1f} {r["target"]:6.0f}'
              f' {"ok" if r["met"] else "MISSED"}')
    print('plant step alone (thesis cam, 1 kHz, median of repeats): ' + ', '.join(
        f'{name} {us:.1f} us' for name, us in plant_us.items()))


def _plant_step_us(name, repeats, n=20000, dt=1e-3):
    """Time ``n`` plant steps on the thesis cam (30 mm, 1.1 Hz) at 1 A; median us per step."""
    w = 2.0 * math.pi * presets.THESIS_CAM_FREQ_HZ
    amp = presets.THESIS_CAM_AMPLITUDE_M
    motion = [(amp * math.sin(w * k * dt), amp * w * math.cos(w * k * dt)) for k in range(n)]
    costs = []
    for _ in range(repeats):
        plant = make_plant(name)
        t0 = time.perf_counter()
        for x, v in motion:
            plant.step(dt, x, v, 1.0)
        costs.append((time.perf_counter() - t0) / n * 1e6)
    return statistics.median(costs)


if __name__ == '__main__':
    main()
