#!/usr/bin/env python3
"""
Comfort on estimated states: the laws with ideal states against the Kalman-filtered estimate.

Spencer damper (the "true" plant), kwok-current identified on the simulated rig (as
bench_laws.py), ISO 8608 class C at 20 m/s, 60 s, seeds 1 2 3, medians over the seeds. For
skyhook, SH-ADD, clipped-optimal and clipped-optimal-wk: Wk RMS body acceleration [m/s^2] and
RMS dynamic tyre load / static load with the law on the true state ("ideal") and on the state
estimated from the default modelled sensors (ADXL313-like body accelerometer, ride-height
sensor; ``quarter_car_sim.plant.sensors``) by ``semi_active_control.estimation.quarter_car``
("vehicle"), and the RMS estimation error of each state. Conditions:

- ``nominal``: the simulated car is the one the estimator (and the LQR laws) assume;
- ``m_s +-20%``, ``k_s +-20%``, ``k_t +-20%``: the simulated car's body mass, spring or tyre
  stiffness off by 20 % from what the estimator and the laws assume;
- ``bias drift``: accelerometer bias drifting 0.005 m/s^2 per second (0.3 m/s^2 = 31 mg over
  the run, an ADXL313 warm-up of about 40 degC at its 0.75 mg/degC) with a random walk of
  5e-3 m/s^2/sqrt(s).

Goal (nominal): every law within 3 % of its ideal-state Wk at no worse tyre load; the best law
on estimated states at least 5 % below passive@0A. Plot of estimated against true states
(nominal car, clipped-optimal-wk, seed 1): ``--plot PNG``.

Usage::

    .venv/bin/python bench/bench_sensing.py [--seeds 1 2 3] [--duration 60]
        [--conditions nominal ...] [--plot docs/sensing_states.png] [--json OUT.json]
"""
import argparse
import json
import os
from pathlib import Path
import statistics
import time

from mr_damper_model.models.plant import make_plant
from mr_damper_rig.virtual_rig import identify_damper
from semi_active_control.laws import make_controller, Passive
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import iso8608
from quarter_car_sim.simulate.sensed_loop import ERROR_STATES, simulate_sensed, true_values
from semi_active_control.estimation.sensor_specs import accelerometer_spec, default_specs
from quarter_car_sim.simulate.quarter_car import make_inverse, simulate

LAWS = ('skyhook', 'sh-add', 'clipped-optimal', 'clipped-optimal-wk')
NOMINAL = QuarterCarParams()
CONDITIONS = {
    'nominal': {},
    'm_s +20%': {'m_s': NOMINAL.m_s * 1.2}, 'm_s -20%': {'m_s': NOMINAL.m_s * 0.8},
    'k_s +20%': {'k_s': NOMINAL.k_s * 1.2}, 'k_s -20%': {'k_s': NOMINAL.k_s * 0.8},
    'k_t +20%': {'k_t': NOMINAL.k_t * 1.2}, 'k_t -20%': {'k_t': NOMINAL.k_t * 0.8},
    'bias drift': {},
}
KEYS = ('rms_body_accel_wk', 'rms_tyre_load_ratio')
#: Display scale and unit of each estimation error.
ERR_UNITS = {'travel': (1e3, 'mm'), 'v_s': (1.0, 'm/s'), 'tyre_def': (1e3, 'mm'),
             'v_u': (1.0, 'm/s'), 'v_rel': (1.0, 'm/s'), 'a_s': (1.0, 'm/s2')}


def specs_for(condition):
    """Return the sensor set of a condition (the defaults, or drifting accelerometer bias)."""
    specs = default_specs()
    if condition == 'bias drift':
        specs['body_accel'] = accelerometer_spec(bias_drift=0.005, bias_rw=5e-3)
    return specs


def plot_states(res, path, t0=10.0, t1=12.0):
    """Write estimated against true states over ``t0 .. t1`` [s] to ``path`` (small PNG)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    sim, est = res.sim, res.est
    truth = true_values(sim)
    sel = (sim.t >= t0) & (sim.t <= t1)
    panels = (('v_s', 'body velocity [m/s]', 1.0), ('v_rel', 'suspension velocity [m/s]', 1.0),
              ('tyre_def', 'tyre deflection [mm]', 1e3), ('v_u', 'wheel velocity [m/s]', 1.0))
    fig, axes = plt.subplots(2, 2, figsize=(8, 4.8), sharex=True)
    for ax, (key, label, sc) in zip(axes.ravel(), panels):
        ax.plot(sim.t[sel], sc * truth[key][sel], 'k', lw=1.0, label='true')
        ax.plot(sim.t[sel], sc * est[key][sel], 'r', lw=0.8, alpha=0.8, label='estimated')
        ax.set_ylabel(label, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc='upper right')
    for ax in axes[1]:
        ax.set_xlabel('t [s]', fontsize=8)
    fig.suptitle('clipped-optimal-wk on estimated states, ISO 8608 C at 20 m/s (seed 1)',
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    plt.close(fig)


def main(argv=None):
    """Run the benchmark."""
    ap = argparse.ArgumentParser(description='sensing benchmark (see module docstring)')
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--speed', type=float, default=20.0)
    ap.add_argument('--conditions', nargs='+', default=list(CONDITIONS),
                    choices=list(CONDITIONS))
    ap.add_argument('--laws', nargs='+', default=list(LAWS), choices=list(LAWS))
    ap.add_argument('--plot', metavar='PNG', help='estimated against true states (nominal)')
    ap.add_argument('--json', metavar='OUT.json', help='also write the figures as JSON')
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    load0 = os.getloadavg()
    plant = make_plant('spencer')
    ident = identify_damper(plant, seed=0)
    inverse = make_inverse(ident)
    roads = {s: iso8608('C', args.speed, args.duration, 1e-3, rng=s) for s in args.seeds}
    out = {}
    print(f'Spencer plant, ISO 8608 C @ {args.speed:g} m/s, {args.duration:g} s, seeds '
          f'{args.seeds}, medians; identified nrmse '
          f'{ident["metrics"].get("nrmse_percent", float("nan")):.2f} %; load at start {load0}')
    err_head = ' '.join(f'{k + "[" + u + "]":>13s}' for k, (_, u) in ERR_UNITS.items())
    print(f'{"condition":11s} {"law":19s} {"Wk ideal":>8s} {"Wk est":>7s} {"dWk%":>6s} '
          f'{"tyre id":>7s} {"tyre est":>8s} {"dTyre%":>6s} {"fs%":>5s} {err_head}')
    for cond in args.conditions:
        car = NOMINAL.replace(**CONDITIONS[cond])
        specs = specs_for(cond)
        passive = [simulate(car, roads[s], Passive(0.0), plant, inverse=inverse).metrics()
                   for s in args.seeds]
        rows = {'passive@0.0A': {k: statistics.median(m[k] for m in passive) for k in KEYS}}
        for law in args.laws:
            ideal, vehicle, errs, fs = [], [], [], []
            for s in args.seeds:
                c = make_controller(law, params=NOMINAL, inverse=inverse)
                ideal.append(simulate(car, roads[s], c, plant, inverse=inverse).metrics())
                c = make_controller(law, params=NOMINAL, inverse=inverse)
                res = simulate_sensed(car, roads[s], c, plant, inverse, specs=specs,
                                      nominal=NOMINAL, rng=s)
                m = res.metrics()
                vehicle.append(m)
                errs.append(m)
                fs.append(m['estimate_invalid_fraction'])
                if args.plot and cond == 'nominal' and law == 'clipped-optimal-wk' and s == 1:
                    Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
                    plot_states(res, args.plot)
            row = {f'{k}_ideal': statistics.median(m[k] for m in ideal) for k in KEYS}
            row.update({f'{k}_est': statistics.median(m[k] for m in vehicle) for k in KEYS})
            row.update({f'est_rms_error_{k}': statistics.median(m[f'est_rms_error_{k}']
                                                                for m in errs)
                        for k in ERROR_STATES})
            row.update({f'est_rel_error_{k}': statistics.median(m[f'est_rel_error_{k}']
                                                                for m in errs)
                        for k in ERROR_STATES})
            row['invalid_fraction'] = max(fs)
            row['dwk_pct'] = 100.0 * (row['rms_body_accel_wk_est']
                                      / row['rms_body_accel_wk_ideal'] - 1.0)
            row['dtyre_pct'] = 100.0 * (row['rms_tyre_load_ratio_est']
                                        / row['rms_tyre_load_ratio_ideal'] - 1.0)
            rows[law] = row
            errs_txt = ' '.join(f'{sc * row["est_rms_error_" + k]:13.4f}'
                                for k, (sc, _) in ERR_UNITS.items())
            print(f'{cond:11s} {law:19s} {row["rms_body_accel_wk_ideal"]:8.4f} '
                  f'{row["rms_body_accel_wk_est"]:7.4f} {row["dwk_pct"]:6.2f} '
                  f'{row["rms_tyre_load_ratio_ideal"]:7.4f} {row["rms_tyre_load_ratio_est"]:8.4f} '
                  f'{row["dtyre_pct"]:6.2f} {100 * row["invalid_fraction"]:5.2f} {errs_txt}',
                  flush=True)
        p0 = rows['passive@0.0A']
        print(f'{cond:11s} {"passive@0.0A":19s} {p0["rms_body_accel_wk"]:8.4f} '
              f'{"":7s} {"":6s} {p0["rms_tyre_load_ratio"]:7.4f}', flush=True)
        out[cond] = rows
    verdicts = {}
    for cond, rows in out.items():
        laws = {k: v for k, v in rows.items() if k != 'passive@0.0A'}
        if not laws:
            continue
        p0 = rows['passive@0.0A']['rms_body_accel_wk']
        best = min(laws, key=lambda k: laws[k]['rms_body_accel_wk_est'])
        verdicts[cond] = {
            'worst_dwk_pct': max(v['dwk_pct'] for v in laws.values()),
            'every_law_within_3pct': all(v['dwk_pct'] <= 3.0 for v in laws.values()),
            'every_law_no_worse_tyre': all(v['dtyre_pct'] <= 0.0 for v in laws.values()),
            'worst_dtyre_pct': max(v['dtyre_pct'] for v in laws.values()),
            'best_law_est': best,
            'best_vs_passive0_pct': 100.0 * (laws[best]['rms_body_accel_wk_est'] / p0 - 1.0),
        }
        verdicts[cond]['best_5pct_below_passive0'] = verdicts[cond]['best_vs_passive0_pct'] <= -5
    for cond, v in verdicts.items():
        print(f'verdict {cond}: {json.dumps(v, default=float)}')
    if args.json:
        Path(args.json).write_text(json.dumps({'table': out, 'verdict': verdicts}, indent=1,
                                              default=float))
    print(f'load at end {os.getloadavg()}; wall {time.perf_counter() - t_start:.0f} s')


if __name__ == '__main__':
    main()
