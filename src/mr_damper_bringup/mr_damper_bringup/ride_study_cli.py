"""
``quarter-car-sim``: offline quarter-car ride study with an MR damper.

Examples::

    quarter-car-sim --compare                       # identify the plant, all controllers + bound
    quarter-car-sim --controller skyhook --road bump --speed 10 --json
    quarter-car-sim --compare --damper-params fit.json --plant kwok --plot ride.png

Without ``--damper-params`` the tool first runs a simulated rig test of the plant and identifies
kwok-current parameters with ``mr_damper_model.identification.identify``; the controllers only
ever see those.
``--compare`` also runs the road-preview rows (``quarter_car_sim.preview_rows``:
``clipped-optimal-wk`` with LQ preview fed by a simulated look-ahead sensor, ideal and with the
``--preview-*`` errors) and the offline optimal semi-active bound (``quarter_car_sim.bound``,
full road preview, comfort only), listing its current sequence replayed on the plant as
``bound``.
Bad input exits with status 2 and one line on stderr.

It lives in ``mr_damper_bringup``, above the rig and the car, because it needs both the rig
(the simulated identification test, :func:`mr_damper_rig.virtual_rig.simulated_rig_data`) and
the car; neither of those two packages imports the other.
"""
import json
import sys

from quarter_car_sim.cli_args import (add_preview_arguments, OneLineParser, positive,
                                      preview_options)
from quarter_car_sim.controllers import CONTROLLER_NAMES
from quarter_car_sim.preview_rows import QUARTER_CAR_ROWS as PREVIEW_ROWS

PLANTS = {'kwok': 'kwok-current', 'kwok-current': 'kwok-current', 'spencer': 'spencer'}
COMPARE_CURRENTS_A = (0.0, 0.5, 1.0, 1.5, 2.0)
#: Every law of the factory but the passive settings (those are run at COMPARE_CURRENTS_A).
COMPARE_NAMES = tuple(n for n in CONTROLLER_NAMES if n != 'passive@<I>A')
TABLE_KEYS = (('rms_body_accel_wk', 'Wk acc', '{:8.3f}'), ('rms_body_accel', 'acc', '{:7.3f}'),
              ('rms_suspension_travel', 'travel mm', '{:9.1f}'),
              ('rms_tyre_load_ratio', 'tyre', '{:6.3f}'),
              ('mean_current_a', 'I mean', '{:6.2f}'),
              ('saturated_fraction', 'sat', '{:5.2f}'))


def build_parser():
    """Return the argument parser."""
    p = OneLineParser(
        prog='quarter-car-sim',
        description='Quarter car with a semi-active MR damper: ride comparison of controllers.')
    p.add_argument('--controller', default='skyhook',
                   help=f'{", ".join(CONTROLLER_NAMES + PREVIEW_ROWS)} (default skyhook)')
    p.add_argument('--compare', action='store_true',
                   help='run every controller, the road-preview rows and the offline semi-active '
                        'bound on the same road')
    p.add_argument('--road', default='iso8608-C',
                   help='iso8608-A..H, bump, sine, step or FILE.csv (default iso8608-C)')
    p.add_argument('--speed', type=positive('--speed'), default=20.0, metavar='M_PER_S',
                   help='vehicle speed [m/s] (default 20)')
    p.add_argument('--duration', type=positive('--duration'), default=30.0, metavar='S',
                   help='simulated time [s] (default 30)')
    p.add_argument('--damper-params', metavar='PARAMS.json',
                   help='identified kwok-current parameter file (default: identify the plant '
                        'from a simulated rig test first)')
    p.add_argument('--plant', choices=('kwok', 'spencer'), default='spencer',
                   help='true damper: thesis-like kwok-current or Spencer (default spencer)')
    p.add_argument('--seed', type=int, default=1, help='road (and identification) seed')
    p.add_argument('--dt', type=positive('--dt'), default=1e-3, help='control period [s]')
    p.add_argument('--sensing', choices=('ideal', 'vehicle'), default='ideal',
                   help='ideal: the laws read the true car state; vehicle: they read the state '
                        'a Kalman filter estimates from modelled automotive sensors (body '
                        'accelerometer, ride-height sensor; docs/sensing.md)')
    add_preview_arguments(p)
    p.add_argument('--json', action='store_true', help='print one JSON object')
    p.add_argument('--plot', metavar='OUT.png', help='write time traces, PSD, '
                   'transmissibility and current plots')
    return p


def run(args):
    """Run the study for parsed ``args``; return the JSON-ready dict and the results."""
    from mr_damper_common.health import finite_or_none
    from mr_damper_model.models.plant import make_plant
    from mr_damper_rig.virtual_rig import identify_damper
    from quarter_car_sim.bound import bound_name, KwokForceModel, semi_active_bound
    from quarter_car_sim.controllers import make_controller, Passive
    from quarter_car_sim.params import QuarterCarParams
    from quarter_car_sim.preview_rows import quarter_car_preview_row
    from quarter_car_sim.road import make_road
    from quarter_car_sim.simulate import compare, make_inverse

    params = QuarterCarParams()
    road = make_road(args.road, speed_m_s=args.speed, duration_s=args.duration, dt=args.dt,
                     rng=args.seed)
    popts = preview_options(args)
    has_speed = road.speed_m_s > 0          # nan for a road in time only
    if args.compare:
        rows = list(PREVIEW_ROWS) if has_speed else []   # no preview on a road without speed
    elif args.controller in PREVIEW_ROWS:
        rows = [args.controller]
        if not has_speed:
            raise ValueError(f'road {args.road!r} has no speed: the preview rows need one')
    else:
        rows = []
    if not args.compare and not rows:
        make_controller(args.controller, params=params)     # bad name: fail before identifying
    plant = make_plant(PLANTS[args.plant])
    if args.damper_params:
        inverse = make_inverse(args.damper_params, i_min=params.i_min, i_max=params.i_max)
        ident = {'source': str(args.damper_params)}
    else:
        if not args.json:
            print(f'identifying the {args.plant} damper from a simulated rig test ...',
                  file=sys.stderr)
        d = identify_damper(plant, seed=args.seed)
        inverse = make_inverse(d, i_min=params.i_min, i_max=params.i_max)
        ident = {'source': 'identified from simulated rig test', 'metrics': d['metrics']}
    ident['parameters'] = inverse.params
    if args.compare:
        controllers = [Passive(i) for i in COMPARE_CURRENTS_A]
        controllers += [make_controller(n, params=params, inverse=inverse, dt=args.dt)
                        for n in COMPARE_NAMES]
    elif not rows:
        controllers = [make_controller(args.controller, params=params, inverse=inverse,
                                       dt=args.dt)]
    else:
        controllers = []
    previewed = {n: quarter_car_preview_row(n, params, road, inverse, popts, dt=args.dt)
                 for n in rows}
    controllers += list(previewed.values())
    sensed = {}
    if args.sensing == 'vehicle':
        from quarter_car_sim.sensed_loop import simulate_sensed
        damper_laws = [c for c in controllers if c.kind in ('current', 'semi-active')]
        for c in damper_laws:
            sensed[c.name] = simulate_sensed(params, road, c, plant, inverse, dt=args.dt,
                                             rng=args.seed)
        controllers = [c for c in controllers if c.name not in sensed]
    results = compare(params, road, controllers, plant, dt=args.dt, damper_params=inverse)
    results.update({n: r.sim for n, r in sensed.items()})
    if args.compare:
        results[bound_name()] = semi_active_bound(params, road, KwokForceModel(inverse), plant,
                                                  dt=args.dt).replay
    out = {
        'road': road.name, 'speed_m_s': args.speed, 'duration_s': args.duration,
        'seed': args.seed, 'plant': PLANTS[args.plant], 'dt_s': args.dt,
        'sensing': args.sensing, 'damper_params': finite_or_none(ident),
        'controllers': {n: finite_or_none(_metrics(n, r, sensed)) for n, r in results.items()},
    }
    for n, c in previewed.items():
        out['controllers'][n]['preview'] = finite_or_none({**popts.to_dict(n), **c.status()})
    return out, results


def _metrics(name, result, sensed):
    """Metrics of one run; on estimated states plus the estimation errors and counters."""
    if name not in sensed:
        return result.metrics()
    m = sensed[name].metrics()
    m['estimator'] = sensed[name].status
    return m


def _table(out):
    head = f'{"controller":16s}' + ''.join(f' {h:>{len(fmt.format(0.0))}s}'
                                           for _, h, fmt in TABLE_KEYS)
    lines = [f'road {out["road"]}, {out["duration_s"]:g} s, plant {out["plant"]}, '
             f'sensing {out["sensing"]}', head]
    for name, m in out['controllers'].items():
        cells = []
        for key, _, fmt in TABLE_KEYS:
            v = m.get(key)
            if v is None:
                cells.append(' ' + ' ' * (len(fmt.format(0.0)) - 1) + '-')
            else:
                cells.append(' ' + fmt.format(v * 1000 if key == 'rms_suspension_travel' else v))
        lines.append(f'{name:16s}' + ''.join(cells))
    lines.append('Wk acc, acc: RMS body acceleration [m/s^2] (ISO 2631-1 Wk, raw); travel: RMS '
                 'suspension travel [mm]; tyre: RMS dynamic tyre load / static load; I mean: '
                 'mean current command [A]; sat: fraction of time saturated')
    return '\n'.join(lines)


def main(argv=None):
    """Console entry point; returns the exit status (2 on bad input)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        out, results = run(args)
        if args.plot:
            from quarter_car_sim.plots import plot_results
            plot_results(results, args.plot)
    except (ValueError, OSError, KeyError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f'quarter-car-sim: error: {msg}', file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(out, allow_nan=False))
    else:
        print(_table(out))
    return 0


if __name__ == '__main__':
    sys.exit(main())
