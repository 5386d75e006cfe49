"""The vector environments: N cars stepped together equal N single environments."""
import gymnasium
import numpy as np
import pytest

import mr_damper_gym
from mr_damper_gym import ActionError, SemiActiveVectorEnv

KW = dict(plant='kwok-current', duration_s=0.04)


@pytest.mark.slow
@pytest.mark.parametrize('env_id', [mr_damper_gym.QUARTER_CAR_ID, mr_damper_gym.FULL_CAR_ID])
@pytest.mark.parametrize('threads', [1, 2], ids=['one_thread', 'two_threads'])
def test_the_vector_env_equals_single_envs_with_the_same_seeds(env_id, threads):
    n = 3
    venv = gymnasium.make_vec(env_id, num_envs=n, threads=threads, **KW)
    assert isinstance(venv, SemiActiveVectorEnv) and venv.batch.threads == threads
    envs = [gymnasium.make(env_id, episode_end='passive', **KW) for _ in range(n)]
    obs, _ = venv.reset(seed=10)
    assert np.array_equal(obs, np.array([e.reset(seed=10 + i)[0] for i, e in enumerate(envs)]))
    rng = np.random.default_rng(0)
    ended = [False] * n
    episodes = 0
    for _ in range(100):                    # two and a half episodes: autoresets included
        a = rng.uniform(venv.single_action_space.low, venv.single_action_space.high, (n, 4))
        a = a[:, :venv.single_action_space.shape[0]]
        vo, vr, vterm, vtrunc, vinfo = venv.step(a)
        assert not vterm.any()
        for i, e in enumerate(envs):
            if ended[i]:                    # next-step autoreset: reset, the action unused
                o, _ = e.reset()
                r, trunc = 0.0, False
                ended[i] = False
            else:
                o, r, _, trunc, info = e.step(a[i])
                if trunc:
                    ended[i] = True
                    episodes += 1
                    assert vinfo['_episode'][i]
                    assert vinfo['episode']['cost'][i] == info['episode']['cost']
                    assert (vinfo['reference']['passive']['cost'][i]
                            == info['reference']['passive']['cost'])
            assert np.array_equal(o, vo[i]) and r == vr[i] and trunc == vtrunc[i]
    assert episodes == 2 * n
    venv.close()


def test_partial_reset_and_bad_actions():
    venv = gymnasium.make_vec(mr_damper_gym.FULL_CAR_ID, num_envs=2, **KW)
    obs, _ = venv.reset(seed=1)
    for _ in range(5):
        obs, *_ = venv.step(np.zeros((2, 4)))
    again, info = venv.reset(options={'reset_mask': np.array([False, True])})
    assert np.array_equal(again[0], obs[0]) and not np.array_equal(again[1], obs[1])
    assert info['_road'].tolist() == [False, True]
    bad = np.zeros((2, 4))
    bad[1, 2] = np.nan
    with pytest.raises(ActionError, match='NaN'):
        venv.step(bad)
    with pytest.raises(ActionError, match='per car'):
        venv.step(np.zeros(3))
    _, _, _, _, info = venv.step(np.full((2, 4), 5.0))
    assert info['action_clipped'].tolist() == [True, True]
    assert np.all(info['current_a'] == 2.0)


@pytest.mark.slow
def test_cars_out_of_step_equal_single_envs_through_their_autoresets():
    # car 1 restarts 10 steps after car 0: steps where one car resets while the other steps
    n = 2
    venv = gymnasium.make_vec(mr_damper_gym.QUARTER_CAR_ID, num_envs=n, threads=1, **KW)
    envs = [gymnasium.make(mr_damper_gym.QUARTER_CAR_ID, episode_end='passive', **KW)
            for _ in range(n)]
    venv.reset(seed=3)
    for i, e in enumerate(envs):
        e.reset(seed=3 + i)
    a = np.full((n, 1), 0.7)
    for _ in range(10):
        venv.step(a)
        for e in envs:
            e.step(a[0])
    venv.reset(options={'reset_mask': np.array([False, True])})
    envs[1].reset()
    ended, mixed = [False] * n, 0
    for _ in range(90):
        vo, vr, _, vtrunc, vinfo = venv.step(a)
        mixed += sum(ended) == 1
        for i, e in enumerate(envs):
            if ended[i]:
                o, _ = e.reset()
                r, trunc, stepped = 0.0, False, False
                ended[i] = False
            else:
                o, r, _, trunc, info = e.step(a[i])
                ended[i], stepped = trunc, True
                assert vinfo['t_s'][i] == info['t_s']
                assert vinfo['rms_body_accel_wk'][i] == info['rms_body_accel_wk']
            assert np.array_equal(o, vo[i]) and r == vr[i] and trunc == vtrunc[i]
            assert vinfo['_rms_body_accel_wk'][i] == stepped
    assert mixed >= 4                       # two restarts of each car, never together
    venv.close()
