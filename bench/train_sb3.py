#!/usr/bin/env python3
r"""
Example: train a soft actor-critic (stable-baselines3) on a semi-active car (optional extra).

Not part of the suite's environment: torch and stable-baselines3 are not in requirements.txt.
Install them in a venv of their own that sees the suite's packages (``site.addsitedir`` also
runs the suite venv's own .pth files: the editable installs), e.g.::

    python3 -m venv /tmp/sb3
    echo "import site; site.addsitedir('$PWD/.venv/lib/python3.11/site-packages')" \\
        > /tmp/sb3/lib/python3.11/site-packages/suite.pth
    /tmp/sb3/bin/pip install torch==2.13.0 stable-baselines3==2.9.2 pandas==3.1.1
    /tmp/sb3/bin/python bench/train_sb3.py [--car quarter] [--steps 100000]

The agent sees the true state (``observation='state'``, each entry divided by a typical
magnitude of its unit) and commands the coil current (``action='current'``, rescaled to
[-1, 1]); training episodes are ``--episode-s`` long on ISO 8608 C roads at 20 m/s from the
env's generator. Evaluation: the deterministic policy on the standard roads (road seeds
``--eval-seeds``, ``--eval-s`` s), with passive at 0 A, the suite's laws through the env
(:mod:`mr_damper_gym.baselines`) and the offline bound on the same roads, and the fraction
of the passive-to-bound gap each closed.
"""
import argparse
import os
import time

import gymnasium
from gymnasium.wrappers import RescaleAction, TransformObservation
import numpy as np

import mr_damper_gym
from mr_damper_gym.baselines import FULL_BASELINES, LawPolicy, QUARTER_BASELINES, run_episode

#: Typical magnitude of an observation entry, by unit.
SCALE = {'m': 0.02, 'm/s': 0.3, 'm/s^2': 3.0, 'N': 300.0, 'A': 1.0, 'rad': 0.01,
         'rad/s': 0.1, 'rad/s^2': 1.0, '1': 1.0}


def make_env(car, duration_s, **kw):
    """Make the env as the agent sees it: scaled state, current rescaled to [-1, 1]."""
    env_id = mr_damper_gym.QUARTER_CAR_ID if car == 'quarter' else mr_damper_gym.FULL_CAR_ID
    env = gymnasium.make(env_id, observation='state', action='current', plant='spencer',
                         duration_s=duration_s, **kw)
    core = env.unwrapped.core
    units = core.model.obs_units[core.obs_slice]
    scale = np.array([SCALE[u] for u in units])
    space = gymnasium.spaces.Box(env.observation_space.low / scale,
                                 env.observation_space.high / scale, dtype=np.float64)
    env = TransformObservation(env, lambda o: o / scale, space)
    return RescaleAction(env, -1.0, 1.0)


class ActionRepeat(gymnasium.Wrapper):
    """Hold each action for ``k`` env steps (1 ms each), the reward summed: one decision per k."""

    def __init__(self, env, k):
        super().__init__(env)
        self.k = k

    def step(self, action):
        """Step ``k`` times with ``action`` (fewer at the episode's end)."""
        total = 0.0
        for _ in range(self.k):
            obs, reward, terminated, truncated, info = self.env.step(action)
            total += reward
            if terminated or truncated:
                break
        return obs, total, terminated, truncated, info


def held(policy, k):
    """Evaluate ``policy`` as it was trained: a new action every ``k`` steps, held between."""
    state = {'n': 0, 'action': None}

    def act(obs):
        if state['n'] % k == 0:
            state['action'] = policy(obs)
        state['n'] += 1
        return state['action']
    return act


def main():
    """Train, evaluate, print the table."""
    from stable_baselines3 import SAC
    import torch
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--car', choices=('quarter', 'full'), default='quarter')
    ap.add_argument('--steps', type=int, default=100_000)
    ap.add_argument('--episode-s', type=float, default=2.0)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--eval-seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--eval-s', type=float, default=20.0)
    ap.add_argument('--save', default='')
    ap.add_argument('--action-repeat', type=int, default=1,
                    help='env steps (1 ms) per decision; with gamma 0.99 a decision sees about '
                         '100 decisions ahead: 0.1 s at 1, the 1 s of the body mode at 10')
    ap.add_argument('--gamma', type=float, default=0.99)
    args = ap.parse_args()
    torch.set_num_threads(1)
    print(f'load average at start: {os.getloadavg()}', flush=True)
    env = make_env(args.car, args.episode_s, episode_end='none')
    if args.action_repeat > 1:
        env = ActionRepeat(env, args.action_repeat)
    # one gradient step per 8 env steps (train_freq 32, 4 steps): a 1 kHz env gives many
    # correlated samples per second of driving
    model = SAC('MlpPolicy', env, seed=args.seed, verbose=0, train_freq=32, gradient_steps=4,
                gamma=args.gamma,
                learning_starts=2000, policy_kwargs={'net_arch': [64, 64]})
    t = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    train_s = time.perf_counter() - t
    print(f'trained {args.steps} decisions ({args.action_repeat} env steps each, gamma '
          f'{args.gamma:g}) in {train_s:.0f} s ({args.steps / train_s:.0f} decisions/s)',
          flush=True)
    if args.save:
        model.save(args.save)
    laws = QUARTER_BASELINES if args.car == 'quarter' else FULL_BASELINES
    key = 'rms_body_accel_wk' if args.car == 'quarter' else 'a_v'
    rows = {}
    for seed in args.eval_seeds:
        opts = {'road_seed': seed}
        ev = make_env(args.car, args.eval_s, episode_end='bound')
        policy = held(lambda o: model.predict(o, deterministic=True)[0], args.action_repeat)
        info = run_episode(ev, policy, seed=seed, options=opts)
        refs = info['reference']
        rows.setdefault('SAC', []).append((info['episode'], info['gap_closed']))
        rows.setdefault('passive@0A (reference)', []).append((refs['passive'], 0.0))
        rows.setdefault('bound (offline)', []).append((refs['bound'], 1.0))
        for name, kind in laws.items():
            law_env = gymnasium.make(ev.unwrapped.spec.id, observation='state', action=kind,
                                     plant='spencer', duration_s=args.eval_s,
                                     episode_end='none')
            li = run_episode(law_env, LawPolicy(law_env, name), seed=seed, options=opts)
            rows.setdefault(name, []).append(
                (li['episode'], mr_damper_gym.gap_closed(li['episode']['cost'], refs)))
    print(f'{"policy":26s} {key:>18s} {"tyre (worst)":>13s} {"cost":>7s} {"gap closed":>10s}'
          '  (medians over road seeds ' + ' '.join(map(str, args.eval_seeds)) + ')')
    for name, vals in rows.items():
        med = [float(np.median([v[0][k] for v in vals]))
               for k in (key, 'max_rms_tyre_load_ratio', 'cost')]
        gap = float(np.median([v[1] for v in vals]))
        print(f'{name:26s} {med[0]:18.4f} {med[1]:13.4f} {med[2]:7.3f} {gap:10.2f}')
    print(f'load average at end: {os.getloadavg()}')


if __name__ == '__main__':
    main()
