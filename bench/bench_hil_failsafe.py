"""
Benchmark: how soon a HIL car in fail-safe gets a model it may use (``--config hil``).

The car of ``suite_hil.yaml`` (skyhook, safe current 0.5 A, probe of 0.25 A bins for 0.2 s every
1 s, 500 samples a bin) drives an ISO 8608 class C road at 20 m/s on the virtual rig (first-order
actuator, polynomial compensation) and stays in fail-safe; the rig's samples go to the live
identifier with the suite's settings (0.25 A bins, 2 s windows, 0.2 s hop). Printed per road
seed, in one run, for the probe's order (``least-filled``: the previous schedule, ``farthest``:
:meth:`quarter_car_sim.probing.CurrentProbe.next_level`) and the acceptance review's velocity-bin
share check (``min_velocity_bin_share`` 0.03, the default, or 0, ``suite_hil.yaml``), each with
every window fitted (``in order``) and with one window fitted per second (``starved``: the
identifier of a loaded machine, most windows superseded):

- the car time [s] of the first valid set over at least 1 A (the car's ``min_current_span_a``),
  i.e. when the car may leave fail-safe ('-': not within the run);
- the windows fitted and the sets the review refused, by reason;
- the identification error of the refused and the taken sets over at least 1 A: NRMSE [%] on a
  cam-rig record of the same true damper (five current levels), against the truth's own.

The car never leaves fail-safe here (its supervisor gets no set), so each stream is simulated
once per probe order and replayed into each identifier variant. Usage::

    .venv/bin/python bench/bench_hil_failsafe.py [--seconds 30] [--roads 1,2,3]
"""
import argparse
import os
import platform
import time

import numpy as np

from mr_damper_bringup import car_in_the_loop as cil
from mr_damper_model.identification import presets
from mr_damper_model.live import LiveConfig, LiveIdentifier
from quarter_car_sim import live_loop
from quarter_car_sim.controllers import make_controller
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.probing import CurrentProbe
from quarter_car_sim.road import make_road

DT = 1e-3
SPAN_A = 1.0          # the car's min_current_span_a
BIN_A = 0.25          # suite_hil.yaml: the identifier's current_bin_a = the probe's bin
BATCH = 20            # samples per measurement message


class LeastFilledProbe(CurrentProbe):
    """The previous schedule: every probe window goes to the least-filled bin."""

    def next_level(self):
        """Return the least-filled bin's level [A]."""
        return float(self.levels_a[int(np.argmin(self.counts))])


def fail_safe_stream(probe, seconds, road_seed):
    """Simulate the HIL car in fail-safe with ``probe``; return the rig's samples (n, 5)."""
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=road_seed,
                     duration_s=seconds + 1.0)
    plant = cil.make_hil_plant(actuator='first', compensation='poly', rng=1)
    rows = []
    sample = plant.rig.sample

    def recorded():
        row = sample()
        rows.append(row)
        return row

    plant.rig.sample = recorded
    car = QuarterCar(params, plant, road, t0=-0.5)          # settle_s 0.5 before the road
    sup = ModelSupervisor(timeout_s=1.0, safe_current_a=0.5)  # never offered a set
    loop = live_loop.ClosedLoop(car, make_controller('skyhook', damper_only=True), sup, DT)
    for _ in range(int(round((seconds + 0.5) / DT))):
        loop.i_cmd = probe(loop.command(car.state, 0.0), car.t)
        probe.observe(loop.advance().coil_current)
    return np.asarray(rows, dtype=float)


def replay(stream, share, starved, valid_record):
    """Feed ``stream`` to the identifier; return its figures (see the module docstring)."""
    cfg = LiveConfig(current_bin_a=BIN_A, budget_s=0.0, min_velocity_bin_share=share,
                     backlog_windows=0 if starved else 300)
    ident = LiveIdentifier(cfg)
    reviewed = []
    review = ident._accept.review

    def recorded(params, fit, window):
        reason = review(params, fit, window)
        span = float(np.ptp(np.round(fit.i / BIN_A))) * BIN_A
        if span >= SPAN_A:
            reviewed.append((reason.split(':')[0] or 'taken', cil._nrmse_percent(
                dict(params, i_ref_a=cfg.i_ref_a), valid_record)))
        return reason

    ident._accept.review = recorded
    every = int(round(1.0 / DT)) if starved else BATCH
    t_origin = stream[0, 0] + 0.5                          # the road starts at car time 0
    first = None
    for k in range(0, len(stream), BATCH):
        b = stream[k:k + BATCH]
        ident.add_samples(b[:, 0], b[:, 1], b[:, 2], b[:, 3], b[:, 4])
        if (k + BATCH) % every:
            continue
        while (window := ident.next_window()) is not None:
            est = ident.process(window)
            if (first is None and est is not None and est.valid
                    and est.current_max_a - est.current_min_a >= SPAN_A):
                first = window.end_s - t_origin
    status = ident.status()
    return {'first_s': first, 'fitted': status['windows_fitted'],
            'refused': dict(status['windows_refused']), 'reviewed': reviewed}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seconds', type=float, default=30.0, help='car time per run [s]')
    ap.add_argument('--roads', default='1,2,3', help='road seeds')
    args = ap.parse_args()
    print(f'machine: {platform.machine()}, {os.cpu_count()} cores; load (uptime) '
          f'{os.getloadavg()[0]:.2f} at the start')
    model, truth = presets.thesis_kwok_current()
    valid_record = cil.cam_rig_record('kwok-current', seed=5)
    truth_nrmse = cil._nrmse_percent(dict(truth, i_ref_a=model.options['i_ref_a']),
                                     valid_record)
    print(f'cam-rig record NRMSE of the true parameters (noise floor): {truth_nrmse:.3f} %')
    print(f'{"road":>4s} {"probe":>12s} {"share":>5s} {"identifier":>10s} '
          f'{"first set >= 1 A [s]":>20s} {"fitted":>6s}  refused')
    errors = {}
    t0 = time.perf_counter()
    for road in [int(r) for r in args.roads.split(',')]:
        for order, cls in (('least-filled', LeastFilledProbe), ('farthest', CurrentProbe)):
            probe = cls(0.0, 2.0, bin_a=BIN_A, period_s=1.0, hold_s=0.2, min_samples=500)
            stream = fail_safe_stream(probe, args.seconds, road)
            for share in (LiveConfig().min_velocity_bin_share, 0.0):
                for starved in (False, True):
                    r = replay(stream, share, starved, valid_record)
                    first = '-' if r['first_s'] is None else f'{r["first_s"]:.1f}'
                    refused = ', '.join(f'{k} {v}' for k, v in sorted(r['refused'].items()))
                    print(f'{road:4d} {order:>12s} {share:5.2f} '
                          f'{"starved" if starved else "in order":>10s} {first:>20s} '
                          f'{r["fitted"]:6d}  {refused or "-"}', flush=True)
                    for reason, e in r['reviewed']:
                        errors.setdefault(reason, []).append(e)
    print('sets over >= 1 A reviewed, all runs: cam-rig record NRMSE [%] (truth '
          f'{truth_nrmse:.3f} %)')
    for reason, e in sorted(errors.items()):
        e = np.asarray(e)
        print(f'  {reason:>20s}: {e.size:5d} sets, p50 {np.median(e):.3f}, p90 '
              f'{np.percentile(e, 90):.3f}, max {e.max():.3f}')
    print(f'load (uptime) {os.getloadavg()[0]:.2f} at the end; {time.perf_counter() - t0:.0f} s')


if __name__ == '__main__':
    main()
