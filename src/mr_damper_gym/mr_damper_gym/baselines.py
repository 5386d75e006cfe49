"""
The suite's control laws as policies of the environments (reference scores, sanity checks).

A policy maps the environment's true-state observation (``observation='state'``) to an action:
a passive law gives a coil current (``action='current'``), a semi-active law a body force per
corner (``action='force'``, through the environment's identified inverse, exactly as the
offline tools' controller core does). The laws are the simulator's own
(:func:`quarter_car_sim.controllers.make_controller`,
:func:`quarter_car_sim.full_car.control.make_full_car_law`); the policy only rebuilds the
state they read (:class:`quarter_car_sim.dynamics.CarState`,
:class:`quarter_car_sim.full_car.dynamics.FullCarState`) from the observation.

:func:`run_episode` drives one episode with a policy; ``bench/bench_gym.py`` and the tests
compare its figures with ``quarter-car-sim`` / ``full-car-sim`` on the same road.
"""
import math

import numpy as np

from quarter_car_sim.controllers import make_controller
from quarter_car_sim.dynamics import CarState
from quarter_car_sim.full_car.control import make_full_car_law
from quarter_car_sim.full_car.dynamics import FullCarState

#: Baselines of each car: name -> (law name of the offline tool, action kind).
QUARTER_BASELINES = {'passive@0A': 'current', 'skyhook': 'force', 'clipped-optimal-wk': 'force'}
FULL_BASELINES = {'passive@0A': 'current', 'per-corner-skyhook': 'force',
                  'per-corner-clipped-optimal-wk': 'force', 'modal-skyhook': 'force'}


class LawPolicy:
    """
    One of the suite's laws acting through an environment's API.

    Parameters
    ----------
    env : SemiActiveEnv
        The environment (its car, control period and identified inverse); its observation
        must be ``'state'``.
    name : str
        Law name of the offline tool (``passive@<I>A``, ``skyhook``, ``clipped-optimal-wk``,
        ...; full car ``modal-skyhook``, ``per-corner-<law>``).

    Attributes
    ----------
    action : {'current', 'force'}
        The action kind the law needs (the environment's ``action`` option).

    """

    def __init__(self, env, name):
        core = env.unwrapped.core
        if core.observation != 'state':
            raise ValueError("a law reads the true state: make the environment with "
                             "observation='state'")
        self.core, self.name = core, name
        self.dt = core.dt
        p = core.params
        if core.car == 'quarter':
            self.law = make_controller(name, params=p, inverse=core.inverses[0], dt=self.dt,
                                       damper_only=True)
            self.laws = [self.law]
        else:
            self.law = make_full_car_law(name, p, dt=self.dt)
            self.laws = self.law.corner_laws
        kinds = {law.kind for law in self.laws}
        self.action = 'current' if kinds == {'current'} else 'force'
        if core.action != self.action:
            raise ValueError(f'law {name!r} needs action={self.action!r}, the environment has '
                             f'{core.action!r}')
        self.reset()

    def reset(self):
        """Start an episode: the law's memory cleared, its clock at t = 0."""
        self.law.reset()
        self.t = 0.0

    def state(self, obs):
        """Return the simulator's state type the law reads, from a true-state observation."""
        o = np.asarray(obs, dtype=float).tolist()
        nan = math.nan
        if self.core.car == 'quarter':
            tr, tyre, vr, vs, a_s, vu, fd, cur = o[:8]
            # road height 0: the wheel height is the tyre deflection (only z_u - z_r is read)
            return CarState(self.t, tr + tyre, vs, a_s, tyre, vu, nan, 0.0, tr, vr, nan, fd,
                            cur)
        a = np.asarray(obs, dtype=float)
        c = [a[4 * j:4 * j + 4] for j in range(9)]
        body = a[36:45]
        q = np.concatenate([body[:3], c[1]])
        v = np.concatenate([body[3:6], c[5]])
        acc = np.concatenate([body[6:9], np.full(4, nan)])
        zero = np.zeros(4)
        return FullCarState(self.t, q, v, acc, zero, zero, c[0], c[2], np.full(4, nan), c[6],
                            c[7], c[3], c[4])

    def __call__(self, obs):
        """Return the action for a true-state observation (and advance the law's clock)."""
        s = self.state(obs)
        if self.core.car == 'quarter':
            out = [self.law.demand(s)]
        else:
            self.law.prepare(s)
            out = [law.demand(s.corner(i)) for i, law in enumerate(self.laws)]
        self.t += self.dt
        return np.asarray(out, dtype=float)


def run_episode(env, policy, *, seed=None, options=None):
    """
    Drive one episode with a policy; return its ``info`` at the end and the mean reward.

    Parameters
    ----------
    env : gymnasium.Env
        A :class:`~mr_damper_gym.envs.SemiActiveEnv` (or a wrapper of one).
    policy : callable
        ``policy(obs) -> action``; its ``reset()`` is called first when it has one.
    seed, options
        Of ``env.reset``.

    Returns
    -------
    dict
        ``info`` of the last step (``episode``, ``reference``, ``gap_closed``) plus
        ``mean_reward`` and ``steps``.

    """
    obs, _ = env.reset(seed=seed, options=options)
    if hasattr(policy, 'reset'):
        policy.reset()
    total, n = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total += reward
        n += 1
        if terminated or truncated:
            break
    info['mean_reward'] = total / n
    info['steps'] = n
    return info
