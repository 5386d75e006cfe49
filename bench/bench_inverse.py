#!/usr/bin/env python3
"""
Per-call time of the one scalar inverse (``mr_damper_model.models.inverse.KwokCurrentInverse``).

Compared in the same run, on the same demands:

- ``one``: the one inverse, ``sign_convention='body'`` (as the car calls it);
- ``before``: what the car ran before issue 9: its adapter class over the model inverse
  (demand negated, flag turned into a bool) with the previous fast path (end points, a
  mid-range monotonicity guess, a 9-point grid otherwise); re-stated here as the reference,
  it is not in the package any more;
- ``vector``: ``inverse_current`` called for one sample (the vectorised inverse);

on the demands of a skyhook ride (ISO 8608 class C, 20 m/s, thesis kwok-current damper, the
identified model equal to the plant), on uniformly random demands (out of reach included) and
on demands the model makes at random currents (``made``: all reachable). Printed: median time
per call [us] over ``--repeats`` batches (the inverses take turns batch by batch), the ratio to
``one``, and how many demands each left saturated (in ``made`` every one is a miss: the round
trip of ``one`` is exact, the previous fast path missed demands near an extremum of F(i)).
Then the whole skyhook control step [us/step] of the car's closed loop (``live_loop.ClosedLoop``
with a fixed inverse) with ``one`` and with ``before``.

Usage::

    .venv/bin/python bench/bench_inverse.py [--seconds 20] [--repeats 15] [--json]
"""
import argparse
import json
import statistics
import time

import numpy as np

from mr_damper_model.identification import presets
from mr_damper_model.models.inverse import inverse_current, KwokCurrentInverse
from mr_damper_model.models.plant import make_plant
from semi_active_control.laws import Skyhook
from quarter_car_sim.plant.quarter_car import QuarterCar
from quarter_car_sim.simulate.live_loop import ClosedLoop
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import iso8608

SEED = 1
TOL_A = 1e-4            # the car's inverse tolerance (``inverse_tol_a``)


class BeforeInverse(KwokCurrentInverse):
    """The pre-issue-9 fast path of the model inverse (reference for the comparison only)."""

    def _current(self, f_des, x, v):
        s_lo, s_hi = self._s_lo, self._s_hi
        d_lo = self._f(s_lo, x, v) - f_des
        d_hi = self._f(s_hi, x, v) - f_des
        if d_lo == 0.0 or (d_lo < 0.0) != (d_hi < 0.0):
            return self._solve(s_lo, s_hi, d_lo, d_hi, f_des, x, v), 0
        d_mid = self._f(0.5 * (s_lo + s_hi), x, v) - f_des
        if min(d_lo, d_hi) <= d_mid <= max(d_lo, d_hi):
            return (self.i_min, -1) if abs(d_lo) <= abs(d_hi) else (self.i_max, 1)
        return self._grid_scan(f_des, x, v)


class BeforeCarAdapter:
    """The car's former ``controllers.KwokCurrentInverse``: body force in, (current, bool) out."""

    def __init__(self, params, **kw):
        self._inverse = BeforeInverse(params, **kw)

    def current(self, f_body, travel, v_rel):
        current, flag = self._inverse.current(-f_body, travel, v_rel)
        return current, flag != 0


def _ride_demands(seconds, truth):
    """(f_body, travel, v_rel) of every step of a skyhook ride with the one inverse."""
    params = QuarterCarParams()
    road = iso8608('C', 20.0, seconds, 1e-3, rng=SEED)
    car = QuarterCar(params, make_plant('kwok-current'), road, t0=road.t[0])
    inv = KwokCurrentInverse(truth, tol_a=TOL_A, sign_convention='body')
    law = Skyhook()
    out = []
    for _ in range(road.n - 1):
        s = car.state
        f = law.demand(s)
        out.append((f, s.travel, s.v_rel))
        car.step(1e-3, inv.current(f, s.travel, s.v_rel)[0])
    return out


def _per_call_us(fns, demands, repeats):
    """
    Median over ``repeats`` batches of the mean time per call [us], for each function.

    The functions take turns batch by batch, so that they share the machine's load.
    """
    per = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            for f, x, v in demands:
                fn(f, x, v)
            per[name].append((time.perf_counter() - t0) / len(demands) * 1e6)
    return {name: statistics.median(t) for name, t in per.items()}


def _loop_us_per_step(inverses, seconds, repeats):
    """Median wall time per control step [us] of the skyhook loop with each inverse."""
    params = QuarterCarParams()
    road = iso8608('C', 20.0, seconds, 1e-3, rng=SEED)
    walls = {name: [] for name in inverses}
    n = road.n - 1
    for _ in range(repeats):
        for name, inverse in inverses.items():
            car = QuarterCar(params, make_plant('kwok-current'), road, t0=road.t[0])
            loop = ClosedLoop(car, Skyhook(), dt=1e-3, inverse=inverse)
            t0 = time.perf_counter()
            for _ in range(n):
                loop.step()
            walls[name].append((time.perf_counter() - t0) / n * 1e6)
    return {name: statistics.median(w) for name, w in walls.items()}


def main(argv=None):
    """Run the benchmark and print the figures (or JSON)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--seconds', type=float, default=20.0, help='ride length [s]')
    ap.add_argument('--repeats', type=int, default=15)
    ap.add_argument('--json', action='store_true')
    args = ap.parse_args(argv)
    model, truth = presets.thesis_kwok_current()
    one = KwokCurrentInverse(truth, tol_a=TOL_A, sign_convention='body')
    before = BeforeCarAdapter(truth, tol_a=TOL_A)
    ride = _ride_demands(args.seconds, truth)
    rng = np.random.default_rng(SEED)
    n = 5000
    rand = list(zip(rng.uniform(-1500, 1500, n).tolist(), rng.normal(0, 0.02, n).tolist(),
                    rng.normal(0, 0.3, n).tolist()))
    p_vec = np.array([truth[k] for k in model.param_names])
    # demands the model makes at random currents in the range: every one is reachable
    x, v, i = rng.uniform(-0.03, 0.03, n), rng.uniform(-0.25, 0.25, n), rng.uniform(0, 2, n)
    made = list(zip((-model.force(p_vec, x, v, i)).tolist(), x.tolist(), v.tolist()))

    def vector(f, x, v):
        return inverse_current(-f, x, v, p_vec, tol_a=TOL_A)

    out = {'seconds': args.seconds, 'repeats': args.repeats, 'cases': {}}
    for case, demands in (('ride', ride), ('random', rand), ('made', made)):
        row = {'calls': len(demands)}
        t = _per_call_us({'one': one.current, 'before': before.current}, demands, args.repeats)
        row['one_us'], row['before_us'] = t['one'], t['before']
        row['vector_us'] = _per_call_us({'vector': vector}, demands[:500],
                                        max(3, args.repeats // 5))['vector']
        row['before_ratio'] = row['before_us'] / row['one_us']
        row['vector_ratio'] = row['vector_us'] / row['one_us']
        # demands each left saturated (all of 'made' are reachable: a saturation is a miss)
        row['saturated_one'] = sum(one.current(f, x, v)[1] != 0 for f, x, v in demands)
        row['saturated_before'] = sum(bool(before.current(f, x, v)[1]) for f, x, v in demands)
        out['cases'][case] = row
    lp = _loop_us_per_step({'one': one, 'before': before}, args.seconds,
                           max(3, args.repeats // 5))
    out['loop_us_per_step'] = {'one': lp['one'], 'before': lp['before'],
                               'ratio_before_to_one': lp['before'] / lp['one']}
    if args.json:
        print(json.dumps(out, indent=1, allow_nan=False))
        return 0
    print(f'scalar inverse per call [us], median of {args.repeats} batches '
          '(ratio = that / one):')
    for case, row in out['cases'].items():
        print(f'  {case:6s} ({row["calls"]} calls): one {row["one_us"]:.2f}, before '
              f'{row["before_us"]:.2f} (x{row["before_ratio"]:.2f}), vector '
              f'{row["vector_us"]:.1f} (x{row["vector_ratio"]:.1f}); left saturated: one '
              f'{row["saturated_one"]}, before {row["saturated_before"]}')
    lp = out['loop_us_per_step']
    print(f'skyhook closed loop (car + kwok-current plant + law + inverse) [us/step]: one '
          f'{lp["one"]:.2f}, before {lp["before"]:.2f} (x{lp["ratio_before_to_one"]:.2f})')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
