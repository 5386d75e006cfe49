#!/usr/bin/env python3
"""
The vehicle loop's execution time per stage when it waits for each cycle, as live (issue 34).

A live vehicle computer answers a sensor cycle every 2 ms and waits for the next one in
between; the suite's figures (``execution_s`` of ``bench/bench_vehicle.py``) are several times
a replay's that runs the same cycles back to back. This bench runs one
:class:`~semi_active_control.runtime.VehicleLoop` (the shipped estimator, modal skyhook with the
shipped models, the bridge's command encoding on a bus that drops the frame) on the same
recorded sensor cycles in three ways, in one process, one after the other:

- ``back-to-back``: the next cycle at once (what a hand-made replay or a profiler measures);
- ``spin``: the next cycle at its 2 ms, the thread busy-waiting meanwhile (the core never idles);
- ``sleep``: the next cycle at its 2 ms, the thread sleeping meanwhile (as the live loop,
  blocked on the bus between frames).

First the filter runs ``--warmup`` cycles back to back, so every measured cycle is on the
steady gain. The cycles are a simulated car's bus sensors (the shipped dampers at the safe
current, the suite's road: ISO 8608 C at 20 m/s). Prints per way and stage (``estimate``,
``control``, ``send``; :attr:`VehicleLoop.execution`) the p50 and p99 [us] and the ratios of
the p50s to back-to-back's. Pin it to a core (``taskset -c 1``) for the live loop's conditions.

Usage::

    .venv/bin/python bench/bench_vehicle_cycle.py [--cycles 3000] [--warmup 7000] [--json OUT]
"""
import argparse
import json
import os
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
CYCLE_S = 0.002
WAYS = ('back-to-back', 'spin', 'sleep')


def sensor_cycles(n, seed=1):
    """Return ``n`` bus cycles (body accelerations less g, travels) of the simulated car."""
    import numpy as np
    from mr_damper_model.io.params_file import load_plant
    from quarter_car_sim.plant.full_car import FullCar
    from quarter_car_sim.plant.sensors import bus_sensor_cluster
    from quarter_car_sim.plant.two_track_road import make_two_track_road
    from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
    from semi_active_control.estimation.sensor_specs import G0
    from semi_active_control.supervision import COIL_SETTINGS
    dt = CYCLE_S / 2
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                               duration_s=n * CYCLE_S + 1.0, dt=dt, rng=seed)
    plants = [load_plant('kwok-current', str(MODELS / f'{c}.json')) for c in CORNERS]
    car = FullCar(PASSENGER_CAR, plants, road)
    sensors = bus_sensor_cluster(dt, CYCLE_S, seed)
    acc, travel = np.full((n, 4), np.nan), np.full((n, 4), np.nan)
    s = car.state
    k = 0
    while k < n:
        r = sensors.step(s.t, s)
        if r:
            acc[k] = [r[f'accel_{c}'] - G0 for c in CORNERS]
            travel[k] = [r[f'travel_{c}'] for c in CORNERS]
            k += 1
        s = car.step(dt, [COIL_SETTINGS['safe_current_a']] * 4)
    return acc, travel


def make_loop():
    """Return ``(estimator, controller, send)``: the vehicle computer's cores and encoder."""
    from mr_damper_can.vehicle_bridge import VehicleBridge
    from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
    from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings,
                                                                  VehicleEstimatorCore)
    from semi_active_control.runtime import VehicleControllerCore
    from semi_active_control.supervision import COIL_SETTINGS, CornerModels

    class NullBus:
        def send(self, msg, timeout=None):
            pass

    estimator = VehicleEstimatorCore(PASSENGER_CAR, EstimatorSettings(cycle_s=CYCLE_S))
    models = CornerModels([str(MODELS / f'{c}.json') for c in CORNERS], **COIL_SETTINGS)
    controller = VehicleControllerCore(PASSENGER_CAR, 'modal-skyhook', models,
                                       cycle_s=CYCLE_S, max_consecutive_misses=10 ** 9)
    bridge = VehicleBridge(NullBus(), cycle_s=CYCLE_S)
    bridge.activate()
    return estimator, controller, bridge.command_all


def run_way(way, cores, acc, travel, start, n):
    """Run cycles ``start .. start + n - 1`` one way; return the loop's execution summaries."""
    from semi_active_control.runtime import VehicleLoop
    estimator, controller, send = cores
    loop = VehicleLoop(estimator, controller, send)
    loop.activate(0.0)
    t_due = time.perf_counter()
    for k in range(start, start + n):
        if way != 'back-to-back':
            t_due += CYCLE_S
            if way == 'sleep':
                delay = t_due - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            else:
                while time.perf_counter() < t_due:
                    pass
        t = (k + 1) * CYCLE_S
        loop.cycle(k + 1, t, acc[k], travel[k], t + 1e-4)   # answered on the cycle's clock
    return {stage: h.summary() for stage, h in loop.execution.items()}


def main(argv=None):
    """Run the bench; print per way and stage the p50 / p99 and the ratios to back-to-back."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--cycles', type=int, default=3000, help='measured cycles per way')
    ap.add_argument('--warmup', type=int, default=7000,
                    help='cycles back to back first (the filter reaches its steady gain)')
    ap.add_argument('--json', help='write the figures to this file')
    args = ap.parse_args(argv)
    n_all = args.warmup + len(WAYS) * args.cycles
    print(f'vehicle loop cycle: {args.cycles} cycles per way after {args.warmup} back to back; '
          f'load {os.getloadavg()[0]:.2f}; CPUs {sorted(os.sched_getaffinity(0))}; '
          f'{sys.version.split()[0]}', flush=True)
    acc, travel = sensor_cycles(n_all)
    cores = make_loop()
    estimator, controller, _ = cores
    controller.configure(0.0)
    run_way('back-to-back', cores, acc, travel, 0, args.warmup)
    steady = estimator.status()['steady_gain']
    print(f'filter on its steady gain after the warm-up: {steady}')
    out = {'cycles': args.cycles, 'warmup': args.warmup, 'steady_gain': steady,
           'load_end': None, 'ways': {}}
    start = args.warmup
    for way in WAYS:
        out['ways'][way] = run_way(way, cores, acc, travel, start, args.cycles)
        start += args.cycles
    out['load_end'] = os.getloadavg()[0]
    ref = out['ways']['back-to-back']
    print(f'\n{"way":14s} ' + ' '.join(f'{s + " p50 / p99 [us]":>26s}' for s in ref)
          + '   p50 / back-to-back')
    for way, ex in out['ways'].items():
        cells = ' '.join(f'{ex[s]["p50_s"] * 1e6:12.0f} / {ex[s]["p99_s"] * 1e6:11.0f}'
                         for s in ex)
        ratios = ', '.join(f'{s} {ex[s]["p50_s"] / ref[s]["p50_s"]:.2f}x' for s in ex)
        total = sum(ex[s]['p50_s'] for s in ex) * 1e6
        print(f'{way:14s} {cells}   {ratios}; p50s add up to {total:.0f} us')
    print(f'load at the end {out["load_end"]:.2f}')
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
