"""Tests of the inverse current-dependent Kwok model."""
import numpy as np
import pytest

from mr_damper_model.models.inverse import inverse_current, KwokCurrentInverse
from mr_damper_model.models.presets import thesis_kwok_current


def _samples(n, seed):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-0.03, 0.03, n), rng.uniform(-0.25, 0.25, n),
            rng.uniform(0.0, 2.0, n))


@pytest.mark.parametrize('beta1', [-0.3, 0.0])
def test_round_trip(beta1):
    model, p = thesis_kwok_current()
    p = dict(p, beta1=beta1)
    x, v, i = _samples(5000, 1)
    f_des = model.force(model.from_dict(p), x, v, i)
    r = inverse_current(f_des, x, v, p)
    assert r.reachable.mean() > 0.999
    f_back = model.force(model.from_dict(p), x, v, r.current)
    np.testing.assert_allclose(f_back[r.reachable], f_des[r.reachable], atol=1e-5)
    np.testing.assert_allclose(r.force, f_back, atol=1e-9)
    # where F(i) is monotone and clearly sensitive to i (moving away from the centre, where
    # the delta shift adds to the velocity term) the current itself comes back
    sens = (np.abs(v) > 0.05) & (np.sign(x) == np.sign(v))
    np.testing.assert_allclose(r.current[sens], i[sens], atol=1e-6)


def test_saturation_flags():
    model, p = thesis_kwok_current()
    x = np.array([0.01, -0.01, 0.0, -0.02])
    v = np.array([0.2, -0.2, 0.15, -0.1])
    wrong = -np.sign(v) * 100.0
    r = inverse_current(wrong, x, v, p)
    assert np.all(r.current == 0.0) and np.all(r.saturated_low) and not r.reachable.any()
    f_max = model.force(model.from_dict(p), x, v, np.full(4, 2.0))
    r = inverse_current(f_max * 1.5, x, v, p)
    assert np.all(r.current == 2.0) and np.all(r.saturated_high)
    np.testing.assert_allclose(r.force, f_max)
    assert not (r.saturated_low | r.reachable).any()


def test_non_monotone_gives_nearest_force():
    model, p = thesis_kwok_current()
    # x > 0 while moving down: |F(i)| peaks inside the current range (delta shift, beta1 < 0)
    grid = np.linspace(0.0, 2.0, 4001)
    f_grid = model.force(model.from_dict(p), np.full(grid.size, 0.02),
                         np.full(grid.size, -0.1), grid)
    assert 0 < np.argmin(f_grid) < grid.size - 1
    r = inverse_current([1.5 * f_grid.min()], [0.02], [-0.1], p)
    assert not (r.reachable[0] or r.saturated_low[0] or r.saturated_high[0])
    assert r.force[0] == pytest.approx(f_grid.min(), abs=0.05)


def test_scalar_inverse_matches():
    model, p = thesis_kwok_current()
    inv = KwokCurrentInverse(p)
    x, v, i = _samples(200, 2)
    f_des = model.force(model.from_dict(p), x, v, i)
    for k in range(200):
        cur, flag = inv.current(f_des[k], x[k], v[k])
        if flag == 0:
            assert inv.force(cur, x[k], v[k]) == pytest.approx(f_des[k], abs=1e-5)
    assert inv.current(-500.0, 0.0, 0.2) == (0.0, -1)
    assert inv.current(5000.0, 0.0, 0.2) == (2.0, 1)


def test_bad_input():
    _, p = thesis_kwok_current()
    with pytest.raises(ValueError, match='f_des'):
        inverse_current([np.nan], [0.0], [0.1], p)
    with pytest.raises(ValueError, match='i_max'):
        inverse_current([1.0], [0.0], [0.1], p, i_min=2.0, i_max=1.0)
    with pytest.raises(ValueError, match='missing'):
        inverse_current([1.0], [0.0], [0.1], {'c0': 1.0})


def test_scalar_round_trip_is_exact_and_flag_zero_only_when_reachable():
    # demands the model makes at a known current: each is reachable (flag 0) and the current
    # found makes it again to the solver's force tolerance 1e-9 (1 + |F|) N
    model, p = thesis_kwok_current()
    inv = KwokCurrentInverse(p)
    x, v, i = _samples(2000, 3)
    f_des = model.force(model.from_dict(p), x, v, i)
    for k in range(x.size):
        cur, flag = inv.current(f_des[k], x[k], v[k])
        assert flag == 0 and 0.0 <= cur <= 2.0
        assert abs(inv.force(cur, x[k], v[k]) - f_des[k]) <= 1e-9 * (1.0 + abs(f_des[k]))
    # out of reach: never flag 0, the current is an end of the range or the nearest force's
    for f, x_, v_ in ((-500.0, 0.0, 0.2), (5000.0, 0.0, 0.2), (500.0, 0.0, -0.2)):
        assert inv.current(f, x_, v_)[1] != 0


def test_body_sign_convention_is_the_negated_model_demand():
    # the body convention (force on the car body, positive up) is the model convention with
    # the demand negated: the same current to the last bit, the flag negated
    model, p = thesis_kwok_current()
    model_inv = KwokCurrentInverse(p, tol_a=1e-4)
    body_inv = KwokCurrentInverse(p, tol_a=1e-4, sign_convention='body')
    rng = np.random.default_rng(4)
    n = 3000
    f, x, v = rng.uniform(-1500, 1500, n), rng.normal(0, 0.02, n), rng.normal(0, 0.3, n)
    flags = set()
    for k in range(n):
        cur_m, flag_m = model_inv.current(-f[k], x[k], v[k])
        cur_b, flag_b = body_inv.current(f[k], x[k], v[k])
        assert cur_b == cur_m and flag_b == -flag_m
        flags.add(flag_b)
    assert flags == {-1, 0, 1}
    lo, hi = body_inv.body_force_range(0.01, 0.2)
    assert (lo, hi) == tuple(sorted((-model_inv.force(0.0, 0.01, 0.2),
                                     -model_inv.force(2.0, 0.01, 0.2))))
    assert body_inv.params == {k: float(p[k]) for k in model.param_names}
    with pytest.raises(ValueError, match='sign_convention'):
        KwokCurrentInverse(p, sign_convention='up')


@pytest.mark.parametrize('lag', [False, True])
def test_compiled_scalar_inverse_is_its_plain_python_source(lag):
    # the compiled kernel runs scalar_current's own source: interpreted, the same function
    # gives the same currents and flags, on reachable, saturated and non-monotone demands
    from mr_damper_model.models.inverse import KwokCurrentLagInverse
    from mr_damper_model.models.scalar_inverse import scalar_current
    model, p = thesis_kwok_current()
    p = dict(p, beta1=-0.3)
    if lag:
        inv = KwokCurrentLagInverse(list(model.from_dict(p)) + [0.003, 0.008])
        inv.step(100.0, 0.01, 0.1, 1e-3)           # a lag state after a first sample
    else:
        inv = KwokCurrentInverse(p)
    x, v, i = _samples(300, 4)
    f_des = model.force(model.from_dict(p), x, v, i) * np.linspace(-1.5, 1.5, 300)
    flags = set()
    for k in range(x.size):
        args = (inv._q, inv._lim, inv._grid, inv._dense, float(f_des[k]), float(x[k]),
                float(v[k]))
        cur, flag = inv._kernels[0](*args)
        assert (cur, flag) == scalar_current(*args)
        flags.add(flag)
    assert flags == {-1, 0, 1}
