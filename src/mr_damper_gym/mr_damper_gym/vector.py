"""
The vector environments: N cars stepped together by one call of the compiled step.

``gymnasium.make_vec('mr_damper/SemiActiveFullCar-v0', num_envs=N)`` (the ids' vector entry
point) gives a :class:`SemiActiveVectorEnv`: one :class:`~mr_damper_gym.batch.CarBatch` of N
cars, each with its own road, sensors and random generator. Sub-environment ``i`` reset with
seed ``s + i`` (gymnasium's rule for ``reset(seed=s)``) is step for step the single
environment reset with that seed (a test). Autoreset: gymnasium's next-step mode (the step
after a truncation resets that car and ignores its action). ``episode_end`` defaults to
``'passive'`` here (the bound costs seconds per episode: for evaluation, not training).
"""
import gymnasium
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
import numpy as np

from mr_damper_gym.batch import CarBatch
from mr_damper_gym.core import ActionError, EnvCore, gap_closed
from mr_damper_gym.render import side_view


class SemiActiveVectorEnv(VectorEnv):
    """
    N semi-active cars stepped together (a ``gymnasium.vector.VectorEnv``).

    Parameters
    ----------
    car : {'quarter', 'full'}
        Car.
    num_envs : int
        Number of cars.
    render_mode : {'rgb_array', None}
        ``render()`` returns the side view of each car.
    episode_end : {'passive', 'bound', 'none'}
        References at each episode's end (default passive at ``i_min``).
    threads : int or None
        Threads stepping the cars side by side (None: one per core from 8 cars on).
    **options
        Options of :class:`mr_damper_gym.core.EnvCore`.

    Notes
    -----
    ``infos`` holds every key of the single environment's ``info`` as an array over the cars
    with its ``_key`` mask (gymnasium's convention); ``episode``, ``reference`` and
    ``gap_closed`` only for the cars whose episode ended at this step.

    """

    metadata = {'render_modes': ['rgb_array'], 'autoreset_mode': AutoresetMode.NEXT_STEP}

    def __init__(self, car='quarter', num_envs=1, render_mode=None, episode_end='passive',
                 threads=None, **options):
        if int(num_envs) < 1:
            raise ValueError(f'`num_envs` must be >= 1, got {num_envs}')
        if render_mode not in (None, 'rgb_array'):
            raise ValueError(f"`render_mode` must be None or 'rgb_array', got {render_mode!r}")
        self.core = EnvCore(car, episode_end=episode_end, **options)
        self.num_envs = int(num_envs)
        self.render_mode = render_mode
        obs, act = self.core.spaces()
        self.single_observation_space, self.single_action_space = obs, act
        self.observation_space = batch_space(obs, self.num_envs)
        self.action_space = batch_space(act, self.num_envs)
        n = self.num_envs
        self.batch = CarBatch(self.core.model, n, threads=threads)
        self._sl = self.core.obs_slice
        self._rngs = [None] * n
        self._steps = np.zeros(n, dtype=np.int64)
        self._n_steps = np.zeros(n, dtype=np.int64)
        self._n_clipped = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=bool)
        self.roads = [None] * n
        self.road_specs = [None] * n

    def _reset_car(self, i, seed, options):
        if seed is not None or self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random(seed)
        road, spec, steps = self.core.new_episode(self.batch, i, self._rngs[i], options)
        self.roads[i], self.road_specs[i] = road, spec
        self._steps[i] = 0
        self._n_steps[i] = steps
        self._n_clipped[i] = 0
        self._autoreset[i] = False

    def reset(self, *, seed=None, options=None):
        """
        Reset every car (or those of ``options['reset_mask']``) on new roads.

        ``seed``: an int (car i gets ``seed + i``), a list of one seed (or None) per car, or
        None. Other options: :mod:`mr_damper_gym.roads`, the same for every car.
        """
        super().reset(seed=seed)
        n = self.num_envs
        if seed is None or isinstance(seed, (list, tuple)):
            seeds = [None] * n if seed is None else list(seed)
        else:
            seeds = [int(seed) + i for i in range(n)]
        if len(seeds) != n:
            raise ValueError(f'`seed`: one per car ({n}), got {len(seeds)}')
        options = dict(options or {})
        mask = np.asarray(options.pop('reset_mask', np.ones(n, dtype=bool)), dtype=bool)
        for i in np.flatnonzero(mask):
            self._reset_car(i, seeds[i], options)
        road = {'road_seed': np.array([s['road_seed'] for s in self.road_specs]),
                'speed_m_s': np.array([s['speed_m_s'] for s in self.road_specs]),
                'road_class': np.array([s['road_class'] for s in self.road_specs]),
                'steps': self._n_steps.copy()}
        info = {'road': road, '_road': mask.copy(), 't_s': np.zeros(n), '_t_s': mask.copy()}
        return self.batch.obs[:, self._sl].copy(), info

    def step(self, actions):
        """
        Hold each car's action for one control period (cars that ended are reset instead).

        Raises
        ------
        mr_damper_gym.core.ActionError
            NaN, infinite or wrongly shaped actions of a car that steps.

        """
        n = self.num_envs
        b = self.batch
        restart = self._autoreset.copy()
        stepping = ~restart
        a = np.asarray(actions, dtype=float)
        if a.size != b.cmd.size:
            raise ActionError(f'the actions must hold {b.cmd.shape[1]} value(s) per car for '
                              f'{n} cars, got shape {np.shape(actions)}')
        a = a.reshape(b.cmd.shape).copy()
        # a car that ended is reset at this step: its action is not used (next-step autoreset)
        act = self.single_action_space
        a[restart] = np.clip(0.0, act.low, act.high)
        cur, clipped, sat = self.core.currents(a, b.obs)
        for i in np.flatnonzero(restart):
            self._reset_car(i, None, None)
        all_step = not restart.any()
        # every car stepping (the common case): the batch's own all-cars mask, which lets it
        # skip the per-step check of the sensors' random-number blocks
        b.step(cur, active=None if all_step else stepping)
        if all_step:
            self._steps += 1
            reward = b.reward.copy()
        else:
            self._steps[stepping] += 1
            clipped &= stepping
            reward = np.where(stepping, b.reward, 0.0)
        self._n_clipped += clipped
        truncated = stepping & (self._steps >= self._n_steps)
        terminated = np.zeros(n, dtype=bool)
        sums = b.sums
        info = self.core.running(sums.T)
        # the masks: one array per step for the keys every car has (read them, do not write)
        every = np.ones(n, dtype=bool)
        stepped = every if all_step else stepping
        info.update({'_' + k: stepped for k in list(info)})
        info.update(t_s=self._steps * self.core.dt, current_a=cur, action_clipped=clipped,
                    n_action_clipped=self._n_clipped.copy(), saturated=sat,
                    obs_clipped=sums[:, self.core.model.sum_slots['clipped']].astype(np.int64))
        for key in ('t_s', 'current_a', 'action_clipped', 'n_action_clipped', 'saturated',
                    'obs_clipped'):
            info['_' + key] = every
        for i in np.flatnonzero(truncated):
            fig = b.figures(i)
            refs = self.core.references(self.roads[i])
            info = self._add_info(info, {'episode': fig, 'reference': refs,
                                         'gap_closed': gap_closed(fig['cost'], refs)}, i)
        self._autoreset = truncated
        return (b.obs[:, self._sl].copy(), reward, terminated, truncated, info)

    def close_extras(self, **kwargs):
        """Stop the batch's threads."""
        self.batch.close()

    def render(self):
        """Side views of the cars (a tuple of RGB uint8 arrays), with ``rgb_array``."""
        if self.render_mode is None:
            gymnasium.logger.warn('render() without render_mode (use render_mode="rgb_array")')
            return None
        return tuple(side_view(self.core, self.batch, i, self.roads[i])
                     for i in range(self.num_envs))


class SemiActiveQuarterCarVectorEnv(SemiActiveVectorEnv):
    """Vector form of ``mr_damper/SemiActiveQuarterCar-v0``."""

    def __init__(self, num_envs=1, render_mode=None, **options):
        super().__init__('quarter', num_envs=num_envs, render_mode=render_mode, **options)


class SemiActiveFullCarVectorEnv(SemiActiveVectorEnv):
    """Vector form of ``mr_damper/SemiActiveFullCar-v0``."""

    def __init__(self, num_envs=1, render_mode=None, **options):
        super().__init__('full', num_envs=num_envs, render_mode=render_mode, **options)
