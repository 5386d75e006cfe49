"""
Benchmark: hardware-in-the-loop quarter car on the virtual rig vs the damper model in the loop.

Skyhook (true Kwok-current parameters through the supervisor) on an ISO 8608 class C road at
20 m/s, 1 kHz, fixed seeds. Prints, in one run:

- tracking error of the rig (RMS / peak of desired vs measured displacement, remaining delay)
  for a first- and a second-order servo actuator (2 ms transport delay), without compensation,
  with polynomial extrapolation, and with the adaptive horizon;
- ride metrics (Wk-weighted body acceleration RMS, travel RMS, tyre load RMS) of each HIL run
  against model-in-the-loop (ratio);
- the ROS 2 link simulated in one process (``car_in_the_loop.SimulatedLink``: the rig node's
  guarded actuator, the car's ``RemoteRigPlant``) with 0, 5 and 20 ms of message latency: tracking
  error and ride against model-in-the-loop, without compensation, with the fixed horizon and
  with the adaptive one;
- the comfort cost of the current probe (Wk RMS increase) and per-bin sample counts with and
  without probing.

Saves the tracking and bin-count plot to ``--plot`` (default ``bench_out/bench_hil.png``;
``docs/hil_bench.png`` is this plot). Usage::

    .venv/bin/python bench/bench_hil.py --seconds 20 [--plot docs/hil_bench.png]
"""
import argparse
import os
from pathlib import Path

from mr_damper_model.models.plant import make_plant
from mr_damper_bringup import car_in_the_loop as cil
from quarter_car_sim import hil, live_loop
from quarter_car_sim.controllers import make_controller
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.probing import CurrentProbe
from quarter_car_sim.road import make_road

DT = 1e-3
BENCH_OUT = Path(__file__).resolve().parents[1] / 'bench_out'


def _truth_msg():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    return dict(params, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
                valid=1.0)


def run(plant, seconds, probe=None):
    """Skyhook on ISO C with ``plant`` as the car's damper; return (record, ride metrics)."""
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=7,
                     duration_s=seconds)
    car = QuarterCar(params, plant, road, t0=0.0)
    sup = ModelSupervisor(timeout_s=1e9, safe_current_a=0.5)
    sup.offer(_truth_msg(), 0.0)
    metrics = live_loop.make_running_metrics(params)
    loop = live_loop.ClosedLoop(car, make_controller('skyhook', damper_only=True), sup, DT,
                                metrics=metrics)
    return hil.run_loop(loop, seconds, probe=probe), metrics.as_dict()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seconds', type=float, default=20.0, help='HIL runs [s]')
    ap.add_argument('--probe-seconds', type=float, default=100.0, help='probing runs [s]')
    ap.add_argument('--plot', metavar='PNG', default=str(BENCH_OUT / 'bench_hil.png'),
                    help='tracking and bin-count plot (default bench_out/bench_hil.png)')
    args = ap.parse_args()
    print(f'load (uptime): {os.getloadavg()}')
    ride_keys = ('rms_body_accel_wk', 'rms_suspension_travel', 'rms_tyre_load_ratio')
    rec_ref, ref = run(make_plant('kwok-current'), args.seconds)
    print('model in the loop: ' + ', '.join(f'{k} {ref[k]:.4g}' for k in ride_keys))
    cases = [('ideal', 'none', 0.0), ('first', 'none', 0.0), ('first', 'poly', 0.0),
             ('first', 'poly', 2.0), ('second', 'none', 0.0), ('second', 'poly', 0.0),
             ('second', 'poly', 2.0)]
    print(f'{"actuator":8s} {"comp":10s} {"rms_mm":>8s} {"peak_mm":>8s} {"delay_ms":>9s} '
          f'{"horizon_ms":>10s} ' + ' '.join(f'{k + "/ref":>26s}' for k in ride_keys))
    records = {}
    for kind, comp, gain in cases:
        plant = cil.make_hil_plant(actuator=kind, compensation=comp, adapt_gain=gain, rng=1)
        rec, ride = run(plant, args.seconds)
        tr = plant.monitor.as_dict()
        label = comp if gain == 0 else 'adaptive'
        horizon = plant.compensator.delay_s * 1e3 if plant.compensator else float('nan')
        print(f'{kind:8s} {label:10s} {tr["rms_m"] * 1e3:8.3f} {tr["peak_m"] * 1e3:8.3f} '
              f'{tr["delay_s"] * 1e3:9.2f} {horizon:10.2f} '
              + ' '.join(f'{ride[k] / ref[k]:26.3f}' for k in ride_keys))
        records[(kind, label)] = rec
    # the ROS 2 link, simulated: message latency on top of the actuator
    print('ROS 2 link simulated (first-order actuator, force one sample late + latency):')
    print(f'{"latency_ms":>10s} {"comp":10s} {"rms_mm":>8s} {"peak_mm":>8s} {"horizon_ms":>10s} '
          f'{"wk/ref":>8s} {"travel/ref":>10s}')
    for latency in (0, 5, 20):
        for comp, gain in (('none', 0.0), ('poly', 0.0), ('poly', 2.0)):
            link = cil.make_simulated_link(actuator='first', compensation=comp,
                                           adapt_gain=gain, latency_steps=latency, rng=1,
                                           delay_s=0.015)
            _, ride = run(link, args.seconds)
            tr = link.monitor.as_dict()
            horizon = link.remote.compensator.delay_s * 1e3 if comp == 'poly' else float('nan')
            label = comp if gain == 0 else 'adaptive'
            print(f'{latency:10d} {label:10s} {tr["rms_m"] * 1e3:8.3f} {tr["peak_m"] * 1e3:8.3f} '
                  f'{horizon:10.2f} {ride["rms_body_accel_wk"] / ref["rms_body_accel_wk"]:8.3f} '
                  f'{ride["rms_suspension_travel"] / ref["rms_suspension_travel"]:10.3f}')
    # probing cost and bin coverage (model in the loop, so only the probe differs)
    rec_law, ref_p = run(make_plant('kwok-current'), args.probe_seconds)
    law = CurrentProbe()
    for i in rec_law['coil_current']:
        law.observe(i)
    probe = CurrentProbe()
    rec_probe, probed = run(make_plant('kwok-current'), args.probe_seconds, probe)
    cost = probed['rms_body_accel_wk'] / ref_p['rms_body_accel_wk'] - 1
    print(f'probe over {args.probe_seconds:g} s: period {probe.period_s} s, hold '
          f'{probe.hold_s} s (duty {probe.duty:.0%}), Wk RMS {ref_p["rms_body_accel_wk"]:.4g} -> '
          f'{probed["rms_body_accel_wk"]:.4g} m/s^2 (comfort cost {cost:+.1%}); all bins '
          f'covered at t = {probe.covered_s} s; bins covered (>= {probe.min_samples} samples): '
          f'law {int((law.counts >= probe.min_samples).sum())}/{law.counts.size}, '
          f'probed {int((probe.counts >= probe.min_samples).sum())}/{probe.counts.size}')
    print('bin [A]   ' + ' '.join(f'{x:6.1f}' for x in probe.levels_a))
    print('law       ' + ' '.join(f'{c:6d}' for c in law.counts))
    print('probed    ' + ' '.join(f'{c:6d}' for c in probe.counts))
    _plot(records, law, probe, Path(args.plot))


def _plot(records, law, probe, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(9, 7))
    rec = records[('first', 'none')]
    sl = slice(int(5.0 / DT), int(6.0 / DT))
    ax1.plot(rec['t'][sl], 1e3 * rec['travel'][sl], 'k', label='desired (car travel)')
    for label in ('none', 'poly', 'adaptive'):
        r = records[('first', label)]
        ax1.plot(r['t'][sl], 1e3 * r['measured'][sl], label=f'measured ({label})')
    ax1.plot(rec['t'][sl], 1e3 * records[('first', 'adaptive')]['command'][sl], ':',
             label='command (adaptive)')
    ax1.set_xlabel('t [s]')
    ax1.set_ylabel('displacement [mm]')
    ax1.set_title('first-order actuator (12 ms lag + 2 ms delay)')
    ax1.legend(fontsize=8)
    w = 0.4 * probe.bin_a
    ax2.bar(probe.levels_a - w / 2, law.counts, w, label='skyhook alone')
    ax2.bar(probe.levels_a + w / 2, probe.counts, w, label='with probe')
    ax2.set_yscale('log')
    ax2.set_xlabel('current bin [A]')
    ax2.set_ylabel('samples')
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f'plot: {path}')


if __name__ == '__main__':
    main()
