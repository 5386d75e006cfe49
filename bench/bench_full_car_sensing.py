#!/usr/bin/env python3
"""
Full car (issue 24): each law on the true state against the production sensing's estimate.

Passenger car, kwok-current plant at each corner with its own parameters in the inverse (the
plant truth: the loss measured is that of sensing alone). Roads ISO 8608 class C at 20 m/s,
two tracks, seeds 1 2 3; sensors seeded as the road. For each law: median over seeds of the
ISO 2631-1 vibration total value a_v and of the worst wheel's RMS dynamic tyre load / static
load, with ``sensing='ideal'`` and ``'vehicle'`` (full-car Kalman filter on three body
accelerometers fl/fr/rl and four position sensors), the loss in %, and the median RMS
estimation error per state group.

Usage::

    .venv/bin/python bench/bench_full_car_sensing.py [--seeds 1 2 3] [--duration 20] [--laws A,B]
"""
import argparse
import os
import statistics
import time

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import compare_laws
from semi_active_control.car.full_car import PASSENGER_CAR

LAWS = ('passive@0A', 'per-corner-skyhook', 'per-corner-sh-add',
        'per-corner-clipped-optimal-wk', 'modal-skyhook', 'full-car-clipped-optimal',
        'full-car-clipped-optimal-wk')


def main(argv=None):
    """Run the bench and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--duration', type=float, default=20.0)
    ap.add_argument('--laws', default=','.join(LAWS), help='comma-separated laws to run')
    args = ap.parse_args(argv)
    laws = [name.strip() for name in args.laws.split(',') if name.strip()]
    print(f'load average at start {os.getloadavg()}', flush=True)
    t0 = time.time()
    plants = [make_plant('kwok-current') for _ in range(4)]
    damper = [presets.thesis_kwok_current()[1]] * 4
    runs = {}
    for seed in args.seeds:
        road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0,
                                   duration_s=args.duration, rng=seed)
        for sensing in ('ideal', 'vehicle'):
            out = compare_laws(PASSENGER_CAR, road, laws, plants, damper,
                               sensing=sensing, sensor_seed=seed)
            for name, m in out.items():
                runs.setdefault((name, sensing), []).append(m)
    print(f'\nISO 8608 C, 20 m/s, two tracks, {args.duration:g} s, seeds {args.seeds} '
          '(medians)')
    print(f'{"law":32s} {"a_v ideal":>9s} {"a_v est":>8s} {"loss %":>7s} '
          f'{"tyre ideal":>10s} {"tyre est":>8s} {"loss %":>7s}   est. RMS error '
          'body rates [m/s, rad/s] / wheel v [m/s] / travel [mm] / tyre def [mm]')
    for name in dict.fromkeys(n for n, _ in runs):
        vals = {}
        for sensing in ('ideal', 'vehicle'):
            ms = runs[(name, sensing)]
            vals[sensing] = (statistics.median(m['a_v'] for m in ms),
                             statistics.median(m['max_rms_tyre_load_ratio'] for m in ms))
        (a0, t0_), (a1, t1) = vals['ideal'], vals['vehicle']
        est = [m['estimation']['rms_error'] for m in runs[(name, 'vehicle')]]

        def grp(g, scale=1.0):
            return statistics.median(max(e[g]) for e in est) * scale

        print(f'{name:32s} {a0:9.3f} {a1:8.3f} {100 * (a1 / a0 - 1):7.1f} {t0_:10.3f} '
              f'{t1:8.3f} {100 * (t1 / t0_ - 1):7.1f}   {grp("body_rates"):.4f} / '
              f'{grp("wheel_v"):.3f} / {grp("travel", 1e3):.2f} / {grp("tyre_def", 1e3):.2f}')
    inv = [m['estimation']['invalid_steps'] for (n, s), ms in runs.items() if s == 'vehicle'
           for m in ms]
    print(f'\ninvalid estimate steps (per run): {inv[:3]} ...')
    print(f'wall {time.time() - t0:.0f} s, load average at end {os.getloadavg()}')


if __name__ == '__main__':
    main()
