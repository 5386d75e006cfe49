#!/usr/bin/env python3
"""
Full car (7 DOF, issue 24): modal skyhook against per-corner laws and passive settings.

Passenger car of ``semi_active_control.car.full_car`` with a Spencer damper (the "true" plant)
at each corner, each corner's kwok-current model identified on the simulated rig
(``mr_damper_rig.virtual_rig.identify_damper``, a different noise seed per corner) and used
through that corner's supervised inverse. Roads: ISO 8608 class C at 20 m/s on two tracks
(isotropic coherence, rear delayed by wheelbase / speed), 60 s, seeds 1 2 3; medians over seeds.

1. Tuning on training roads (seeds 11 12 13, 20 s; not the bench roads): modal sky damping
   ratios (heave, pitch, roll) and the per-corner skyhook gain, each picked by median a_v.
   The full-car clipped-optimal LQR's weights likewise, and those of its ISO-weighted
   version (``full-car-clipped-optimal-wk``: Wk / We filters in the design and the law).
2. Bench roads: passive 0 / 0.5 / 1 / 2 A, per-corner skyhook (default and tuned gain),
   SH-ADD and clipped-optimal-wk, modal skyhook (default and tuned ratios), full-car
   clipped-optimal and full-car clipped-optimal-wk (default and tuned weights).
   ``--only-lqr``: passive 0 A and the two LQRs only.
3. ``--bound``: also the offline optimal semi-active bound (``quarter_car_sim.bound.full_car``:
   full road preview, each corner's identified force map; its currents replayed on the Spencer
   plants) at each ``--bound-rho``, with its model prediction as a row of its own.
   ``--only-bound``: passive 0 / 0.5 A, modal skyhook, the ISO-weighted full-car LQR and the
   bound (no tuning: the laws' defaults).

Goals (issue 24): the best live law at least 10 % below passive 0 A in the ISO 2631-1
vibration total value a_v with no worse RMS dynamic tyre load at any wheel; modal control
better than four independent per-corner laws in pitch and roll (We-weighted RMS).

Usage::

    .venv/bin/python bench/bench_full_car.py [--seeds 1 2 3] [--duration 60]
                                             [--train-seeds 11 12 13] [--train-duration 20]
                                             [--skip-tuning] [--only-lqr] [--json OUT.json]
                                           [--bound [--bound-rho 0 0.5]] [--only-bound]
"""
import argparse
import json
import os
import statistics
import time

from mr_damper_model.models.plant import make_plant
from mr_damper_rig.virtual_rig import identify_damper
from semi_active_control.laws import DEFAULT_C_P, Skyhook
from quarter_car_sim.bound.full_car import corner_force_model, full_car_bound
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import compare_laws
from semi_active_control.laws.full_car import ModalSkyhook, PerCornerLaws
from semi_active_control.laws.registry import make_full_car_law
from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
from semi_active_control.laws.full_car import DEFAULT_MODAL_ZETA
from semi_active_control.laws.full_car_lqr import FullCarClippedOptimal
from semi_active_control.laws.full_car_lqr_wk import FullCarClippedOptimalWk

PASSIVE_A = (0.0, 0.5, 1.0, 2.0)
MODAL_GRID = ((0.3, 0.3, 0.3), (0.5, 0.5, 0.5), (0.5, 1.0, 1.0), (0.7, 1.0, 1.0),
              (0.5, 1.5, 1.5), (0.7, 1.5, 1.5), (0.5, 2.0, 2.0))
SKY_GRID = (2000.0, 3000.0, 4000.0, 6000.0)
LQR_GRID = ({}, {'r_force': 1e-6}, {'r_force': 3e-7}, {'q_tyre': 1e4, 'r_force': 1e-6})
LQR_WK_GRID = ({}, {'r_force': 1e-7}, {'q_travel': 0.0},
               {'q_heave': 0.1, 'q_pitch': 0.016, 'q_roll': 0.04})
KEYS = ('a_v', 'a_wz', 'a_w_pitch', 'a_w_roll', 'vdv_total', 'crest_max')


def _modal(z, name=None):
    zeta = dict(zip(('heave', 'pitch', 'roll'), z))
    return ModalSkyhook.from_car(PASSENGER_CAR, zeta=zeta,
                                 name=name or 'modal-skyhook z=' + '/'.join(f'{v:g}' for v in z))


def _sky(c_sky):
    return PerCornerLaws([Skyhook(c_sky, DEFAULT_C_P) for _ in CORNERS],
                         name=f'per-corner-skyhook c={c_sky:g}')


def _lqr(w, name=None):
    txt = ','.join(f'{k}={v:g}' for k, v in w.items()) or 'default'
    return FullCarClippedOptimal.from_car(PASSENGER_CAR, name=name or f'full-car-co {txt}', **w)


def _lqr_wk(w, name=None):
    txt = ','.join(f'{k}={v:g}' for k, v in w.items()) or 'default'
    return FullCarClippedOptimalWk.from_car(PASSENGER_CAR, name=name or f'full-car-co-wk {txt}',
                                            **w)


def _median_runs(laws_fn, seeds, duration, plants, damper, bound_rho=()):
    """
    Run fresh laws (``laws_fn()``) on each seed's road; return {name: [metrics per seed]}.

    With ``bound_rho`` the offline bound at each weight too: its replay on the plants and its
    prediction on the identified models (``<name> prediction``).
    """
    runs = {}
    models = [corner_force_model(d, PASSENGER_CAR) for d in damper]
    for seed in seeds:
        road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                                   duration_s=duration, rng=seed)
        for name, m in compare_laws(PASSENGER_CAR, road, laws_fn(), plants, damper).items():
            runs.setdefault(name, []).append(m)
        for rho in bound_rho:
            start = time.perf_counter()
            res = full_car_bound(PASSENGER_CAR, road, models, plants, damper, rho=rho)
            wall = time.perf_counter() - start
            name = res.replay.law
            print(f'  seed {seed} {name}: J {res.cost_start:.4f} -> '
                  + ' '.join(f'{j:.4f}' for j in res.cost_history[1:]) + f' ({wall:.0f} s)',
                  flush=True)
            for key, m in ((name, res.metrics(PASSENGER_CAR)),
                           (name + ' prediction', dict(res.predicted_metrics))):
                m['wall_time_s'] = wall
                runs.setdefault(key, []).append(m)
    return runs


def _med(ms, key):
    return statistics.median(m[key] for m in ms)


def _wheel_med(ms, corner):
    return statistics.median(m['rms_tyre_load_ratio'][corner] for m in ms)


def main(argv=None):
    """Run the bench and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--train-seeds', type=int, nargs='+', default=[11, 12, 13])
    ap.add_argument('--train-duration', type=float, default=20.0)
    ap.add_argument('--skip-tuning', action='store_true')
    ap.add_argument('--only-lqr', action='store_true',
                    help='only the full-car clipped-optimal LQR (and passive 0 A)')
    ap.add_argument('--bound', action='store_true',
                    help='also the offline optimal semi-active bound (replay and prediction)')
    ap.add_argument('--bound-rho', type=float, nargs='+', default=[0.0, 0.5],
                    help='tyre-load weights of the bound (default 0 0.5)')
    ap.add_argument('--only-bound', action='store_true',
                    help='passive 0 / 0.5 A, modal skyhook, full-car clipped-optimal-wk and '
                         'the bound, no tuning')
    ap.add_argument('--json', default='')
    args = ap.parse_args(argv)
    if args.only_bound:
        args.bound, args.skip_tuning = True, True
    t0 = time.time()
    print(f'load average at start {os.getloadavg()}', flush=True)
    plants = [make_plant('spencer') for _ in CORNERS]
    damper = []
    for i, pl in enumerate(plants):
        d = identify_damper(pl, seed=i + 1)
        damper.append(d)
        print(f'{CORNERS[i]}: identified kwok-current nrmse '
              f'{d["metrics"].get("nrmse_percent", float("nan")):.2f} %', flush=True)

    best_z, best_c = tuple(DEFAULT_MODAL_ZETA[k] for k in ('heave', 'pitch', 'roll')), 2000.0
    best_w, best_wk = {}, {}
    if not args.skip_tuning:
        print(f'\ntuning on seeds {args.train_seeds}, {args.train_duration:g} s (median a_v, '
              'pitch, roll, worst-wheel tyre load)', flush=True)

        def grid():
            out = [_lqr(w) for w in LQR_GRID] + [_lqr_wk(w) for w in LQR_WK_GRID]
            if not args.only_lqr:
                out += [_modal(z) for z in MODAL_GRID] + [_sky(c) for c in SKY_GRID]
            return out

        runs = _median_runs(grid, args.train_seeds, args.train_duration, plants, damper)
        for name, ms in runs.items():
            print(f'  {name:34s} a_v {_med(ms, "a_v"):.3f}  pitch {_med(ms, "a_w_pitch"):.3f}  '
                  f'roll {_med(ms, "a_w_roll"):.3f}  '
                  f'tyre {_med(ms, "max_rms_tyre_load_ratio"):.3f}', flush=True)
        best_w = min(LQR_GRID, key=lambda w: _med(runs[_lqr(w).name], 'a_v'))
        best_wk = min(LQR_WK_GRID, key=lambda w: _med(runs[_lqr_wk(w).name], 'a_v'))
        print(f'  picked full-car clipped-optimal weights {best_w or "default"}, -wk weights '
              f'{best_wk or "default"}', flush=True)
        if not args.only_lqr:
            best_z = min(MODAL_GRID, key=lambda z: _med(runs[_modal(z).name], 'a_v'))
            best_c = min(SKY_GRID, key=lambda c: _med(runs[_sky(c).name], 'a_v'))
            print(f'  picked modal z={best_z}, per-corner skyhook c_sky={best_c:g}', flush=True)

    def laws():
        lqr = [make_full_car_law('full-car-clipped-optimal', PASSENGER_CAR)]
        if best_w:
            lqr.append(_lqr(best_w, name='full-car-clipped-optimal tuned '
                            + ','.join(f'{k}={v:g}' for k, v in best_w.items())))
        lqr.append(make_full_car_law('full-car-clipped-optimal-wk', PASSENGER_CAR))
        if best_wk:
            lqr.append(_lqr_wk(best_wk, name='full-car-clipped-optimal-wk tuned '
                               + ','.join(f'{k}={v:g}' for k, v in best_wk.items())))
        if args.only_lqr:
            return [make_full_car_law('passive@0A', PASSENGER_CAR)] + lqr
        if args.only_bound:
            return [make_full_car_law(n, PASSENGER_CAR)
                    for n in ('passive@0A', 'passive@0.5A', 'modal-skyhook',
                              'full-car-clipped-optimal-wk')]
        out = [make_full_car_law(f'passive@{i:g}A', PASSENGER_CAR) for i in PASSIVE_A]
        out += [make_full_car_law(f'per-corner-{n}', PASSENGER_CAR)
                for n in ('skyhook', 'sh-add', 'clipped-optimal-wk')]
        if best_c != 2000.0:
            out.append(_sky(best_c))
        out.append(make_full_car_law('modal-skyhook', PASSENGER_CAR))
        if best_z != tuple(DEFAULT_MODAL_ZETA[k] for k in ('heave', 'pitch', 'roll')):
            out.append(_modal(best_z, name='modal-skyhook tuned z=' +
                              '/'.join(f'{v:g}' for v in best_z)))
        return out + lqr

    runs = _median_runs(laws, args.seeds, args.duration, plants, damper,
                        bound_rho=args.bound_rho if args.bound else ())
    ref = runs['passive@0.0A']
    av0 = _med(ref, 'a_v')
    print(f'\nISO 8608 C, 20 m/s, {args.duration:g} s, seeds {args.seeds}, Spencer plants, '
          f'medians; load average {os.getloadavg()}')
    head = (f'{"law":36s} {"a_v":>6s} {"dav%":>6s} {"a_wz":>6s} {"pitch":>6s} {"roll":>6s} '
            f'{"VDV":>5s} {"crest":>5s} ' + ' '.join(f'{"tyre " + c:>8s}' for c in CORNERS)
            + f' {"trav mm":>7s} {"wall s":>6s}')
    print(head)
    table = {}
    for name, ms in runs.items():
        row = {k: _med(ms, k) for k in KEYS}
        row['tyre'] = {c: _wheel_med(ms, c) for c in CORNERS}
        row['travel_mm'] = 1e3 * max(statistics.median(m['rms_suspension_travel'][c] for m in ms)
                                     for c in CORNERS)
        row['dav_pct'] = 100.0 * (row['a_v'] / av0 - 1.0)
        row['wall_s'] = statistics.median(m['wall_time_s'] for m in ms)
        row['tyre_no_worse'] = all(row['tyre'][c] <= _wheel_med(ref, c) for c in CORNERS)
        table[name] = row
        print(f'{name:36s} {row["a_v"]:6.3f} {row["dav_pct"]:6.1f} {row["a_wz"]:6.3f} '
              f'{row["a_w_pitch"]:6.3f} {row["a_w_roll"]:6.3f} {row["vdv_total"]:5.2f} '
              f'{row["crest_max"]:5.1f} '
              + ' '.join(f'{row["tyre"][c]:8.3f}' for c in CORNERS)
              + f' {row["travel_mm"]:7.1f} {row["wall_s"]:6.1f}')
    print('a_v: ISO 2631-1 vibration total value at the CG [m/s^2]; a_wz Wk [m/s^2]; pitch, '
          'roll: We-weighted RMS [rad/s^2]; VDV [m/s^1.75]; tyre: RMS dynamic / static load per '
          'wheel; trav: largest corner RMS travel; wall: loop wall time per run')

    live = {n: r for n, r in table.items() if not n.startswith(('passive', 'bound'))}
    ok = {n: r for n, r in live.items() if r['tyre_no_worse']}
    best = min(ok or live, key=lambda n: table[n]['a_v'])
    b = table[best]
    goal1 = b['dav_pct'] <= -10.0 and b['tyre_no_worse']
    print(f'\ngoal 1: best live law with no worse tyre load at any wheel: {best}, a_v '
          f'{b["dav_pct"]:+.1f} % against passive 0 A -> {"met" if goal1 else "NOT met"}')
    corner_laws = [n for n in live if n.startswith('per-corner')]
    modal = [n for n in live if n.startswith('modal')]
    for m in modal if corner_laws else ():
        beat = [c for c in corner_laws if table[m]['a_w_pitch'] < table[c]['a_w_pitch']
                and table[m]['a_w_roll'] < table[c]['a_w_roll']]
        print(f'goal 2: {m} (pitch {table[m]["a_w_pitch"]:.3f}, roll {table[m]["a_w_roll"]:.3f})'
              f' below in both pitch and roll: {len(beat)} of {len(corner_laws)} per-corner laws'
              + (f' (not: {", ".join(c for c in corner_laws if c not in beat)})'
                 if len(beat) < len(corner_laws) else ''))
    wk, co = table.get('full-car-clipped-optimal-wk'), table.get('full-car-clipped-optimal')
    if wk and co:
        print('full-car-clipped-optimal-wk against full-car-clipped-optimal (same run): a_v '
              f'{100.0 * (wk["a_v"] / co["a_v"] - 1.0):+.1f} %, tyre per wheel '
              + ' / '.join(f'{100.0 * (wk["tyre"][c] / co["tyre"][c] - 1.0):+.1f}'
                           for c in CORNERS) + ' %')
    for name in (n for n in table if n.startswith('bound') and 'prediction' not in n):
        r = table[name]
        print(f'{name} (replayed on the plants): a_v {r["a_v"]:.3f} ({r["dav_pct"]:+.1f} % vs '
              f'passive 0 A); best live law {best} {b["a_v"]:.3f}, '
              f'{100.0 * (b["a_v"] / r["a_v"] - 1.0):+.1f} % above the bound; tyre no worse '
              f'than passive 0 A at every wheel: {r["tyre_no_worse"]}')
    print(f'total wall time {time.time() - t0:.0f} s; load average at end {os.getloadavg()}')
    if args.json:
        with open(args.json, 'w') as fh:
            json.dump({'table': table, 'modal_zeta': best_z, 'sky_c': best_c,
                       'lqr_weights': best_w, 'lqr_wk_weights': best_wk}, fh, indent=1)


if __name__ == '__main__':
    main()
