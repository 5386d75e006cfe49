#!/usr/bin/env python3
"""
Where the vehicle chain's a_v goes, offline (issue 34): the cycle, the delay, the estimate.

``mr-damper-suite --config vehicle`` compares the ride under the vehicle computer with the same
law on the true states answered every 1 ms car step (``a_v_lockstep``). This bench runs the
chain without ROS, bus or wall clock
(:func:`quarter_car_sim.simulate.vehicle_chain.simulate_vehicle_chain`: the car's bus sensors,
the vehicle computer's estimator and controller cores, the drivers) on the suite's road (ISO
8608 C, 20 m/s, seed 1, as long as a suite run of that duration makes it; the shipped dampers
as the car's and as the models), per law:

1. ``lock-step``: true states, every 1 ms step, at once (the suite's ``a_v_lockstep``);
2. true states on the 2 ms cycle, answered at once, 1 ms later (the live loop answering
   within a car step) and 2 ms later (within the cycle);
3. the estimate on the 2 ms cycle, 1 ms later: the vehicle's estimator as shipped, then the
   alternatives in the same run: as it was before 30 Nov 2026 (force states driven at 1e8
   N^2/s, started on the steady covariance: ``accel_bias_std`` 0), and other driving
   intensities of the force states.

No deadline is missed offline: a live run's gap beyond these is the platform's (late cycles,
the watchdog's safe current: ``bench/bench_vehicle.py``). Prints a_v, its ratio to lock-step
and each run's wall time.

Usage::

    .venv/bin/python bench/bench_vehicle_chain.py [--duration 60] [--laws modal-skyhook ...]
                                                  [--json OUT.json]
"""
import argparse
import json
import os
from pathlib import Path
import sys
import time

REPO = Path(__file__).resolve().parents[1]
MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'

#: (label, sensing, cycle steps, delay steps, EstimatorSettings changes or None).
CASES = (
    ('lock-step: true, 1 ms, at once', 'true', 1, 0, None),
    ('true, 2 ms cycle, at once', 'true', 2, 0, None),
    ('true, 2 ms cycle, 1 ms later', 'true', 2, 1, None),
    ('true, 2 ms cycle, 2 ms later', 'true', 2, 2, None),
    ('estimate as shipped, 1 ms later', 'estimate', 2, 1, {}),
    ('estimate before 30 Nov (1e8, no turn-on bias)', 'estimate', 2, 1,
     {'q_force': 1e8, 'accel_bias_std': 0.0}),
    ('estimate, force states 1e8', 'estimate', 2, 1, {'q_force': 1e8}),
    ('estimate, force states 3e9', 'estimate', 2, 1, {'q_force': 3e9}),
)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--duration', type=float, default=60.0, help='road recorded [s]')
    ap.add_argument('--laws', nargs='+', default=['modal-skyhook'],
                    help='full-car laws (modal-skyhook, full-car-clipped-optimal, '
                         'per-corner-skyhook, ...)')
    ap.add_argument('--json', help='write the figures to this file')
    args = ap.parse_args(argv)

    from mr_damper_model.io.params_file import load_plant
    from quarter_car_sim.metrics.full_car import body_a_v
    from quarter_car_sim.plant.two_track_road import make_two_track_road
    from quarter_car_sim.simulate.vehicle_chain import simulate_vehicle_chain
    from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
    from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings,
                                                                  VehicleEstimatorCore)
    files = [str(MODELS / f'{c}.json') for c in CORNERS]
    dt = 1e-3
    # the road of a suite run of that duration (mr-damper-suite makes it 30 s longer)
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                               duration_s=args.duration + 30.0, dt=dt, rng=1)
    print(f'vehicle chain offline: {args.duration:g} s of ISO 8608 C at 20 m/s (seed 1), the '
          f'shipped dampers; load {os.getloadavg()[0]:.2f}; {sys.version.split()[0]}')
    estimators = {}
    out = {}
    for law in args.laws:
        rows = out[law] = []
        print(f'\n{law}:')
        print(f'  {"run":48s} {"a_v":>8s} {"vs lock-step":>13s} {"wall":>7s}')
        ref = None
        for label, sensing, cycle, delay, changes in CASES:
            est = None
            if changes is not None:
                key = tuple(sorted(changes.items()))
                if key not in estimators:
                    estimators[key] = VehicleEstimatorCore(
                        PASSENGER_CAR, EstimatorSettings(cycle_s=cycle * dt, **changes))
                est = estimators[key]
            t0 = time.perf_counter()
            res = simulate_vehicle_chain(
                PASSENGER_CAR, road, law, [load_plant('kwok-current', f) for f in files],
                files, dt=dt, cycle_steps=cycle, delay_steps=delay, sensing=sensing,
                estimator=est, duration_s=args.duration)
            wall = time.perf_counter() - t0
            a_v = body_a_v(res.t, res.acc)
            ref = a_v if ref is None else ref
            row = {'run': label, 'a_v': a_v, 'vs_lockstep': a_v / ref - 1.0, 'wall_s': wall}
            if est is not None:
                st = res.status['estimator']
                row.update(invalid_steps=st['invalid_steps'], steady=st['steady_gain'])
            rows.append(row)
            print(f'  {label:48s} {a_v:8.4f} {100 * row["vs_lockstep"]:+12.2f} % '
                  f'{wall:6.1f} s', flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
