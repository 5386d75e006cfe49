#!/usr/bin/env python3
"""
What the live full car's ISO 2631-1 status costs as a run grows: whole history or running.

``full_car_node`` publishes the body's ISO 2631-1 figures (a_v, VDV, crest factors) in its
status once a second. Two ways to get them, compared in the same run on the same samples
(a 1 kHz body history of heave, pitch and roll accelerations, Gaussian):

1. ``whole``: :func:`quarter_car_sim.metrics.full_car.iso2631_seat` of the whole history so far
   at each status (the node before 30 Nov 2026): its cost grows with the run;
2. ``running``: :class:`quarter_car_sim.metrics.full_car.RunningIso2631` fed the second of
   samples since the status before (the node now): its cost is the second's, at any length.

Prints per history length the median time of one status [ms] of each, their ratio, and the
largest relative difference between the two's figures (they must agree).

Usage::

    .venv/bin/python bench/bench_ride_status.py [--lengths-s 10 60 600] [--repeats 7]
"""
import argparse
import copy
import statistics
import time

import numpy as np

from quarter_car_sim.metrics.full_car import iso2631_seat, RunningIso2631

DT = 1e-3          # the car's step [s]
STATUS_S = 1.0     # the node's status period [s]


def _median_ms(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def compare(length_s, repeats, rng):
    """Return ``(whole_ms, running_ms, max_rel_diff)`` of one status after ``length_s``."""
    n = int(round(length_s / DT))
    t = np.arange(n) * DT
    acc = rng.standard_normal((n, 3)) * (0.5, 0.8, 1.1)
    new = int(round(STATUS_S / DT))
    running = RunningIso2631(DT)
    running.add(*acc[:n - new].T)                      # the statuses before this one

    fed = [copy.deepcopy(running) for _ in range(repeats + 1)]   # one per timing

    def one_running():
        r = fed.pop()
        r.add(*acc[n - new:].T)
        return r

    whole_ms = _median_ms(lambda: iso2631_seat(t, *acc.T), repeats)
    running_ms = _median_ms(one_running, repeats)
    a, b = one_running().as_dict(), iso2631_seat(t, *acc.T)       # the last copy
    diff = max(abs(a[k] - b[k]) / abs(b[k]) for k in b if k != 'vdv_required')
    return whole_ms, running_ms, diff


def main(argv=None):
    """Run the comparison and print it."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--lengths-s', type=float, nargs='+', default=[10.0, 60.0, 600.0],
                   help='history lengths [s] at which a status is timed')
    p.add_argument('--repeats', type=int, default=7, help='timings per figure (median)')
    args = p.parse_args(argv)
    rng = np.random.default_rng(1)
    print(f'one status of the full car\'s ISO 2631-1 figures, 1 kHz history, medians of '
          f'{args.repeats}')
    print(f'{"history":>10s} {"whole [ms]":>11s} {"running [ms]":>13s} {"ratio":>7s} '
          f'{"max rel diff":>13s}')
    for length in args.lengths_s:
        whole, running, diff = compare(length, args.repeats, rng)
        print(f'{length:8.0f} s {whole:11.2f} {running:13.3f} {whole / running:7.0f} '
              f'{diff:13.1e}')


if __name__ == '__main__':
    main()
