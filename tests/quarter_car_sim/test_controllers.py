"""Tests of quarter_car_sim.controllers: passivity of the laws, the inverse path, names."""
import math

import numpy as np
import pytest

from mr_damper_model import presets
from mr_damper_model.inverse import inverse_current
from mr_damper_model.plant import KwokCurrentPlant
from quarter_car_sim import controllers as ctl
from quarter_car_sim.dynamics import CarState

SEMI_ACTIVE = [ctl.Skyhook(), ctl.Skyhook(4000.0, 0.0), ctl.SkyhookOnOff(), ctl.Groundhook(),
               ctl.Hybrid(alpha=0.0), ctl.Hybrid(alpha=0.5), ctl.Hybrid(alpha=1.0), ctl.ADD(),
               ctl.SkyhookIdeal()]


def _random_states(n, seed=0):
    g = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        vs, vu = g.normal(0, 0.3, 2)
        zs, zu, zr = g.normal(0, 0.02, 3)
        out.append(CarState(0.0, zs, vs, g.normal(0, 3.0), zu, vu, g.normal(0, 20.0), zr,
                            zs - zu, vs - vu, 3500.0, 0.0, 0.0))
    return out


@pytest.mark.parametrize('law', SEMI_ACTIVE, ids=lambda c: c.name + repr(vars(c)))
def test_semi_active_laws_never_demand_wrong_sign(law):
    states = _random_states(5000)
    d = np.array([law.demand(s) for s in states])
    vr = np.array([s.v_rel for s in states])
    assert np.all(d * vr <= 0.0)
    assert np.mean(d != 0.0) > 0.2          # and they do act


def test_skyhook_law_values():
    s = CarState(0, 0, 0.3, 0, 0, 0.1, 0, 0, 0, 0.2, 0, 0, 0)
    assert ctl.Skyhook(2000.0, 0.0).demand(s) == pytest.approx(-600.0)
    assert ctl.Skyhook(2000.0, 100.0).demand(s) == pytest.approx(-620.0)
    s2 = CarState(0, 0, -0.3, 0, 0, -0.5, 0, 0, 0, 0.2, 0, 0, 0)   # v_s v_rel < 0: off
    assert ctl.Skyhook(2000.0, 0.0).demand(s2) == 0.0
    assert ctl.Groundhook(1000.0).demand(s2) == pytest.approx(-500.0)


def test_lqr_active_feedback():
    k = [1.0, 2.0, 3.0, 4.0]
    s = CarState(0, 0.1, 0.2, 0, 0.05, 0.3, 0, 0.01, 0.05, -0.1, 0, 0, 0)
    expected = -(1.0 * 0.05 + 2.0 * 0.2 + 3.0 * (0.05 - 0.01) + 4.0 * 0.3)
    assert ctl.LqrActive(k).demand(s) == pytest.approx(expected)


def test_inverse_path_delivers_the_demanded_force_on_the_plant():
    # identified parameters == plant parameters, no coil lag: the plant makes the demanded
    # force to within 0.5 N wherever the demand is reachable
    _, truth = presets.thesis_kwok_current()
    inv = ctl.KwokCurrentInverse(truth, tol_a=1e-5)
    plant = KwokCurrentPlant(truth, coil_tau_s=0.0)
    g = np.random.default_rng(1)
    n_reach = 0
    for _ in range(3000):
        x, v = g.normal(0, 0.02), g.normal(0, 0.3)
        f_body = -g.uniform(0.0, 900.0) * math.copysign(1.0, v)      # dissipative demand
        i, sat = inv.current(f_body, x, v)
        assert 0.0 <= i <= 2.0
        plant.reset()
        plant.step(0.0, x, v, i)
        f = plant.step(1e-3, x, v, i)
        if not sat:
            n_reach += 1
            assert -f == pytest.approx(f_body, abs=0.5)
        else:
            lo, hi = inv.model_force(x, v, 0.0), inv.model_force(x, v, 2.0)
            assert -f_body < min(lo, hi) + 1e-6 or -f_body > max(lo, hi) - 1e-6
    assert n_reach > 1000


def test_fast_inverse_agrees_with_mr_damper_model_inverse():
    _, truth = presets.thesis_kwok_current()
    inv = ctl.KwokCurrentInverse(truth, tol_a=1e-6)
    g = np.random.default_rng(2)
    n = 4000
    f, x, v = g.uniform(-900, 900, n), g.normal(0, 0.02, n), g.normal(0, 0.3, n)
    ref = inverse_current(f, x, v, truth)
    mine = np.array([inv.current(-a, b, c) for a, b, c in zip(f, x, v)])
    ok = ref.reachable
    # reachable demands: the same force (the current itself may differ where F(i) is flat)
    fm = np.array([inv.model_force(b, c, i) for b, c, i in zip(x[ok], v[ok], mine[ok, 0])])
    np.testing.assert_allclose(fm, f[ok], atol=0.05)
    # saturated low / high: the same end of the range
    low = ref.saturated_low
    high = ref.saturated_high
    assert np.mean(mine[low, 0] == 0.0) > 0.99 and np.mean(mine[high, 0] == 2.0) > 0.99
    # unreachable, non-monotone cases (nearest force inside the range): at most 10 N further
    # from the demand than the vectorised inverse's dense scan
    other = ~ok & ~low & ~high
    fo = np.array([inv.model_force(b, c, i)
                   for b, c, i in zip(x[other], v[other], mine[other, 0])])
    assert np.all(np.abs(fo - f[other]) <= np.abs(ref.force[other] - f[other]) + 10.0)
    assert np.all(mine[other, 1] == 1.0)


def test_inverse_rejects_bad_params():
    _, truth = presets.thesis_kwok_current()
    bad = dict(truth)
    del bad['beta0']
    with pytest.raises(ValueError, match='beta0'):
        ctl.KwokCurrentInverse(bad)
    bad = dict(truth, c0=float('nan'))
    with pytest.raises(ValueError, match='finite'):
        ctl.KwokCurrentInverse(bad)


@pytest.mark.parametrize('name, cls', [('skyhook', ctl.Skyhook), ('skyhook-onoff',
                                       ctl.SkyhookOnOff), ('groundhook', ctl.Groundhook),
                                       ('hybrid', ctl.Hybrid), ('add', ctl.ADD),
                                       ('skyhook-ideal', ctl.SkyhookIdeal),
                                       ('lqr-active', ctl.LqrActive)])
def test_make_controller_names(name, cls):
    c = ctl.make_controller(name)
    assert isinstance(c, cls) and c.name == name


@pytest.mark.parametrize('i, name', [(0.0, 'passive@0.0A'), (0.5, 'passive@0.5A'),
                                     (0.25, 'passive@0.25A'), (2.0, 'passive@2.0A')])
def test_passive_names(i, name):
    assert ctl.Passive(i).name == name
    assert ctl.make_controller(name).current_a == i


def test_unknown_controller():
    with pytest.raises(ValueError, match='unknown controller'):
        ctl.make_controller('magic')
