"""
The Gymnasium environments: a quarter car and a full car with semi-active MR dampers.

``gymnasium.make('mr_damper/SemiActiveQuarterCar-v0')`` and
``gymnasium.make('mr_damper/SemiActiveFullCar-v0')`` after ``import mr_damper_gym`` (or with
gymnasium's ``'mr_damper_gym:mr_damper/...'`` form, which imports the package itself).
Spaces, reward and options: docs/gym.md and :class:`mr_damper_gym.core.EnvCore`.

One step is one control period (1 ms by default): the action (coil currents, or body forces
through the identified inverse) is held while the car, its four (or one) damper plants with
their coil lag and hysteresis, and the sensors advance; the observation is the new sample's.
An episode drives one road from t = 0 to its end (``duration_s``) and is then truncated (the
road ends; the car's state is not terminal); it never terminates.
"""
import gymnasium

from mr_damper_gym.batch import CarBatch
from mr_damper_gym.core import EnvCore, gap_closed
from mr_damper_gym.render import side_view


class SemiActiveEnv(gymnasium.Env):
    """
    Semi-active suspension control of a simulated car (one car; the base of both ids).

    Parameters
    ----------
    car : {'quarter', 'full'}
        Car.
    render_mode : {'rgb_array', None}
        ``'rgb_array'``: :meth:`render` returns a side view of the car on the road.
    **options
        Options of :class:`mr_damper_gym.core.EnvCore` (``observation``, ``action``,
        ``plant``, ``damper_params``, ``duration_s``, ``road_class``, ``speed_m_s``,
        ``events``, ``tyre_weight``, ``episode_end``, ...).

    Notes
    -----
    ``info`` of every step: ``t_s`` (time of the sample [s]), ``current_a`` (the currents
    applied [A]), ``action_clipped`` (the action lay outside the space and was clipped) and
    ``n_action_clipped`` (so far), ``saturated`` (force action: demand out of the damper's
    reach, per damper), ``obs_clipped`` (observation entries clipped to the space so far; 0 in
    any physical run) and the ISO 2631-1 figures so far (quarter car ``rms_body_accel_wk``,
    ``rms_tyre_load_ratio``; full car ``a_wz``, ``a_w_pitch``, ``a_w_roll``, ``a_v``,
    ``max_rms_tyre_load_ratio``). At the episode's end also ``episode`` (all the figures and
    ``cost``, the mean of minus the reward), ``reference`` (``passive`` at ``i_min`` and the
    offline ``bound`` on the same road, per ``episode_end``) and ``gap_closed`` (0 passive,
    1 the bound).

    """

    metadata = {'render_modes': ['rgb_array'], 'render_fps': 30}

    def __init__(self, car='quarter', render_mode=None, **options):
        if render_mode not in (None, 'rgb_array'):
            raise ValueError(f"`render_mode` must be None or 'rgb_array', got {render_mode!r}")
        self.core = EnvCore(car, **options)
        self.render_mode = render_mode
        self.observation_space, self.action_space = self.core.spaces()
        self.batch = CarBatch(self.core.model, 1)
        self._sl = self.core.obs_slice
        self._steps = 0
        self._n_steps = 0
        self._n_clipped = 0
        self.road = None
        self.road_spec = None
        self._dt = self.core.dt

    def reset(self, *, seed=None, options=None):
        """
        Start an episode on a new road (options: :mod:`mr_damper_gym.roads`).

        Returns
        -------
        observation : ndarray
        info : dict
            ``road`` (its description: ``road_seed`` reproduces it with the offline tools),
            ``t_s`` and the observation's ``names``.

        """
        super().reset(seed=seed)
        self.road, self.road_spec, self._n_steps = self.core.new_episode(
            self.batch, 0, self.np_random, options)
        self._steps = 0
        self._n_clipped = 0
        info = {'road': dict(self.road_spec, name=self.road.name, steps=self._n_steps),
                't_s': 0.0}
        return self.batch.obs[0, self._sl].copy(), info

    def step(self, action):
        """
        Hold ``action`` for one control period.

        Raises
        ------
        mr_damper_gym.core.ActionError
            NaN, infinite or wrongly shaped action.
        RuntimeError
            Step before reset, or after the episode ended.

        """
        if self.road is None:
            raise RuntimeError('call reset() before step()')
        if self._steps >= self._n_steps:
            raise RuntimeError('the episode has ended (truncated): call reset()')
        b = self.batch
        cur, clipped, sat = self.core.currents(action, b.obs)
        b.step(cur)
        self._steps += 1
        clip = bool(clipped[0])
        self._n_clipped += clip
        sums = b.sums[0].tolist()
        info = self.core.running(sums)
        info.update(t_s=self._steps * self._dt, current_a=cur[0].copy(), action_clipped=clip,
                    n_action_clipped=self._n_clipped, saturated=sat[0],
                    obs_clipped=b.obs_clipped(0))
        truncated = self._steps >= self._n_steps
        if truncated:
            fig = b.figures(0)
            refs = self.core.references(self.road)
            info.update(episode=fig, reference=refs, gap_closed=gap_closed(fig['cost'], refs))
        return b.obs[0, self._sl].copy(), float(b.reward[0]), False, truncated, info

    def render(self):
        """Side view of the car and the road around it (``rgb_array``: an RGB uint8 array)."""
        if self.render_mode is None:
            gymnasium.logger.warn('render() without render_mode (use render_mode="rgb_array")')
            return None
        return side_view(self.core, self.batch, 0, self.road)

    @property
    def figures(self):
        """ISO 2631-1 and ride figures of the episode so far (``info['episode']`` keys)."""
        return self.batch.figures(0)

    @property
    def state_row(self):
        """The true-state part of the present observation row (whatever the agent sees)."""
        return self.batch.obs[0, :self.core.model.n_state_obs].copy()

    @property
    def obs_names(self):
        """Names of the observation entries (units: docs/gym.md)."""
        return self.core.model.obs_names[self._sl]


class SemiActiveQuarterCarEnv(SemiActiveEnv):
    """``mr_damper/SemiActiveQuarterCar-v0``: the quarter car (:class:`SemiActiveEnv`)."""

    def __init__(self, render_mode=None, **options):
        super().__init__('quarter', render_mode=render_mode, **options)


class SemiActiveFullCarEnv(SemiActiveEnv):
    """``mr_damper/SemiActiveFullCar-v0``: the 7-DOF full car (:class:`SemiActiveEnv`)."""

    def __init__(self, render_mode=None, **options):
        super().__init__('full', render_mode=render_mode, **options)
