"""
``full-car-sim``: offline full-vehicle ride study with four MR dampers.

Examples::

    full-car-sim --compare                         # passive currents, per-corner laws, modal
    full-car-sim --compare --json --duration 10 --seed 2
    full-car-sim --law modal-skyhook --road pothole --speed 10
    full-car-sim --compare --plant spencer --damper-params fit.json   # identified set
    full-car-sim --compare --sensing vehicle       # laws on the Kalman estimate (3 acc + 4 pos)
    full-car-sim --compare --laws passive@0A,full-car-clipped-optimal-wk,bound --bound-rho 0.5

Each corner has its own "true" damper plant (``--plant kwok|spencer`` or four names,
``fl,fr,rl,rr``) and its own identified Kwok-current parameters for the inverse
(``--damper-params`` one file for all corners or four comma-separated files, e.g. from
``mr-damper-identify --out``). Without ``--damper-params`` only kwok-current plants can run: the
inverse then gets the plant's own parameters (a perfect identification; the JSON says so).
``bound`` (in ``--compare``, or ``--law bound``) is the offline optimal semi-active bound
(:mod:`quarter_car_sim.bound.full_car`: full road preview, each corner's identified force map),
its current sequences replayed on the plants. The road-preview rows
(:mod:`quarter_car_sim.tools.preview_rows`: ``preview-wheelbase``, ``preview-look-ahead-ideal``,
``preview-look-ahead``, in ``--compare`` before the bound) are ``full-car-clipped-optimal-wk``
with LQ preview, fed by a simulated look-ahead sensor (``--preview-*`` options: the realistic
row's errors) or by the front wheels' road alone, and the receding-horizon MPC with the dampers'
limits on the same sensors (``preview-mpc-*``). Bad input exits with status 2 and one line on
stderr.
"""
import json
import math
import sys
import time

from quarter_car_sim.tools.cli_args import (add_preview_arguments, OneLineParser, positive,
                                            preview_options)
from semi_active_control.laws import DAMPER_LAW_NAMES
from quarter_car_sim.tools.preview_rows import FULL_CAR_ROWS as PREVIEW_ROWS

COMPARE_CURRENTS_A = (0.0, 0.5, 1.0, 1.5, 2.0)
#: Name of the offline bound among the laws.
BOUND = 'bound'
#: Per-corner laws of ``--compare`` (the quarter-car damper laws, one per corner).
COMPARE_CORNER_LAWS = ('skyhook', 'sh-add', 'clipped-optimal-wk')
PLANTS = {'kwok': 'kwok-current', 'kwok-current': 'kwok-current', 'spencer': 'spencer'}
TABLE = (('a_v', 'a_v', '{:6.3f}'), ('a_wz', 'a_wz', '{:6.3f}'),
         ('a_w_pitch', 'pitch', '{:6.3f}'), ('a_w_roll', 'roll', '{:6.3f}'),
         ('vdv_total', 'VDV', '{:6.2f}'), ('crest_max', 'crest', '{:5.1f}'),
         ('max_rms_tyre_load_ratio', 'tyre max', '{:8.3f}'))


def build_parser():
    """Return the argument parser."""
    p = OneLineParser(
        prog='full-car-sim',
        description='Full car (7 DOF) with four semi-active MR dampers: ride comparison of '
                    'full-car laws (ISO 2631-1 at the seat).')
    p.add_argument('--law', default='modal-skyhook',
                   help='modal-skyhook, full-car-clipped-optimal(-wk), passive@<I>A, '
                        'per-corner-<law> with <law> one of '
                        f'{", ".join(DAMPER_LAW_NAMES[1:])}, {", ".join(PREVIEW_ROWS)} (road '
                        'preview), or bound (the offline optimal semi-active bound) (default '
                        'modal-skyhook)')
    p.add_argument('--compare', action='store_true',
                   help='passive at each current, per-corner laws, modal skyhook, the '
                        'full-car clipped-optimal LQR (plain and ISO-weighted), the road-preview '
                        'rows and the offline bound')
    p.add_argument('--bound-rho', type=float, default=0.0, metavar='RHO',
                   help='weight of the dynamic tyre loads in the bound\'s cost (default 0: '
                        'comfort only)')
    p.add_argument('--laws', default='',
                   help='comma-separated laws for --compare instead of the default set')
    p.add_argument('--road', default='iso8608-C',
                   help='iso8608-A..H (two tracks), bump, pothole or single-bump')
    p.add_argument('--speed', type=positive('--speed'), default=20.0, metavar='M_PER_S')
    p.add_argument('--duration', type=positive('--duration'), default=30.0, metavar='S')
    p.add_argument('--seed', type=int, default=1, help='road seed')
    p.add_argument('--dt', type=positive('--dt'), default=1e-3, help='control period [s]')
    p.add_argument('--plant', default='kwok',
                   help='true damper of every corner (kwok or spencer) or four, fl,fr,rl,rr')
    p.add_argument('--damper-params', default='', metavar='PARAMS.json',
                   help='identified kwok-current parameter file for every corner, or four '
                        'comma-separated files')
    p.add_argument('--zeta', default='',
                   help='modal skyhook damping ratios heave,pitch,roll (default '
                        'DEFAULT_MODAL_ZETA)')
    p.add_argument('--sensing', choices=('ideal', 'vehicle'), default='ideal',
                   help='ideal: the laws read the true state; vehicle: they read the full-car '
                        'Kalman estimate from three body accelerometers (fl, fr, rl) and four '
                        'position sensors (default ideal)')
    add_preview_arguments(p)
    p.add_argument('--json', action='store_true', help='print one JSON object')
    return p


def _four(text, what):
    items = [s.strip() for s in str(text).split(',') if s.strip()]
    if len(items) == 1:
        items *= 4
    if len(items) != 4:
        raise ValueError(f'{what}: give one value or four (fl,fr,rl,rr), got {len(items)}')
    return items


def _laws(args):
    if args.compare:
        if args.laws:
            return [s.strip() for s in args.laws.split(',') if s.strip()]
        return ([f'passive@{i:g}A' for i in COMPARE_CURRENTS_A]
                + [f'per-corner-{n}' for n in COMPARE_CORNER_LAWS]
                + ['modal-skyhook', 'full-car-clipped-optimal', 'full-car-clipped-optimal-wk']
                + list(PREVIEW_ROWS) + [BOUND])
    return [args.law]


def run(args):
    """Run the study for parsed ``args``; return the JSON-ready dict."""
    from mr_damper_model.models import presets
    from mr_damper_common.health import finite_or_none
    from mr_damper_model.models.plant import make_plant
    from semi_active_control.laws.registry import make_full_car_law
    from semi_active_control.car.full_car import CORNERS, PASSENGER_CAR
    from quarter_car_sim.plant.two_track_road import make_two_track_road
    from quarter_car_sim.simulate.full_car import compare_laws

    params = PASSENGER_CAR
    plant_names = []
    for name in _four(args.plant, '--plant'):
        if name not in PLANTS:
            raise ValueError(f'unknown plant {name!r} (use kwok or spencer)')
        plant_names.append(PLANTS[name])
    zeta = None
    if args.zeta:
        try:
            z = [float(v) for v in args.zeta.split(',')]
        except ValueError:
            raise ValueError(f'--zeta must be three numbers, got {args.zeta!r}') from None
        if len(z) != 3 or not all(math.isfinite(v) and v >= 0 for v in z):
            raise ValueError(f'--zeta must be three numbers >= 0, got {args.zeta!r}')
        zeta = dict(zip(('heave', 'pitch', 'roll'), z))
    if not (math.isfinite(args.bound_rho) and args.bound_rho >= 0):
        raise ValueError(f'--bound-rho must be >= 0, got {args.bound_rho}')
    names = [n.strip().lower() for n in _laws(args)]
    popts = preview_options(args)
    laws = [make_full_car_law(name, params, dt=args.dt, zeta=zeta)
            for name in names if name != BOUND and name not in PREVIEW_ROWS]
    road = make_two_track_road(args.road, params, speed_m_s=args.speed,
                               duration_s=args.duration, dt=args.dt, rng=args.seed)
    plants = [make_plant(n) for n in plant_names]
    if args.damper_params:
        damper = _four(args.damper_params, '--damper-params')
        source = {c: f for c, f in zip(CORNERS, damper)}
    else:
        if any(n != 'kwok-current' for n in plant_names):
            raise ValueError('a spencer plant needs --damper-params (identified kwok-current '
                             'parameters, e.g. from mr-damper-identify --out)')
        damper = [presets.thesis_kwok_current()[1]] * 4
        source = 'kwok-current plant truth (no identification run)'
    metrics = compare_laws(params, road, laws, plants, damper, dt=args.dt,
                           sensing=args.sensing, sensor_seed=args.seed)
    for name in (n for n in names if n in PREVIEW_ROWS):
        metrics[name] = _preview(name, params, road, plants, damper, popts, args)
    if BOUND in names:
        metrics.update(_bound(params, road, plants, damper, args))
    return finite_or_none({
        'road': road.name, 'speed_m_s': args.speed, 'duration_s': args.duration,
        'seed': args.seed, 'dt_s': args.dt, 'sensing': args.sensing,
        'plants': dict(zip(CORNERS, plant_names)),
        'damper_params': source, 'car': params.to_dict(), 'laws': metrics,
    })


def _preview(name, params, road, plants, damper, options, args):
    """Run one preview row; return its metrics with its settings and counters."""
    from quarter_car_sim.simulate.full_car import simulate_full_car
    from quarter_car_sim.tools.preview_rows import full_car_preview_row
    law = full_car_preview_row(name, params, road, options, dt=args.dt, damper=damper)
    res = simulate_full_car(params, road, law, plants, damper, dt=args.dt, sensing=args.sensing,
                            sensor_seed=args.seed)
    m = res.metrics(params)
    est = res.status.pop('estimation', None)
    if est is not None:
        m['estimation'] = est
    m['failsafe_corners'] = [c for c, st in res.status.items() if st['mode'] != 'normal']
    m['wall_time_s'] = res.wall_time_s
    m['preview'] = {**options.to_dict(name), **law.status()}
    return m


def _bound(params, road, plants, damper, args):
    """Run the offline bound; return ``{name: metrics of its replay}``."""
    from quarter_car_sim.bound.full_car import corner_force_model, full_car_bound
    start = time.perf_counter()
    models = [corner_force_model(d, params) for d in damper]
    res = full_car_bound(params, road, models, plants, damper, rho=args.bound_rho, dt=args.dt)
    m = res.metrics(params)
    m['failsafe_corners'] = [c for c, st in res.replay.status.items() if st['mode'] != 'normal']
    m['wall_time_s'] = time.perf_counter() - start
    m['bound'] = {'rho': res.rho, 'cost': res.cost, 'cost_start': res.cost_start,
                  'outer_iterations': res.nit, 'predicted_a_v': res.predicted_metrics['a_v'],
                  'predicted_max_rms_tyre_load_ratio':
                      res.predicted_metrics['max_rms_tyre_load_ratio'],
                  'what': 'offline: full road preview, each corner\'s identified force map; '
                          'its currents replayed open loop on the plants (no sensing)'}
    return {res.replay.law: m}


def _cell(v, fmt):
    if v is None:
        return ' ' * (len(fmt.format(0.0)) - 1) + '-'
    return fmt.format(v)


def table(out):
    """Return the text table of a :func:`run` result."""
    head = f'{"law":30s}' + ''.join(f' {h:>{len(fmt.format(0.0))}s}' for _, h, fmt in TABLE)
    lines = [f'road {out["road"]}, {out["duration_s"]:g} s, sensing {out["sensing"]}',
             head]
    for name, m in out['laws'].items():
        lines.append(f'{name:30s}' + ''.join(' ' + _cell(m.get(k), fmt) for k, _, fmt in TABLE))
    lines.append('a_v: ISO 2631-1 vibration total value at the CG [m/s^2] (Wk vertical, We '
                 'pitch x 0.40, We roll x 0.63); a_wz [m/s^2], pitch, roll [rad/s^2]: weighted '
                 'RMS; VDV [m/s^1.75]; crest: largest crest factor; tyre max: largest RMS '
                 'dynamic tyre load / static load of the four wheels')
    return '\n'.join(lines)


def main(argv=None):
    """Console entry point; returns the exit status (2 on bad input)."""
    args = build_parser().parse_args(argv)
    try:
        out = run(args)
    except (ValueError, OSError, KeyError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f'full-car-sim: error: {msg}', file=sys.stderr)
        return 2
    print(json.dumps(out, allow_nan=False) if args.json else table(out))
    return 0


if __name__ == '__main__':
    sys.exit(main())
