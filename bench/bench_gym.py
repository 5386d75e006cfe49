#!/usr/bin/env python3
"""
The Gymnasium environments (issue 37): steps per second, and the baselines against the tools.

1. ``speed`` (steps per second; each a median of ``--repeats`` runs, wall and process CPU time,
   sensors observation, current action, Spencer plants, ISO 8608 C at 20 m/s):

   - one environment through ``gymnasium.make`` (its wrappers included), quarter and full car;
     the force action (the identified inverse in Python) as a second row;
   - the alternative it replaces: the simulator's own Python step (``QuarterCar.step`` /
     ``FullCar.step`` with the same plants, no sensors, no metrics);
   - the vector environment (``gymnasium.make_vec``), N cars in one thread and on
     ``--threads`` threads (default the cores; the compiled step releases the GIL); the
     alternative: gymnasium's ``SyncVectorEnv`` of single environments. Steps are timed on
     cars already reset (``--car-steps`` car-steps a run), as training steps a whole episode
     after one reset; the reset (a road per car, 0.5 s of settling) is timed apart (ms per
     car), and ``per episode`` is the rate over a default episode (10,000 steps) with its
     reset. The full car's last vector row has kwok-current plants: the Spencer plants' share
     of the step (ten Bouc-Wen sub-steps per damper and period).

   Goals: one full-car env >= 20,000 steps/s (20x real time at 1 kHz); the vector env >=
   200,000 car-steps/s on two cores.

2. ``baselines``: the suite's laws as policies through the env (``observation='state'``; a
   passive law as a current action, the others as force actions through the env's inverse)
   against the offline tools on the same roads: ``quarter-car-sim --controller NAME`` and
   ``full-car-sim --law NAME`` (their ``run()``, with ``--plant spencer`` and the env's
   identified set as ``--damper-params``), seeds ``--seeds`` (the road seed), ISO 8608 C at
   20 m/s, ``--duration`` s. Goal: within 1 %. With each law its cost (the mean of minus the
   reward), and on each road the passive reference and the offline bound (its replay on the
   plants) with each law's fraction of the passive-to-bound gap closed.

Usage::

    .venv/bin/python bench/bench_gym.py [--part speed|baselines|all] [--repeats 3]
                                        [--steps 5000] [--cars 64 256 1024]
                                        [--car-steps 400000] [--threads 2]
                                        [--car quarter full] [--vector-only]
                                        [--seeds 1 2 3] [--duration 20] [--no-bound]
                                        [--json OUT.json]
"""
import argparse
import json
import os
import statistics
import tempfile
import time

import gymnasium
import numpy as np

from mr_damper_bringup import ride_study_cli
import mr_damper_gym
from mr_damper_gym import roads
from mr_damper_gym.baselines import FULL_BASELINES, LawPolicy, QUARTER_BASELINES, run_episode
from mr_damper_gym.core import EnvCore
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.quarter_car import QuarterCar
from quarter_car_sim.tools import full_car_sim as full_car_cli
from quarter_car_sim.plant.full_car import FullCar

#: Steps of an episode at the defaults (10 s at 1 ms): the amortised rates' episode.
EPISODE_STEPS = 10_000
IDS = {'quarter': mr_damper_gym.QUARTER_CAR_ID, 'full': mr_damper_gym.FULL_CAR_ID}


def _rate(run, steps, repeats):
    """Median steps/s of ``run()`` (which takes ``steps`` steps): wall and CPU time."""
    walls, cpus = [], []
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        run()
        walls.append(steps / (time.perf_counter() - w))
        cpus.append(steps / (time.process_time() - c))
    return statistics.median(walls), statistics.median(cpus)


def _env_rate(car, steps, repeats, **kw):
    env = gymnasium.make(IDS[car], duration_s=steps * 1e-3 + 1.0, episode_end='none', **kw)
    env.reset(seed=1)
    a = env.action_space.low if kw.get('action', 'current') == 'current' else np.zeros(
        env.action_space.shape)

    def run():
        env.reset(seed=1)
        for _ in range(steps):
            env.step(a)
    run()                           # compiled kernel loaded, caches warm
    return _rate(run, steps, repeats)


def _simulator_rate(car, steps, repeats):
    """Time the alternative: the simulator's Python car step with the same plants."""
    core = EnvCore(car, plant='spencer', episode_end='none')
    spec = roads.road_spec(core.defaults, {'road_seed': 1, 'duration_s': steps * 1e-3 + 1},
                           None)
    road = roads.build_road(car, core.params, spec, core.dt)
    if car == 'quarter':
        sim = QuarterCar(core.params, make_plant('spencer'), road)
        cmd = 0.0
    else:
        sim = FullCar(core.params, [make_plant('spencer') for _ in range(4)], road)
        cmd = [0.0] * 4

    def run():
        sim.reset()
        for _ in range(steps):
            sim.step(1e-3, cmd)
    return _rate(run, steps, repeats)


def _vector_rate(car, n, steps, repeats, **kw):
    """
    Time N cars of a vector env (``threads``), or gymnasium's SyncVectorEnv of N envs.

    The steps are timed on episodes already reset (as in training, where one reset serves a
    whole episode: 10,000 steps at the defaults); the reset of the N cars (a road each, then
    0.5 s of settling) is timed apart. Returns the steps' wall and CPU rates and the reset's
    wall time [s].
    """
    venv = gymnasium.make_vec(IDS[car], num_envs=n, episode_end='none',
                              duration_s=(repeats + 1) * steps * 1e-3 + 1.0, **kw)
    a = np.tile(venv.single_action_space.low, (n, 1))
    t = time.perf_counter()
    venv.reset(seed=1)
    reset_s = time.perf_counter() - t

    def run():
        for _ in range(steps):
            venv.step(a)
    run()                           # compiled kernel loaded, caches warm
    wall, cpu = _rate(run, steps * n, repeats)
    venv.close()
    return wall, cpu, reset_s


def _amortised(rate, reset_s, n, episode_steps=EPISODE_STEPS):
    """Car-steps/s over whole episodes: ``episode_steps`` steps of N cars plus their reset."""
    return n * episode_steps / (n * episode_steps / rate + reset_s)


def _vector_row(car, label, n, steps, repeats, **kw):
    """Time one vector configuration (:func:`_vector_rate`), print its line, return its row."""
    wall, cpu, reset_s = _vector_rate(car, n, steps, repeats, **kw)
    amort = _amortised(wall, reset_s, n)
    print(f'{car:8s} {label + f" N={n}":40s} {wall:12,.0f} {cpu:12,.0f} '
          f'{reset_s * 1e3 / n:9.1f} {amort:12,.0f}', flush=True)
    return {'car': car, 'what': label, 'n': n, 'steps_s_wall': wall, 'steps_s_cpu': cpu,
            'reset_s': reset_s, 'steps_s_episode': amort}


def speed(args):
    """Measure the steps per second of the envs and the alternatives; return the rows."""
    rows = []
    for car in args.car:
        for label, fn in (
                ('env (sensors, current action)', lambda c=car: _env_rate(
                    c, args.steps, args.repeats, plant='spencer')),
                ('env (true state, force action)', lambda c=car: _env_rate(
                    c, args.steps // 5, args.repeats, plant='spencer', observation='state',
                    action='force')),
                ('simulator Python step (alternative)', lambda c=car: _simulator_rate(
                    c, args.steps // 5, args.repeats))):
            if args.vector_only:
                break
            wall, cpu = fn()
            rows.append({'car': car, 'what': label, 'n': 1, 'steps_s_wall': wall,
                         'steps_s_cpu': cpu})
            print(f'{car:8s} {label:40s} {wall:12,.0f} {cpu:12,.0f}', flush=True)
        for n in args.cars:
            steps = max(200, args.car_steps // n)
            for threads in (1, args.threads):
                label = f'vector env, {threads} thread' + ('s' if threads > 1 else '')
                rows.append(_vector_row(car, label, n, steps, args.repeats, threads=threads))
        if car == 'full':
            # the plant's share: the same cars with kwok-current dampers (no Bouc-Wen sub-steps)
            n = max(args.cars)
            rows.append(_vector_row(car, 'vector env, kwok-current plants', n,
                                    max(200, args.car_steps // n), args.repeats,
                                    threads=args.threads, plant='kwok-current'))
        if args.vector_only:
            continue
        n = 8
        rows.append(_vector_row(car, 'SyncVectorEnv of single envs (alternative)', n,
                                max(200, args.steps // n), args.repeats,
                                vectorization_mode='sync'))
    return rows


def _offline(car, name, seed, duration, params_file):
    """
    Return the law's figures from the offline tool's ``run()`` on the same road.

    The tool names a result by its law object (``passive@0A`` runs as ``passive@0.0A``): the
    run has one law, its one entry is the figures.
    """
    if car == 'quarter':
        args = ride_study_cli.build_parser().parse_args(
            ['--controller', name, '--plant', 'spencer', '--damper-params', params_file,
             '--seed', str(seed), '--duration', str(duration), '--json'])
        return _only(ride_study_cli.run(args)[0]['controllers'])
    args = full_car_cli.build_parser().parse_args(
        ['--law', name, '--plant', 'spencer', '--damper-params', params_file,
         '--seed', str(seed), '--duration', str(duration), '--json'])
    return _only(full_car_cli.run(args)['laws'])


def _only(results):
    """Return the one value of a one-law result dict."""
    if len(results) != 1:
        raise RuntimeError(f'expected one law in the tool\'s result, got {sorted(results)}')
    return next(iter(results.values()))


def baselines(args):
    """Baselines through the env against the offline tools; return the rows."""
    rows = []
    keys = {'quarter': ('rms_body_accel_wk', 'rms_tyre_load_ratio'),
            'full': ('a_v', 'max_rms_tyre_load_ratio')}
    for car, laws in (('quarter', QUARTER_BASELINES), ('full', FULL_BASELINES)):
        envs = {kind: gymnasium.make(IDS[car], observation='state', action=kind,
                                     plant='spencer', episode_end='none',
                                     duration_s=args.duration)
                for kind in ('current', 'force')}
        core = envs['current'].unwrapped.core
        with tempfile.NamedTemporaryFile('w', suffix='.json', delete=False) as fh:
            d = dict(core.damper_params[0])
            json.dump({'model': 'kwok-current', 'parameters': d['parameters'],
                       'model_options': d['model_options'],
                       'current_min_a': d['current_min_a'],
                       'current_max_a': d['current_max_a']}, fh)
            params_file = fh.name
        for seed in args.seeds:
            refs = {}
            for name, kind in laws.items():
                env = envs[kind]
                t = time.perf_counter()
                info = run_episode(env, LawPolicy(env, name), seed=seed,
                                   options={'road_seed': seed})
                env_s = time.perf_counter() - t
                road = env.unwrapped.road
                if not refs:
                    refs['passive'] = core.passive_figures(road, core.params.i_min)
                    if args.bound:
                        t = time.perf_counter()
                        refs['bound'] = core.bound_figures(road)
                        refs['bound']['wall_s'] = time.perf_counter() - t
                t = time.perf_counter()
                off = _offline(car, name, seed, args.duration, params_file)
                off_s = time.perf_counter() - t
                e = info['episode']
                row = {'car': car, 'law': name, 'seed': seed, 'env_s': env_s,
                       'offline_s': off_s, 'cost': e['cost'],
                       'gap_closed': mr_damper_gym.gap_closed(e['cost'], refs)}
                for k in keys[car]:
                    row[f'env_{k}'], row[f'tool_{k}'] = e[k], off[k]
                    row[f'diff_{k}_pct'] = 100.0 * (e[k] / off[k] - 1.0)
                rows.append(row)
                k0, k1 = keys[car]
                print(f'{car:8s} seed {seed} {name:30s} env {e[k0]:.4f} tool {off[k0]:.4f} '
                      f'({row[f"diff_{k0}_pct"]:+.3f} %)  tyre {e[k1]:.4f} / {off[k1]:.4f} '
                      f'({row[f"diff_{k1}_pct"]:+.3f} %)  cost {e["cost"]:.3f} gap '
                      f'{row["gap_closed"]:.2f}  [{env_s:.0f} s / {off_s:.0f} s]', flush=True)
            for ref, fig in refs.items():
                rows.append({'car': car, 'law': ref, 'seed': seed, 'cost': fig['cost'],
                             **{f'env_{k}': fig[k] for k in keys[car]},
                             'wall_s': fig.get('wall_s')})
                print(f'{car:8s} seed {seed} {ref:30s} {keys[car][0]} '
                      f'{fig[keys[car][0]]:.4f} cost {fig["cost"]:.3f}', flush=True)
        os.unlink(params_file)
    return rows


def main():
    """Run the bench and print its figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--part', choices=('speed', 'baselines', 'all'), default='all')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--steps', type=int, default=5000)
    ap.add_argument('--cars', type=int, nargs='+', default=[64, 256, 1024])
    ap.add_argument('--car-steps', type=int, default=400_000,
                    help='car-steps timed per vector run (steps = this / N, at least 200)')
    ap.add_argument('--threads', type=int, default=os.cpu_count() or 1)
    ap.add_argument('--car', nargs='+', choices=('quarter', 'full'), default=['quarter', 'full'],
                    help='speed: the cars to time (default both)')
    ap.add_argument('--vector-only', action='store_true',
                    help="speed: only the vector env's rows (N cars on 1 and --threads threads, "
                         'and the kwok-current row)')
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--duration', type=float, default=20.0)
    ap.add_argument('--no-bound', dest='bound', action='store_false')
    ap.add_argument('--json', default='')
    args = ap.parse_args()
    print(f'load average at start: {os.getloadavg()}', flush=True)
    out = {'load_start': os.getloadavg()}
    if args.part in ('speed', 'all'):
        print(f'{"car":8s} {"what":40s} {"steps/s wall":>12s} {"steps/s CPU":>12s} '
              f'{"reset ms/car":>9s} {"per episode":>12s}')
        out['speed'] = speed(args)
    if args.part in ('baselines', 'all'):
        out['baselines'] = baselines(args)
    out['load_end'] = os.getloadavg()
    print(f'load average at end: {out["load_end"]}')
    if args.json:
        with open(args.json, 'w') as fh:
            json.dump(out, fh, indent=1, default=float)


if __name__ == '__main__':
    main()
