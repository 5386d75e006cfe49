#!/usr/bin/env python3
"""
Simulation speed of the quarter car: real-time factor on ISO 8608 class C, 20 m/s, 60 s, 1 kHz.

Targets (issue 3): kwok-current plant >= 50x faster than real time, Spencer plant >= 5x, with
the controller and the inverse model in the loop. Timing: median of ``--repeats`` runs of
``quarter_car_sim.simulate.simulate`` (whole call: car, plant, controller, inverse, logging and
conversion to arrays; road generation excluded). The machine is shared: figures are noisy.

Usage::

    .venv/bin/python bench/bench_sim_speed.py [--duration 60] [--repeats 3] [--json]
"""
import argparse
import json
import statistics
import time

from mr_damper_model import presets
from mr_damper_model.plant import make_plant
from quarter_car_sim.controllers import Passive, Skyhook
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.road import iso8608
from quarter_car_sim.simulate import make_inverse, simulate

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
    if args.json:
        print(json.dumps(rows, indent=1))
        return
    print(f'ISO 8608 C, 20 m/s, {args.duration:g} s at 1 kHz ({road.n} steps), '
          f'median of {args.repeats}')
    print(f'{"plant":13s} {"controller":13s} {"wall s":>7s} {"us/step":>8s} {"x real":>7s} '
          f'{"target":>6s}')
    for r in rows:
        print(f'{r["plant"]:13s} {r["controller"]:13s} {r["wall_s"]:7.2f} '
              f'{r["us_per_step"]:8.1f} {r["real_time_factor"]:7.1f} {r["target"]:6.0f}'
              f' {"ok" if r["met"] else "MISSED"}')


if __name__ == '__main__':
    main()
