#!/usr/bin/env python3
"""
Ride benchmark: every controller on ISO 8608 class C at 20 m/s, 60 s, several seeds (medians).

Chain: the "true" damper plant is first identified on the simulated rig (kwok-current model,
``mr_damper_rig.virtual_rig.identify_damper``); the semi-active controllers only use those
identified parameters through the inverse model. Reported:

- the --compare table (medians over seeds) with each controller's change in Wk RMS body
  acceleration and in RMS dynamic tyre load against the best-for-comfort passive current;
- targets: skyhook >= 15 % lower Wk RMS than the best passive, and >= 85 % of skyhook-ideal's
  reduction;
- a skyhook gain sweep (how the default gain was chosen);
- comfort vs road holding: passive current sweep against the hybrid weight sweep (plot);
- physics diagnostics: share of the best passive's Wk energy below 2 Hz (what a skyhook can
  remove), the damper's 0 A force floor, time the inverse saturates, the skyhook force applied
  by a perfect actuator limited to the damper's 0..2 A force range, and (kwok plant) the
  skyhook without coil lag.

Usage::

    .venv/bin/python bench/bench_ride.py [--plant kwok|spencer] [--seeds 1 2 3]
        [--duration 60] [--out-dir bench_out] [--json]
"""
import argparse
import json
from pathlib import Path
import statistics
import time

import numpy as np
from scipy import signal

from mr_damper_model.models.plant import make_plant
from mr_damper_rig.virtual_rig import identify_damper
from semi_active_control import laws as ctl
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.analysis.plots import plot_tradeoff
from quarter_car_sim.metrics.quarter_car import ride_metrics
from semi_active_control.iso2631 import wk_filter
from quarter_car_sim.plant.road import iso8608
from quarter_car_sim.simulate.quarter_car import make_inverse, simulate

PLANTS = {'kwok': 'kwok-current', 'spencer': 'spencer'}
PASSIVE_A = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0)
HYBRID_ALPHA = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0)
HYBRID_GAINS = (2000.0, 4000.0)
SKY_GAINS = ((1000.0, 0.0), (2000.0, 0.0), (3000.0, 0.0), (2000.0, 150.0), (3000.0, 150.0),
             (5000.0, 150.0))
KEYS = ('rms_body_accel_wk', 'rms_body_accel', 'rms_suspension_travel', 'rms_tyre_load_ratio',
        'peak_body_accel', 'contact_loss_fraction', 'mean_current_a', 'max_current_a',
        'saturated_fraction')


class RangeLimitedSkyhook(ctl.SkyhookIdeal):
    """
    Skyhook force applied directly but limited to the identified damper's 0..2 A force range.

    A perfect, lag-free actuator that can make any force the MR damper could make at some
    current: it isolates the effect of the damper's 0 A force floor (and 2 A ceiling) from the
    coil lag and the inverse-model error.
    """

    def __init__(self, inverse, name='skyhook-range-limited'):
        super().__init__(name=name)
        self.inverse = inverse

    def demand(self, state):
        """Skyhook force clipped to [F(0 A), F(2 A)] of the identified model (on the body)."""
        d = super().demand(state)
        lo = -self.inverse.force(self.inverse.i_min, state.travel, state.v_rel)
        hi = -self.inverse.force(self.inverse.i_max, state.travel, state.v_rel)
        a, b = min(lo, hi), max(lo, hi)
        if lo * hi > 0.0 and not a <= d <= b:
            return lo if abs(d - lo) <= abs(d - hi) else hi
        return d


def _median_metrics(runs):
    return {k: statistics.median([r[k] for r in runs]) for k in KEYS}


def _wk_low_share(res, f_cut=2.0):
    y = wk_filter(res.a_s, 1.0 / (res.t[1] - res.t[0]))
    f, p = signal.welch(y, fs=1.0 / (res.t[1] - res.t[0]), nperseg=8192)
    return float(np.trapezoid(p[f < f_cut], f[f < f_cut]) / np.trapezoid(p, f))


def main(argv=None):
    """Run the benchmark."""
    ap = argparse.ArgumentParser(description='ride benchmark (see module docstring)')
    ap.add_argument('--plant', choices=tuple(PLANTS), default='kwok')
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--speed', type=float, default=20.0)
    ap.add_argument('--out-dir', default='bench_out')
    ap.add_argument('--json', action='store_true')
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    params = QuarterCarParams()
    plant = make_plant(PLANTS[args.plant])
    ident = identify_damper(plant, seed=0)
    inverse = make_inverse(ident)
    roads = {s: iso8608('C', args.speed, args.duration, 1e-3, rng=s) for s in args.seeds}

    def run(controller):
        out = []
        for s in args.seeds:
            r = simulate(params, roads[s], controller, plant, inverse=inverse)
            out.append((ride_metrics(r), r))
        return out

    table, diag = {}, {}
    passive_runs = {}
    for i in PASSIVE_A:
        c = ctl.Passive(i)
        runs = run(c)
        passive_runs[c.name] = runs
        table[c.name] = _median_metrics([m for m, _ in runs])
    for name in ('skyhook', 'skyhook-onoff', 'groundhook', 'hybrid', 'add', 'skyhook-ideal',
                 'lqr-active'):
        runs = run(ctl.make_controller(name, params=params))
        table[name] = _median_metrics([m for m, _ in runs])
        if name == 'skyhook':
            diag['skyhook_saturated_fraction'] = table[name]['saturated_fraction']
    passive_names = [ctl.Passive(i).name for i in PASSIVE_A]
    best = min(passive_names, key=lambda n: table[n]['rms_body_accel_wk'])
    wk0, ty0 = table[best]['rms_body_accel_wk'], table[best]['rms_tyre_load_ratio']
    for m in table.values():
        m['wk_change_vs_best_passive_pct'] = 100.0 * (m['rms_body_accel_wk'] / wk0 - 1.0)
        m['tyre_load_change_vs_best_passive_pct'] = 100.0 * (m['rms_tyre_load_ratio'] / ty0 - 1.0)
    red_sky = -table['skyhook']['wk_change_vs_best_passive_pct']
    red_ideal = -table['skyhook-ideal']['wk_change_vs_best_passive_pct']
    targets = {
        'best_passive': best,
        'skyhook_reduction_pct': red_sky,
        'skyhook_ideal_reduction_pct': red_ideal,
        'skyhook_share_of_ideal_pct': 100.0 * red_sky / red_ideal if red_ideal > 0 else None,
        'target_reduction_15pct_met': red_sky >= 15.0,
        'target_85pct_of_ideal_met': red_ideal > 0 and red_sky >= 0.85 * red_ideal,
    }
    # physics diagnostics
    shares = [_wk_low_share(r) for _, r in passive_runs[best]]
    diag['best_passive_wk_energy_below_2hz'] = statistics.median(shares)
    diag['bound_if_all_below_2hz_removed_pct'] = 100.0 * (
        1.0 - np.sqrt(1.0 - diag['best_passive_wk_energy_below_2hz']))
    diag['identified_0A_force_n'] = {f'{v:g} m/s': inverse.force(0.0, 0.005, v)
                                     for v in (0.02, 0.05, 0.1, 0.2)}
    diag['skyhook_range_limited_wk'] = statistics.median(
        [m['rms_body_accel_wk'] for m, _ in run(RangeLimitedSkyhook(inverse))])
    if args.plant == 'kwok':
        no_lag_plant = make_plant('kwok-current', coil_tau_s=0.0)
        diag['skyhook_without_coil_lag_wk'] = statistics.median(
            [ride_metrics(simulate(params, roads[s], ctl.Skyhook(), no_lag_plant,
                                   inverse=inverse))['rms_body_accel_wk'] for s in args.seeds])
    # skyhook gain sweep
    sweep = []
    for c_sky, c_p in SKY_GAINS:
        ms = [m for m, _ in run(ctl.Skyhook(c_sky, c_p))]
        mi = [m for m, _ in run(ctl.SkyhookIdeal(c_sky, c_p))]
        sweep.append({'c_sky': c_sky, 'c_p': c_p,
                      'skyhook_wk': statistics.median([m['rms_body_accel_wk'] for m in ms]),
                      'ideal_wk': statistics.median([m['rms_body_accel_wk'] for m in mi])})
    # trade-off
    passive_curve = [(table[n]['rms_tyre_load_ratio'], table[n]['rms_body_accel_wk'],
                      n.split('@')[1]) for n in passive_names]
    hybrid_curves = {}
    for c_h in HYBRID_GAINS:
        pts = []
        for a in HYBRID_ALPHA:
            m = _median_metrics([x for x, _ in run(ctl.Hybrid(c_h, a))])
            pts.append((m['rms_tyre_load_ratio'], m['rms_body_accel_wk'], f'a={a:g}'))
        hybrid_curves[f'hybrid c={c_h:g} N s/m (alpha swept)'] = pts
    # passive lower envelope (Pareto front: no other setting better on both axes)
    front = sorted(p for p in passive_curve
                   if not any(q[0] <= p[0] and q[1] <= p[1] and q != p for q in passive_curve))
    fx = np.array([p[0] for p in front])
    fy = np.array([p[1] for p in front])
    below = {}
    for label, pts in hybrid_curves.items():
        flags = []
        for x, y, lab in pts:
            if x < fx.min():
                ok = bool(y <= fy[0]) or None       # beyond the passive range of tyre load
            elif x > fx.max():
                ok = bool(y < fy[-1])
            else:
                ok = bool(y < np.interp(x, fx, fy))
            flags.append((lab, ok, round(float(y / np.interp(x, fx, fy) - 1.0) * 100, 1)))
        below[label] = flags
    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    png = out_dir / f'tradeoff_{args.plant}.png'
    plot_tradeoff({'passive (constant current)': passive_curve, **hybrid_curves}, png,
                  points={n: (table[n]['rms_tyre_load_ratio'], table[n]['rms_body_accel_wk'])
                          for n in ('skyhook-ideal', 'lqr-active', 'add')})
    result = {'plant': PLANTS[args.plant], 'seeds': args.seeds, 'duration_s': args.duration,
              'identification': {'parameters': ident['parameters'],
                                 'nrmse_percent': ident['metrics'].get('nrmse_percent')},
              'controllers': table, 'targets': targets, 'diagnostics': diag,
              'skyhook_sweep': sweep,
              'tradeoff': {'passive': passive_curve, 'hybrid': hybrid_curves,
                           'hybrid_below_passive': below, 'plot': str(png)},
              'wall_s': time.perf_counter() - t_start}
    if args.json:
        print(json.dumps(result, indent=1, default=float))
        return
    print(f'plant {PLANTS[args.plant]}, ISO 8608 C @ {args.speed:g} m/s, {args.duration:g} s, '
          f'seeds {args.seeds} (medians); identified nrmse '
          f'{ident["metrics"].get("nrmse_percent", float("nan")):.2f} %')
    print(f'{"controller":15s} {"Wk":>6s} {"dWk%":>6s} {"tyre":>6s} {"dTyre%":>7s} '
          f'{"trav mm":>7s} {"I mean":>6s} {"sat":>5s}')
    for n, m in table.items():
        cur = '-' if m['mean_current_a'] != m['mean_current_a'] else f'{m["mean_current_a"]:.2f}'
        sat = ('-' if m['saturated_fraction'] != m['saturated_fraction']
               else f'{m["saturated_fraction"]:.2f}')
        print(f'{n:15s} {m["rms_body_accel_wk"]:6.3f} {m["wk_change_vs_best_passive_pct"]:6.1f}'
              f' {m["rms_tyre_load_ratio"]:6.3f} {m["tyre_load_change_vs_best_passive_pct"]:7.1f}'
              f' {1000 * m["rms_suspension_travel"]:7.1f} {cur:>6s} {sat:>5s}')
    print('targets:', json.dumps(targets, default=float))
    print('diagnostics:', json.dumps(diag, default=float))
    print('skyhook sweep (c_sky, c_p, skyhook Wk, ideal Wk):')
    for s in sweep:
        print(f'  {s["c_sky"]:6.0f} {s["c_p"]:5.0f}  {s["skyhook_wk"]:.3f}  {s["ideal_wk"]:.3f}')
    print('trade-off: hybrid points (label, below the passive envelope?, % vs envelope):')
    for label, flags in below.items():
        print(f'  {label}: {flags}')
    print(f'plot: {png}; wall {result["wall_s"]:.0f} s')


if __name__ == '__main__':
    main()
