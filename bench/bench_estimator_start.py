#!/usr/bin/env python3
"""
The vehicle's full-car filter over its first seconds: the gain schedule against the general step.

From configure on, the vehicle computer's filter starts on wide accelerometer-bias variances
and reaches its steady gain only after about 12 s of road (``EstimatorSettings.steady_tol``).
Until 30 Nov 2026 it ran the general time-varying step (predict the covariance, solve for the
gain, update the covariance) on every one of those cycles; now, while every sensor reads, each
clean cycle runs compiled on the gain worked out for its step when the filter was designed
(:mod:`semi_active_control.estimation.gain_schedule`).

This bench runs, in one process, two filters from the same start over the same recorded
sensor cycles up to their steady gain (``--cycles``, default the schedule's length): ``schedule``
(the shipped settings) and ``general`` (``gain_schedule=False``: the general step on every
cycle until the steady gain, the filter before the schedule: the same recursion). It prints per
way the execution time of a cycle's estimate (p50, p99, mean [us]; each cycle timed alone,
back to back), the ratio of the p50s, the time and memory of the schedule, and the largest
difference of the two estimates (the states in their standard deviations, and the standard
deviations relative), which is round-off.
Pin it to a core (``taskset -c 1``) for the live loop's conditions.

Usage::

    .venv/bin/python bench/bench_estimator_start.py [--cycles N] [--json OUT]
"""
import argparse
import json
import os
from pathlib import Path
import sys
import time

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_vehicle_cycle import CYCLE_S, sensor_cycles  # noqa: E402  (the same recorded cycles)


def make_filter(way):
    """Return the vehicle estimator of ``way``."""
    from semi_active_control.car.full_car import PASSENGER_CAR
    from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings,
                                                                  VehicleEstimatorCore)
    kw = {} if way == 'schedule' else {'gain_schedule': False}
    return VehicleEstimatorCore(PASSENGER_CAR, EstimatorSettings(cycle_s=CYCLE_S, **kw))


def main(argv=None):
    """Run the bench; print per way the estimate's execution time and the two's difference."""
    import numpy as np
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--cycles', type=int, default=None,
                    help='cycles from the start (default: the schedule\'s length)')
    ap.add_argument('--json', help='write the figures to this file')
    args = ap.parse_args(argv)
    print(f'full-car filter from its start: load {os.getloadavg()[0]:.2f}; CPUs '
          f'{sorted(os.sched_getaffinity(0))}; {sys.version.split()[0]}', flush=True)
    filters = {way: make_filter(way) for way in ('schedule', 'general')}
    schedule = filters['schedule'].filter.schedule
    n = args.cycles or schedule.n_steps
    acc, travel = sensor_cycles(n)
    times = {way: np.empty(n) for way in filters}
    diff_x = diff_std = 0.0
    for k in range(n):
        t = (k + 1) * CYCLE_S
        for way, core in filters.items():
            t0 = time.perf_counter()
            core.step(k + 1, t, acc[k], travel[k])
            times[way][k] = time.perf_counter() - t0
        a, b = filters['schedule'].filter, filters['general'].filter
        std = b.std()
        diff_x = max(diff_x, float((np.abs(a.x - b.x) / std).max()))
        diff_std = max(diff_std, float((np.abs(a.std() - std) / std).max()))
    out = {'cycles': n, 'schedule_steps': schedule.n_steps,
           'steady_after': schedule.steady_after, 'schedule_build_s': schedule.build_s,
           'schedule_bytes': schedule.nbytes, 'ways': {},
           'max_relative_difference': {'state': diff_x, 'std': diff_std}}
    print(f'{n} cycles of {CYCLE_S * 1e3:g} ms from the start (the schedule: '
          f'{schedule.n_steps} steps, steady after {schedule.steady_after}; worked out at '
          f'design in {schedule.build_s:.2f} s, {schedule.nbytes / 1e6:.1f} MB)')
    print(f'{"way":10s} {"p50 [us]":>9s} {"p99 [us]":>9s} {"mean [us]":>9s} {"compiled":>9s}')
    for way, core in filters.items():
        ts = times[way] * 1e6
        fig = {'p50_us': float(np.median(ts)),
               'p99_us': float(np.percentile(ts, 99)), 'mean_us': float(ts.mean()),
               'compiled_cycles': int(core.filter.n_compiled)}
        out['ways'][way] = fig
        print(f'{way:10s} {fig["p50_us"]:9.1f} {fig["p99_us"]:9.1f} {fig["mean_us"]:9.1f} '
              f'{fig["compiled_cycles"]:9d}')
    g, s = out['ways']['general'], out['ways']['schedule']
    out['p50_ratio'] = g['p50_us'] / s['p50_us']
    print(f'general / schedule p50: {out["p50_ratio"]:.1f}x; largest difference of the '
          f'estimates: states {diff_x:.1e} of their standard deviations, standard deviations '
          f'{diff_std:.1e} relative; load {os.getloadavg()[0]:.2f}')
    if args.json:
        with open(args.json, 'w') as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == '__main__':
    sys.exit(main())
