"""
The suite's laws run as policies through the environments equal the offline tools.

Same road (the episode's road seed), the same "true" Spencer plants and the same identified set
(the environment's), both runs starting at rest at t = 0 (no settling: the env settles at
``i_min``, the tools with the law, which on a road this short moves the pitch and roll figures by
a few percent; bench/bench_gym.py compares the settled runs on 20 s roads): the env's figures
equal those of ``simulate`` / ``simulate_full_car``, the cores of ``quarter-car-sim`` /
``full-car-sim``, to round-off.
"""
import gymnasium
import pytest

import mr_damper_gym
from mr_damper_gym.baselines import FULL_BASELINES, LawPolicy, QUARTER_BASELINES, run_episode
from mr_damper_model.models.plant import make_plant
from semi_active_control.laws import make_controller
from quarter_car_sim.simulate.full_car import simulate_full_car
from quarter_car_sim.simulate.quarter_car import simulate

DURATION_S = 2.0


def _env(env_id, action):
    return gymnasium.make(env_id, observation='state', action=action, plant='spencer',
                          episode_end='none', duration_s=DURATION_S, settle_s=0.0)


@pytest.mark.slow
@pytest.mark.parametrize('name', list(QUARTER_BASELINES))
def test_quarter_car_laws_equal_quarter_car_sim(name):
    env = _env(mr_damper_gym.QUARTER_CAR_ID, QUARTER_BASELINES[name])
    info = run_episode(env, LawPolicy(env, name), seed=1, options={'road_seed': 2})
    core, road = env.unwrapped.core, env.unwrapped.road
    law = make_controller(name, params=core.params, inverse=core.inverses[0], dt=core.dt)
    m = simulate(core.params, road, law, make_plant('spencer'), inverse=core.inverses[0],
                 dt=core.dt, settle_s=0.0).metrics()
    e = info['episode']
    for key in ('rms_body_accel_wk', 'rms_tyre_load_ratio', 'rms_suspension_travel'):
        assert e[key] == pytest.approx(m[key], rel=1e-6), key
    assert info['n_action_clipped'] == 0


@pytest.mark.slow
@pytest.mark.parametrize('name', list(FULL_BASELINES))
def test_full_car_laws_equal_full_car_sim(name):
    env = _env(mr_damper_gym.FULL_CAR_ID, FULL_BASELINES[name])
    info = run_episode(env, LawPolicy(env, name), seed=1, options={'road_seed': 2})
    core, road = env.unwrapped.core, env.unwrapped.road
    m = simulate_full_car(core.params, road, name, [make_plant('spencer') for _ in range(4)],
                          core.damper_params, dt=core.dt, settle_s=0.0).metrics(core.params)
    e = info['episode']
    for key in ('a_v', 'a_wz', 'a_w_pitch', 'a_w_roll', 'max_rms_tyre_load_ratio'):
        assert e[key] == pytest.approx(m[key], rel=1e-6), key
    assert info['n_action_clipped'] == 0


def test_a_law_needs_the_true_state_and_its_action_kind():
    env = gymnasium.make(mr_damper_gym.QUARTER_CAR_ID, plant='kwok-current',
                         episode_end='none', duration_s=0.1)
    with pytest.raises(ValueError, match="observation='state'"):
        LawPolicy(env, 'skyhook')
    env = gymnasium.make(mr_damper_gym.QUARTER_CAR_ID, plant='kwok-current', observation='state',
                         episode_end='none', duration_s=0.1)
    with pytest.raises(ValueError, match="action='force'"):
        LawPolicy(env, 'skyhook')
