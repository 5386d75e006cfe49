#!/usr/bin/env python3
"""
Road preview (issue 36): the preview laws against today's best law and the offline bound.

Full car as ``bench/bench_full_car.py``: the passenger car with a Spencer damper (the "true"
plant) at each corner, each corner's kwok-current model identified on the simulated rig (noise
seed 1-4 per corner) and used through that corner's supervised inverse; ISO 8608 class C at
20 m/s on two tracks, seeds 1 2 3, 60 s, medians over the seeds. Rows:

- ``full-car-clipped-optimal-wk``: today's best live law (no preview);
- the preview rows of :mod:`quarter_car_sim.preview_rows`: ``preview-wheelbase`` (the front
  wheels' road for the rear ones, speed signal 2 % off), ``preview-look-ahead-ideal``,
  ``preview-look-ahead`` (20 ms latency, 3 mm RMS height noise, speed 2 % off), and the MPC on
  the same two sensors (``preview-mpc-*``);
- ``bound``: the offline optimal semi-active bound (comfort only), replayed on the plants.

The goals' figures follow the table: each law's a_v over the bound's, its tyre loads against
today's best law at every wheel, the MPC's plan time against its update period. The quarter
car (Spencer plant, identified on the rig, ISO C 20 m/s, seeds 1-3, 60 s, as
``bench/bench_laws.py``): ``clipped-optimal-wk``, its preview rows, the bound.

``--curves``: robustness, a_v against each error alone (latency, height noise, speed error,
the sensor's far range) on shorter roads (``--curve-duration``, ``--curve-seeds``), for the LQ
preview and (``--mpc-curves``) the MPC, with today's law and the bound as reference lines; a
table and a plot (``--plot``, default ``bench_out/preview_robustness.png``).

Usage::

    .venv/bin/python bench/bench_preview.py [--seeds 1 2 3] [--duration 60] [--no-quarter]
                                            [--no-full] [--no-mpc] [--curves [--mpc-curves]]
                                            [--curve-duration 20] [--curve-seeds 1]
                                            [--json OUT.json] [--plot OUT.png]
"""
import argparse
import dataclasses
import json
import os
from pathlib import Path
import statistics
import time

from mr_damper_model.models.plant import make_plant
from mr_damper_rig.virtual_rig import identify_damper
from quarter_car_sim.bound import KwokForceModel, semi_active_bound
from quarter_car_sim.controllers import make_controller
from quarter_car_sim.full_car import (compare_laws, CORNERS, make_full_car_law,
                                      make_two_track_road, PASSENGER_CAR, simulate_full_car)
from quarter_car_sim.full_car.bound import corner_force_model, full_car_bound
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.preview_rows import (FULL_CAR_ROWS, full_car_preview_row, is_mpc,
                                          PreviewOptions, quarter_car_preview_row,
                                          QUARTER_CAR_ROWS)
from quarter_car_sim.preview_sensor import IDEAL_LOOK_AHEAD
from quarter_car_sim.road import iso8608
from quarter_car_sim.simulate import make_inverse, simulate

TODAY = 'full-car-clipped-optimal-wk'
P = PASSENGER_CAR
CURVES = {
    'latency_ms': (0.0, 10.0, 20.0, 50.0, 100.0),
    'height_noise_mm': (0.0, 1.0, 3.0, 5.0, 10.0),
    'speed_error_pct': (0.0, 1.0, 2.0, 5.0, 10.0),
    'range_m': (1.0, 2.0, 4.0, 8.0, 15.0),
}


def _curve_options(kind, value, seed):
    """Preview options with one error alone on the ideal sensor."""
    spec = IDEAL_LOOK_AHEAD
    err = 0.0
    if kind == 'latency_ms':
        spec = dataclasses.replace(spec, latency_s=value / 1e3)
    elif kind == 'height_noise_mm':
        spec = dataclasses.replace(spec, height_noise_m=value / 1e3)
    elif kind == 'speed_error_pct':
        err = value / 100.0
    elif kind == 'range_m':
        spec = dataclasses.replace(spec, range_m=(min(0.5, value / 2.0), value))
    return PreviewOptions(sensor=spec, speed_error=err, seed=seed)


def _full_runs(seeds, duration, plants, damper, rows, bound=True, options=None):
    """Metrics per law per seed: today's law, the preview ``rows``, the bound."""
    runs = {}
    models = [corner_force_model(d, P) for d in damper]
    for seed in seeds:
        road = make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=duration,
                                   rng=seed)
        for name, m in compare_laws(P, road, [make_full_car_law(TODAY, P)], plants,
                                    damper).items():
            runs.setdefault(name, []).append(m)
        for name in rows:
            opts = options or PreviewOptions(seed=seed)
            law = full_car_preview_row(name, P, road, opts, damper=damper)
            res = simulate_full_car(P, road, law, plants, damper)
            m = res.metrics(P)
            m['wall_time_s'] = res.wall_time_s
            m['preview'] = law.status()
            runs.setdefault(name, []).append(m)
            print(f'  seed {seed} {name}: a_v {m["a_v"]:.4f} ({res.wall_time_s:.0f} s)',
                  flush=True)
        if bound:
            start = time.perf_counter()
            res = full_car_bound(P, road, models, plants, damper)
            m = res.metrics(P)
            m['wall_time_s'] = time.perf_counter() - start
            runs.setdefault('bound', []).append(m)
            print(f'  seed {seed} bound: a_v {m["a_v"]:.4f} ({m["wall_time_s"]:.0f} s)',
                  flush=True)
    return runs


def _med(ms, key):
    return statistics.median(m[key] for m in ms)


def _full_table(runs):
    table = {}
    for name, ms in runs.items():
        row = {k: _med(ms, k) for k in ('a_v', 'a_wz', 'a_w_pitch', 'a_w_roll', 'vdv_total')}
        row['tyre'] = {c: statistics.median(m['rms_tyre_load_ratio'][c] for m in ms)
                       for c in CORNERS}
        row['travel_mm'] = 1e3 * max(statistics.median(m['rms_suspension_travel'][c]
                                                       for m in ms) for c in CORNERS)
        plans = [m['preview'] for m in ms if 'preview' in m and 'plan_ms_median' in
                 m['preview']]
        if plans:
            row['plan_ms_median'] = statistics.median(p['plan_ms_median'] for p in plans)
            row['plan_ms_p95'] = max(p['plan_ms_p95'] for p in plans)
        prev = [m['preview']['law'] for m in ms if 'preview' in m]
        if prev:
            row['fallback_steps'] = sum(p['fallback_steps'] for p in prev)
            row['steps'] = sum(p['steps'] for p in prev)
        table[name] = row
    return table


def _print_full(table, seeds, duration):
    bound = table['bound']['a_v']
    today = table[TODAY]
    print(f'\nfull car: ISO 8608 C, 20 m/s, {duration:g} s, seeds {seeds}, Spencer plants, '
          f'medians; load average {os.getloadavg()}')
    print('| law | a_v m/s^2 | over bound | a_wz | pitch | roll | VDV | tyre fl / fr / rl / '
          'rr | travel mm |')
    print('|---|---|---|---|---|---|---|---|---|')
    for name, r in table.items():
        print(f'| {name} | {r["a_v"]:.3f} | {100 * (r["a_v"] / bound - 1):+.1f} % | '
              f'{r["a_wz"]:.3f} | {r["a_w_pitch"]:.3f} | {r["a_w_roll"]:.3f} | '
              f'{r["vdv_total"]:.2f} | '
              + ' / '.join(f'{r["tyre"][c]:.3f}' for c in CORNERS)
              + f' | {r["travel_mm"]:.1f} |')
    print('\ngoals (full car):')
    for name, r in table.items():
        if name in (TODAY, 'bound'):
            continue
        over = 100 * (r['a_v'] / bound - 1)
        goal = 10.0 if name.endswith('ideal') else 15.0 if name.endswith('look-ahead') else None
        tyre_ok = all(r['tyre'][c] <= today['tyre'][c] for c in CORNERS)
        verdict = '' if goal is None else (' -> within {:g} %: {}'.format(
            goal, 'MET' if over <= goal else 'not met'))
        print(f'  {name}: a_v {r["a_v"]:.3f}, {over:+.1f} % over the bound{verdict}; tyre '
              f'loads no worse than {TODAY} at every wheel: {tyre_ok}; fallback steps '
              f'{r.get("fallback_steps", 0)} of {r.get("steps", 0)}')
        if 'plan_ms_median' in r:
            from quarter_car_sim.full_car.preview_mpc import DEFAULT_MPC
            period_ms = DEFAULT_MPC['update_every']
            print(f'    MPC plan time median {r["plan_ms_median"]:.1f} ms, p95 '
                  f'{r["plan_ms_p95"]:.1f} ms against its update period {period_ms} ms: '
                  f'{"fits" if r["plan_ms_p95"] <= period_ms else "does NOT fit"} (at this '
                  'load)')
    print(f'  {TODAY} (today): a_v {today["a_v"]:.3f}, '
          f'{100 * (today["a_v"] / bound - 1):+.1f} % over the bound')


def _quarter(seeds, duration):
    params = QuarterCarParams()
    plant = make_plant('spencer')
    inverse = make_inverse(identify_damper(plant, seed=0))
    runs = {}
    for seed in seeds:
        road = iso8608('C', 20.0, duration, 1e-3, rng=seed)
        laws = [make_controller('clipped-optimal-wk', params=params, inverse=inverse)]
        laws += [quarter_car_preview_row(n, params, road, inverse,
                                         PreviewOptions(seed=seed)) for n in QUARTER_CAR_ROWS]
        for law in laws:
            runs.setdefault(law.name, []).append(
                simulate(params, road, law, plant, inverse=inverse).metrics())
        res = semi_active_bound(params, road, KwokForceModel(inverse), plant)
        runs.setdefault('bound', []).append(res.metrics())
        print(f'  quarter car seed {seed}: ' + ', '.join(
            f'{n} {v[-1]["rms_body_accel_wk"]:.4f}' for n, v in runs.items()), flush=True)
    table = {n: {k: _med(ms, k) for k in ('rms_body_accel_wk', 'rms_tyre_load_ratio',
                                          'rms_suspension_travel')}
             for n, ms in runs.items()}
    bound = table['bound']['rms_body_accel_wk']
    print(f'\nquarter car: Spencer plant, ISO 8608 C, 20 m/s, {duration:g} s, seeds {seeds}, '
          f'medians; load average {os.getloadavg()}')
    print('| law | Wk m/s^2 | over bound | tyre | travel mm |')
    print('|---|---|---|---|---|')
    for n, r in table.items():
        print(f'| {n} | {r["rms_body_accel_wk"]:.4f} | '
              f'{100 * (r["rms_body_accel_wk"] / bound - 1):+.2f} % | '
              f'{r["rms_tyre_load_ratio"]:.3f} | {1e3 * r["rms_suspension_travel"]:.1f} |')
    best = min((n for n in table if n != 'bound'),
               key=lambda n: table[n]['rms_body_accel_wk'])
    over = 100 * (table[best]['rms_body_accel_wk'] / bound - 1)
    print(f'goal (quarter car within 1 % of its bound): {best} {over:+.2f} % -> '
          f'{"MET" if over <= 1.0 else "not met"}')
    return table


def _curves(args, plants, damper):
    laws = ['preview-look-ahead'] + (['preview-mpc-look-ahead'] if args.mpc_curves else [])
    ref = _full_table(_full_runs(args.curve_seeds, args.curve_duration, plants, damper, []))
    out = {'today': ref[TODAY]['a_v'], 'bound': ref['bound']['a_v'], 'curves': {}}
    print(f'\nrobustness ({args.curve_duration:g} s, seeds {args.curve_seeds}): '
          f'{TODAY} {out["today"]:.3f}, bound {out["bound"]:.3f}; load {os.getloadavg()}')
    for kind, values in CURVES.items():
        for law in laws:
            pts = []
            for v in values:
                ms = []
                for seed in args.curve_seeds:
                    road = make_two_track_road('iso8608-C', P, speed_m_s=20.0,
                                               duration_s=args.curve_duration, rng=seed)
                    fed = full_car_preview_row(law, P, road, _curve_options(kind, v, seed),
                                               damper=damper)
                    res = simulate_full_car(P, road, fed, plants, damper)
                    st = fed.status()['law']
                    ms.append({'a_v': res.metrics(P)['a_v'],
                               'fallback': st['fallback_steps'] / st['steps']})
                pts.append((v, _med(ms, 'a_v'), _med(ms, 'fallback')))
                print(f'  {law} {kind} {v:g}: a_v {pts[-1][1]:.4f} (fallback '
                      f'{100 * pts[-1][2]:.1f} % of steps)', flush=True)
            out['curves'].setdefault(kind, {})[law] = pts
    print('\n| error | value | ' + ' | '.join(f'{law} a_v (over bound)' for law in laws) + ' |')
    print('|---|---|' + '---|' * len(laws))
    for kind, per_law in out['curves'].items():
        for j, v in enumerate(CURVES[kind]):
            cells = [f'{a:.3f} ({100 * (a / out["bound"] - 1):+.1f} %)'
                     for a in (per_law[law][j][1] for law in laws)]
            print(f'| {kind} | {v:g} | ' + ' | '.join(cells) + ' |')
    _plot(out, args.plot)
    return out


def _plot(out, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(out['curves']), figsize=(4 * len(out['curves']), 3.6),
                             sharey=True)
    for ax, (kind, per_law) in zip(axes, out['curves'].items()):
        for law, pts in per_law.items():
            ax.plot([p[0] for p in pts], [p[1] for p in pts], 'o-', label=law)
        ax.axhline(out['today'], color='grey', ls='--', label=f'{TODAY} (no preview)')
        ax.axhline(out['bound'], color='k', ls=':', label='bound')
        ax.set_xlabel(kind.replace('_', ' '))
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel('a_v [m/s^2]')
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f'plot: {path}')


def main(argv=None):
    """Run the bench and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--no-full', action='store_true', help='skip the full-car goal table')
    ap.add_argument('--no-quarter', action='store_true', help='skip the quarter car')
    ap.add_argument('--no-mpc', action='store_true', help='leave out the MPC rows')
    ap.add_argument('--curves', action='store_true', help='robustness curves')
    ap.add_argument('--mpc-curves', action='store_true', help='curves of the MPC too')
    ap.add_argument('--curve-duration', type=float, default=20.0)
    ap.add_argument('--curve-seeds', type=int, nargs='+', default=[1])
    ap.add_argument('--plot', default='bench_out/preview_robustness.png')
    ap.add_argument('--json', default='')
    args = ap.parse_args(argv)
    t0 = time.time()
    print(f'load average at start {os.getloadavg()}', flush=True)
    out = {}
    if not args.no_quarter:
        out['quarter_car'] = _quarter(args.seeds, args.duration)
    if not args.no_full or args.curves:
        plants = [make_plant('spencer') for _ in CORNERS]
        damper = [identify_damper(pl, seed=i + 1) for i, pl in enumerate(plants)]
    if not args.no_full:
        rows = [n for n in FULL_CAR_ROWS if not (args.no_mpc and is_mpc(n))]
        table = _full_table(_full_runs(args.seeds, args.duration, plants, damper, rows))
        _print_full(table, args.seeds, args.duration)
        out['full_car'] = table
    if args.curves:
        out['curves'] = _curves(args, plants, damper)
    print(f'total wall time {time.time() - t0:.0f} s; load average at end {os.getloadavg()}')
    if args.json:
        with open(args.json, 'w') as fh:
            json.dump(out, fh, indent=1)


if __name__ == '__main__':
    main()
