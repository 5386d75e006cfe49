"""
What the single and the vector environment share: the car, its dampers, actions, references.

:class:`EnvCore` builds, from the environment's options, the car model
(:class:`~mr_damper_gym.model.CarModel`), the "true" damper plants and the identified
kwok-current sets the force-demand action goes through (the offline tools' inverse), the
reward's normalisation (passive at the softest current on a reference road), the episode
roads (:mod:`mr_damper_gym.roads`) and the episode-end references on the same road: passive
at the softest current (the compiled car) and the offline optimal semi-active bound
(:func:`quarter_car_sim.bound.semi_active_bound`, :func:`quarter_car_sim.full_car.bound.
full_car_bound`, replayed on the true plants).

Reward of a step (the sample the step ends on)::

    r = -( sum_j (k_j a_w,j)^2 / A0 + rho * mean_i (F_t,dyn,i / W_i)^2 / T0 ) / (1 + rho)

``a_w,j``: the ISO 2631-1 weighted body accelerations (quarter car: Wk vertical; full car: Wk
vertical at the seat, We pitch and roll), ``k_j`` the axis factors (1; 1, 0.40, 0.63), so the
first sum is the vibration total value squared of this sample; ``F_t,dyn,i / W_i`` each
wheel's dynamic tyre load over its static load; ``rho`` the tyre weight; ``A0`` and ``T0`` the
means of the two terms for the car at ``i_min`` on the reference road (ISO 8608 class and speed
of the environment's defaults, road seed :data:`REFERENCE_SEED`, :data:`REFERENCE_S` long).
Passive at the softest current therefore scores -1 per step on the reference road and about -1
on other roads of that class and speed. The mean of ``-r`` over an episode is the episode's
``cost``: ``a_v^2 / A0`` for ``rho = 0``.
"""
import functools
import math

from gymnasium import spaces
import numpy as np

from mr_damper_model.identification import presets
from mr_damper_model.models.inverse import KwokCurrentInverse
from mr_damper_model.models.plant import make_plant
from mr_damper_rig.virtual_rig import identify_damper
from quarter_car_sim.bound import KwokForceModel, semi_active_bound
from quarter_car_sim.full_car.bound import corner_force_model, full_car_bound
from quarter_car_sim.full_car.estimator import ACCEL_CORNERS
from quarter_car_sim.full_car.params import CORNERS, PASSENGER_CAR
from quarter_car_sim.full_car.simulate import corner_message
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.sensors import accelerometer_spec, default_specs, ride_height_spec
from quarter_car_sim.simulate import INVERSE_TOL_A, make_inverse

from mr_damper_gym.batch import CarBatch
from mr_damper_gym.model import CarModel, ModelError
from mr_damper_gym import roads as R

#: Road seed and length [s] of the reward's reference run.
REFERENCE_SEED = 0
REFERENCE_S = 20.0
#: Episode-end references: none, passive at the softest current, or passive and the bound.
EPISODE_END = ('none', 'passive', 'bound')
OBSERVATIONS = ('sensors', 'state')
ACTIONS = ('current', 'force')
PLANTS = {'spencer': 'spencer', 'kwok': 'kwok-current', 'kwok-current': 'kwok-current'}


class ActionError(ValueError):
    """An action the environment refuses (NaN, infinite, wrong shape)."""


@functools.lru_cache(maxsize=8)
def identified_set(plant_name, seed):
    """
    Identify a kwok-current set on a plant from the simulated rig test (once a process).

    ``mr_damper_rig.virtual_rig.identify_damper`` (the ``quarter-car-sim`` default): the laws'
    and the force action's inverse never see the plant's true parameters.
    """
    return identify_damper(make_plant(plant_name), seed=seed)


def default_set(plant_name, seed):
    """
    Return a plant's identified set: from the rig test, or a kwok-current plant's own.

    A kwok-current plant's own parameters stand for a perfect identification (as
    ``full-car-sim`` without ``--damper-params``); a Spencer plant is identified.
    """
    if plant_name == 'kwok-current':
        model, params = presets.thesis_kwok_current()
        return {'parameters': params, 'model_options': dict(model.options),
                'current_min_a': 0.0, 'current_max_a': 2.0,
                'source': 'kwok-current plant truth (no identification)'}
    return identified_set(plant_name, int(seed))


class EnvCore:
    """
    The car, dampers, sensors, actions, reward and references of one environment's options.

    Parameters
    ----------
    car : {'quarter', 'full'}
        Car: :class:`quarter_car_sim.params.QuarterCarParams` (default car) or
        :data:`quarter_car_sim.full_car.params.PASSENGER_CAR`.
    observation : {'sensors', 'state'}
        What the agent sees: the vehicle's sensors with their error models, or the true state.
    action : {'current', 'force'}
        Coil current per damper [A], or a force demand on the body per corner [N] through the
        identified inverse (as the laws use it).
    plant : str or sequence of str
        True damper of every corner (``'spencer'``, ``'kwok-current'``) or one per corner.
    damper_params : dict, path or sequence, optional
        Identified kwok-current set(s) (one for all corners or one per corner); default: the
        plant identified on the simulated rig (:func:`default_set`).
    duration_s, road, road_class, speed_m_s, events
        Default episode road (:mod:`mr_damper_gym.roads`).
    tyre_weight : float
        ``rho`` of the reward (0: comfort only).
    episode_end : {'bound', 'passive', 'none'}
        References computed on the episode's road at its end.
    dt : float
        Control period [s].
    settle_s : float
        Settling time before t = 0 [s] (the offline tools' 0.5 s).
    settle_current_a : float, optional
        Current while settling [A] (default ``i_min``).
    force_limit_n : float
        Bound of the force action [N].
    identification_seed : int
        Seed of the simulated rig test of a Spencer plant.
    substeps : int
        Integration sub-steps per period.
    sensors : sequence, optional
        ``(name, kind, corner, SensorSpec)`` instead of the production set.
    params : QuarterCarParams or FullCarParams, optional
        Another car.

    """

    def __init__(self, car, *, observation='sensors', action='current', plant='spencer',
                 damper_params=None, duration_s=10.0, road='iso8608', road_class='C',
                 speed_m_s=20.0, events=(), tyre_weight=0.0, episode_end='bound', dt=1e-3,
                 settle_s=0.5, settle_current_a=None, force_limit_n=5000.0,
                 identification_seed=1, substeps=1, sensors=None, params=None):
        if car not in ('quarter', 'full'):
            raise ModelError(f"`car` must be 'quarter' or 'full', got {car!r}")
        for name, value, allowed in (('observation', observation, OBSERVATIONS),
                                     ('action', action, ACTIONS),
                                     ('episode_end', episode_end, EPISODE_END)):
            if value not in allowed:
                raise ModelError(f'`{name}` must be one of {", ".join(allowed)}, got {value!r}')
        self.car, self.observation, self.action = car, observation, action
        self.episode_end = episode_end
        if params is None:
            if car == 'quarter':
                params = QuarterCarParams()
            else:
                params = PASSENGER_CAR
        self.params = params
        nc = 1 if car == 'quarter' else 4
        names = [plant] * nc if isinstance(plant, str) else list(plant)
        if len(names) != nc or any(n not in PLANTS for n in names):
            raise ModelError(f'`plant`: one of {", ".join(sorted(PLANTS))}, or {nc} of them')
        self.plant_names = [PLANTS[n] for n in names]
        if damper_params is None:
            self.damper_params = [default_set(n, identification_seed) for n in self.plant_names]
        elif isinstance(damper_params, (list, tuple)):
            if len(damper_params) != nc:
                raise ModelError(f'`damper_params`: one set or {nc}')
            self.damper_params = list(damper_params)
        else:
            self.damper_params = [damper_params] * nc
        self.dt = float(dt)
        if not (math.isfinite(settle_s) and settle_s >= 0):
            raise ModelError(f'`settle_s` must be >= 0, got {settle_s}')
        self.settle_steps = int(round(settle_s / self.dt))
        self.settle_current_a = params.i_min if settle_current_a is None else float(
            settle_current_a)
        self.force_limit_n = float(force_limit_n)
        if not (math.isfinite(self.force_limit_n) and self.force_limit_n > 0):
            raise ModelError(f'`force_limit_n` must be > 0, got {force_limit_n}')
        self.defaults = {'road': road, 'road_class': road_class, 'speed_m_s': speed_m_s,
                         'road_seed': None, 'events': list(events), 'duration_s': duration_s}
        self.model = CarModel(car, params, [make_plant(n) for n in self.plant_names],
                              self._sensors() if sensors is None else list(sensors),
                              dt=self.dt, substeps=substeps, tyre_weight=tyre_weight)
        self.inverses = self._inverses()
        self._reference_run()

    # --- construction ----------------------------------------------------------------------
    def _sensors(self):
        """Return the production sensor set (quarter car: body accelerometer, position sensor)."""
        if self.car == 'quarter':
            s = default_specs()
            return [('body_accel', 'accel', 0, s['body_accel']),
                    ('travel', 'travel', 0, s['travel'])]
        out = [(f'accel_{c}', 'accel', CORNERS.index(c), accelerometer_spec())
               for c in ACCEL_CORNERS]
        out += [(f'travel_{c}', 'travel', i, ride_height_spec()) for i, c in enumerate(CORNERS)]
        return out

    def _inverses(self):
        """Each corner's inverse of its identified set, as the offline tools build it."""
        p = self.params
        if self.car == 'quarter':
            return [make_inverse(self.damper_params[0], i_min=p.i_min, i_max=p.i_max)]
        out = []
        for d in self.damper_params:
            # as the corner's ControllerCore: within the range the set was identified on
            msg = corner_message(d)
            lo = max(p.i_min, msg['current_min_a'])
            hi = min(p.i_max, msg['current_max_a'])
            if not hi > lo:
                lo, hi = p.i_min, p.i_max
            out.append(KwokCurrentInverse(msg, i_ref_a=msg['i_ref_a'], i_min=lo, i_max=hi,
                                          tol_a=INVERSE_TOL_A, sign_convention='body'))
        return out

    def _reference_run(self):
        """Normalise the reward on passive at ``i_min`` on the reference road."""
        cls, speed = self.defaults['road_class'], self.defaults['speed_m_s']
        spec = R.road_spec(self.defaults, {
            'road': 'iso8608', 'road_seed': REFERENCE_SEED, 'duration_s': REFERENCE_S,
            'events': [], 'road_class': cls[0] if isinstance(cls, (list, tuple)) else cls,
            'speed_m_s': (float(np.mean(speed)) if isinstance(speed, (list, tuple))
                          else speed)}, None)
        fig = self.passive_figures(R.build_road(self.car, self.params, spec, self.dt),
                                   self.params.i_min, raw=True)
        self.model.set_normalisation(fig['comfort'], fig['tyre'])
        self.reference_spec = spec

    # --- spaces ----------------------------------------------------------------------------
    @property
    def obs_slice(self):
        """Part of the kernel's observation row the agent sees."""
        n = self.model.n_state_obs
        return slice(0, n) if self.observation == 'state' else slice(n, None)

    def spaces(self):
        """Return ``(observation_space, action_space)`` (gymnasium Boxes, float64, SI)."""
        m = self.model
        sl = self.obs_slice
        obs = spaces.Box(m.obs_low[sl], m.obs_high[sl], dtype=np.float64)
        nc = m.nc
        if self.action == 'current':
            act = spaces.Box(np.full(nc, self.params.i_min), np.full(nc, self.params.i_max),
                             dtype=np.float64)
        else:
            act = spaces.Box(np.full(nc, -self.force_limit_n), np.full(nc, self.force_limit_n),
                             dtype=np.float64)
        return obs, act

    # --- episodes --------------------------------------------------------------------------
    def new_episode(self, batch, k, rng, options):
        """
        Draw car ``k``'s road from ``rng`` and the options, reset and settle it on the road.

        Returns
        -------
        road : RoadProfile or TwoTrackRoad
            The episode's road.
        spec : dict
            Its description (:func:`mr_damper_gym.roads.road_spec`).
        steps : int
            Control periods of the episode.

        """
        options = dict(options or {})
        spec = R.road_spec(self.defaults, options, rng)
        road = R.build_road(self.car, self.params, spec, self.dt)
        settle = float(options.get('settle_current_a', self.settle_current_a))
        if not (math.isfinite(settle) and self.params.i_min <= settle <= self.params.i_max):
            raise ModelError(f'`settle_current_a` must lie in the coil range, got {settle}')
        self._load(batch, k, road, settle, np.random.default_rng(rng.integers(2 ** 63)))
        return road, spec, R.recorded_samples(road, self.dt) - 1

    def _load(self, batch, k, road, settle_current, sensor_rng):
        """Put ``road`` under car ``k`` and reset it there (settling at ``settle_current``)."""
        if abs(road.dt - self.dt) > 1e-12 * self.dt:
            raise ModelError('the road must be sampled at the control period')
        t0 = -self.settle_steps * self.dt
        tr, delay = R.tracks(self.car, road)
        batch.set_road(k, tr, delay)
        batch.reset_car(k, R.initial_state(self.car, self.params, road, t0), t0,
                        settle_steps=self.settle_steps, settle_current=settle_current,
                        rng=sensor_rng)

    # --- actions ---------------------------------------------------------------------------
    def currents(self, action, state_rows):
        """
        Coil currents of a batch of actions; refuses NaN, clips and flags what is out of range.

        Parameters
        ----------
        action : array_like (n, nc)
            Currents [A] or body forces [N] per corner.
        state_rows : ndarray (n, nobs)
            The cars' kernel observation rows (the force action's inverse reads the true
            travel and suspension velocity of each damper).

        Returns
        -------
        currents : ndarray (n, nc)
            [A], within the coil range.
        clipped : ndarray of bool (n,)
            An action entry lay outside the action space and was clipped to it.
        saturated : ndarray of bool (n, nc)
            Force action: the demand was out of the damper's reach (nearest force made).

        Raises
        ------
        ActionError
            Wrong shape, NaN or infinite entries.

        """
        nc = self.model.nc
        a = np.asarray(action, dtype=float)
        n = state_rows.shape[0]
        if a.size != n * nc:
            raise ActionError(f'the action must hold {nc} value(s) per car, got shape '
                              f'{np.shape(action)}')
        a = a.reshape(n, nc)
        if self.action == 'current':
            lo, hi = self.params.i_min, self.params.i_max
        else:
            lo, hi = -self.force_limit_n, self.force_limit_n
        sat = np.zeros((n, nc), dtype=bool)
        if lo <= a.min() and a.max() <= hi:          # the common case (False for NaN)
            c, clipped = a, np.zeros(n, dtype=bool)
        else:
            if not np.all(np.isfinite(a)):
                raise ActionError(
                    f'the action holds NaN or infinite values: {a.tolist()} (a '
                    f'{"coil current [A]" if self.action == "current" else "force [N]"} per '
                    'damper is needed)')
            c = np.clip(a, lo, hi)
            clipped = np.any(c != a, axis=1)
        if self.action == 'current':
            return c, clipped, sat
        out = np.empty((n, nc))
        for k in range(n):
            for i, inv in enumerate(self.inverses):
                cur, flag = inv.current(float(c[k, i]), float(state_rows[k, i]),
                                        float(state_rows[k, 2 * nc + i]))
                out[k, i] = min(max(cur, self.params.i_min), self.params.i_max)
                sat[k, i] = flag != 0
        return out, clipped, sat

    # --- figures ---------------------------------------------------------------------------
    def running(self, sums):
        """
        Return the ISO 2631-1 figures so far of a sums row (floats) or of its columns (arrays).

        Plain arithmetic, so one car's row as a list costs no numpy call (every step's info).
        """
        m = self.model
        off = m.sum_slots
        n = sums[off['n']]
        tyre = sums[off['tyre']]
        for i in range(1, m.nc):
            other = sums[off['tyre'] + 3 * i]
            tyre = (tyre + other + abs(tyre - other)) / 2.0       # the larger, floats or arrays
        if self.car == 'quarter':
            return {'rms_body_accel_wk': (sums[0] / n) ** 0.5,
                    'rms_tyre_load_ratio': (tyre / n) ** 0.5}
        wz, wp, wr = ((sums[3 * j] / n) ** 0.5 for j in range(3))
        k = m.axis_factors.tolist()
        return {'a_wz': wz, 'a_w_pitch': wp, 'a_w_roll': wr,
                'a_v': (wz * wz + (k[1] * wp) ** 2 + (k[2] * wr) ** 2) ** 0.5,
                'max_rms_tyre_load_ratio': (tyre / n) ** 0.5}

    def passive_figures(self, road, current, *, raw=False):
        """
        Figures of the car at a constant ``current`` [A] on ``road`` (compiled, no sensors).

        Settles at the same current; with ``raw`` also the means of the reward's two terms.
        """
        b = CarBatch(self.model, 1)
        self._load(b, 0, road, current, None)
        b.run(np.full((1, self.model.nc), current), R.recorded_samples(road, self.dt) - 1)
        fig = b.figures(0)
        if raw:
            m = self.model
            off = m.sum_slots
            n = b.sums[0, off['n']]
            ch = b.sums[0, off['ch']:off['tyre']].reshape(m.nw, 3)[:, 0]
            fig['comfort'] = float(np.sum(m.axis_factors ** 2 * ch) / n)
            fig['tyre'] = float(np.mean(b.sums[0, off['tyre']:off['corner']:3]) / n)
        return fig

    def bound_figures(self, road):
        """
        Run the offline optimal semi-active bound on ``road``, replayed on the true plants.

        Its cost uses the tyre weight of the reward. Returns the figures of the replay (the
        keys of :meth:`CarModel.figures` the offline metrics give) and ``cost``.
        """
        rho = self.model.tyre_weight
        plants = [make_plant(n) for n in self.plant_names]
        if self.car == 'quarter':
            res = semi_active_bound(self.params, road, KwokForceModel(self.inverses[0]),
                                    plants[0], rho=rho, dt=self.dt,
                                    settle_s=self.settle_steps * self.dt)
            m = res.replay.metrics()
            fig = {'rms_body_accel_wk': m['rms_body_accel_wk'],
                   'rms_tyre_load_ratio': m['rms_tyre_load_ratio'],
                   'rms_suspension_travel': m['rms_suspension_travel'],
                   'max_rms_tyre_load_ratio': m['rms_tyre_load_ratio']}
            comfort, tyre = m['rms_body_accel_wk'] ** 2, m['rms_tyre_load_ratio'] ** 2
        else:
            models = [corner_force_model(d, self.params) for d in self.damper_params]
            res = full_car_bound(self.params, road, models, plants, self.damper_params,
                                 rho=rho, dt=self.dt, settle_s=self.settle_steps * self.dt)
            m = res.metrics(self.params)
            fig = {k: m[k] for k in ('a_wz', 'a_w_pitch', 'a_w_roll', 'a_v', 'vdv_total',
                                     'crest_max', 'max_rms_tyre_load_ratio')}
            fig['rms_tyre_load_ratio'] = [m['rms_tyre_load_ratio'][c]
                                          for c in self.model.corners]
            comfort = m['a_v'] ** 2
            tyre = float(np.mean(np.square(fig['rms_tyre_load_ratio'])))
        a0, t0 = self.model.normalisation
        fig['cost'] = (comfort / a0 + rho * tyre / t0) / (1.0 + rho)
        return fig

    def references(self, road):
        """Episode-end references on ``road`` (``episode_end``) as a dict (may be empty)."""
        out = {}
        if self.episode_end in ('passive', 'bound'):
            out['passive'] = self.passive_figures(road, self.params.i_min)
        if self.episode_end == 'bound':
            out['bound'] = self.bound_figures(road)
        return out


def gap_closed(cost, refs):
    """
    Fraction of the passive-to-bound gap an episode closed: 0 passive, 1 the bound.

    ``(cost_passive - cost) / (cost_passive - cost_bound)``; NaN without both references.
    """
    if 'passive' not in refs or 'bound' not in refs:
        return math.nan
    gap = refs['passive']['cost'] - refs['bound']['cost']
    return (refs['passive']['cost'] - cost) / gap if gap > 0 else math.nan
