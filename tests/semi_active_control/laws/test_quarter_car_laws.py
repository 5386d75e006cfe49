"""Tests of semi_active_control.laws: passivity of the laws, the inverse path, names."""
import math

import numpy as np
import pytest

from mr_damper_model.identification import presets
from mr_damper_model.models.inverse import inverse_current, KwokCurrentInverse
from mr_damper_model.models.plant import KwokCurrentPlant
from semi_active_control import laws as ctl
from semi_active_control.iso2631 import wk_state_space
from mr_damper_common.contract import CornerState

SEMI_ACTIVE = [ctl.Skyhook(), ctl.Skyhook(4000.0, 0.0), ctl.SkyhookOnOff(), ctl.Groundhook(),
               ctl.Hybrid(alpha=0.0), ctl.Hybrid(alpha=0.5), ctl.Hybrid(alpha=1.0), ctl.ADD(),
               ctl.SkyhookIdeal(), ctl.ShAdd(), ctl.ShAdd(8000.0, 300.0, 0.5),
               ctl.ClippedOptimal(ctl.clipped_optimal_gain()),
               ctl.ClippedOptimal(ctl.clipped_optimal_gain(),
                                  KwokCurrentInverse(
                                      presets.thesis_kwok_current()[1], tol_a=1e-4,
                                      sign_convention='body').body_force_range)]


def _random_states(n, seed=0):
    g = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        vs, vu = g.normal(0, 0.3, 2)
        zs, zu, zr = g.normal(0, 0.02, 3)
        out.append(CornerState(0.0, zs, vs, g.normal(0, 3.0), zu, vu, g.normal(0, 20.0), zr,
                               zs - zu, vs - vu, 3500.0, 0.0, 0.0))
    return out


def _law_id(law):
    # the same in every process (pytest-xdist workers compare their ids): no object's address
    return law.name + repr({k: (type(v).__name__ if callable(v) else v)
                            for k, v in vars(law).items()})


@pytest.mark.parametrize('law', SEMI_ACTIVE, ids=_law_id)
def test_semi_active_laws_never_demand_wrong_sign(law):
    states = _random_states(5000)
    d = np.array([law.demand(s) for s in states])
    vr = np.array([s.v_rel for s in states])
    assert np.all(d * vr <= 0.0)
    assert np.mean(d != 0.0) > 0.2          # and they do act


def test_skyhook_law_values():
    s = CornerState(0, 0, 0.3, 0, 0, 0.1, 0, 0, 0, 0.2, 0, 0, 0)
    assert ctl.Skyhook(2000.0, 0.0).demand(s) == pytest.approx(-600.0)
    assert ctl.Skyhook(2000.0, 100.0).demand(s) == pytest.approx(-620.0)
    s2 = CornerState(0, 0, -0.3, 0, 0, -0.5, 0, 0, 0, 0.2, 0, 0, 0)   # v_s v_rel < 0: off
    assert ctl.Skyhook(2000.0, 0.0).demand(s2) == 0.0
    assert ctl.Groundhook(1000.0).demand(s2) == pytest.approx(-500.0)


def test_lqr_active_feedback():
    k = [1.0, 2.0, 3.0, 4.0]
    s = CornerState(0, 0.1, 0.2, 0, 0.05, 0.3, 0, 0.01, 0.05, -0.1, 0, 0, 0)
    expected = -(1.0 * 0.05 + 2.0 * 0.2 + 3.0 * (0.05 - 0.01) + 4.0 * 0.3)
    assert ctl.LqrActive(k).demand(s) == pytest.approx(expected)


def test_inverse_path_delivers_the_demanded_force_on_the_plant():
    # identified parameters == plant parameters, no coil lag: the plant makes the demanded
    # force to within 0.5 N wherever the demand is reachable
    _, truth = presets.thesis_kwok_current()
    inv = KwokCurrentInverse(truth, tol_a=1e-5, sign_convention='body')
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
            lo, hi = inv.force(0.0, x, v), inv.force(2.0, x, v)
            assert -f_body < min(lo, hi) + 1e-6 or -f_body > max(lo, hi) - 1e-6
    assert n_reach > 1000


def test_fast_inverse_agrees_with_mr_damper_model_inverse():
    _, truth = presets.thesis_kwok_current()
    inv = KwokCurrentInverse(truth, tol_a=1e-6, sign_convention='body')
    g = np.random.default_rng(2)
    n = 4000
    f, x, v = g.uniform(-900, 900, n), g.normal(0, 0.02, n), g.normal(0, 0.3, n)
    ref = inverse_current(f, x, v, truth)
    mine = np.array([inv.current(-a, b, c) for a, b, c in zip(f, x, v)])
    ok = ref.reachable
    # reachable demands: the same force (the current itself may differ where F(i) is flat)
    fm = np.array([inv.force(i, b, c) for b, c, i in zip(x[ok], v[ok], mine[ok, 0])])
    np.testing.assert_allclose(fm, f[ok], atol=0.05)
    # saturated low / high: the same end of the range
    low = ref.saturated_low
    high = ref.saturated_high
    assert np.mean(mine[low, 0] == 0.0) > 0.99 and np.mean(mine[high, 0] == 2.0) > 0.99
    # unreachable, non-monotone cases (nearest force inside the range): at most 10 N further
    # from the demand than the vectorised inverse's dense scan
    other = ~ok & ~low & ~high
    fo = np.array([inv.force(i, b, c)
                   for b, c, i in zip(x[other], v[other], mine[other, 0])])
    assert np.all(np.abs(fo - f[other]) <= np.abs(ref.force[other] - f[other]) + 10.0)
    assert np.all(mine[other, 1] != 0.0)


def test_inverse_rejects_bad_params():
    _, truth = presets.thesis_kwok_current()
    bad = dict(truth)
    del bad['beta0']
    with pytest.raises(ValueError, match='beta0'):
        KwokCurrentInverse(bad, tol_a=1e-4, sign_convention='body')
    bad = dict(truth, c0=float('nan'))
    with pytest.raises(ValueError, match='finite'):
        KwokCurrentInverse(bad, tol_a=1e-4, sign_convention='body')


@pytest.mark.parametrize('name, cls', [('skyhook', ctl.Skyhook), ('skyhook-onoff',
                                       ctl.SkyhookOnOff), ('groundhook', ctl.Groundhook),
                                       ('hybrid', ctl.Hybrid), ('add', ctl.ADD),
                                       ('skyhook-ideal', ctl.SkyhookIdeal),
                                       ('sh-add', ctl.ShAdd),
                                       ('clipped-optimal', ctl.ClippedOptimal),
                                       ('clipped-optimal-wk', ctl.ClippedOptimalWk),
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


def _state(v_s=0.0, a_s=0.0, v_rel=0.0, travel=0.0, z_u=0.0, z_r=0.0, v_u=None):
    v_u = v_s - v_rel if v_u is None else v_u
    return CornerState(0.0, travel + z_u, v_s, a_s, z_u, v_u, 0.0, z_r, travel, v_rel, 3500.0,
                       0.0, 0.0)


@pytest.mark.parametrize('v_s, a_s, v_rel, law, high', [
    # alpha = 1 / (2 pi 2 Hz) = 0.0796 s: |v_s| >= alpha |a_s| -> skyhook choice
    (0.2, 1.0, 0.1, 'skyhook', True),       # v_s v_rel > 0 -> c_max
    (0.2, 1.0, -0.1, 'skyhook', False),     # v_s v_rel < 0 -> c_min (ADD would say c_max)
    (-0.2, -1.0, -0.1, 'skyhook', True),
    (0.2, -2.5, 0.1, 'skyhook', True),      # 0.2 >= 0.199: still skyhook
    # |v_s| < alpha |a_s| -> ADD choice
    (0.2, -2.6, 0.1, 'add', False),         # a_s v_rel < 0 -> c_min (skyhook would say c_max)
    (0.01, 1.0, 0.1, 'add', True),          # a_s v_rel > 0 -> c_max
    (-0.01, 1.0, 0.1, 'add', True),         # skyhook would say c_min
    (0.01, -1.0, -0.1, 'add', True),
])
def test_sh_add_switches_as_its_condition_says(v_s, a_s, v_rel, law, high):
    c = ctl.ShAdd(4000.0, 300.0, 2.0)
    s = _state(v_s, a_s, v_rel)
    assert c.alpha == pytest.approx(1.0 / (4.0 * math.pi))
    assert (v_s ** 2 - c.alpha ** 2 * a_s ** 2 >= 0.0) == (law == 'skyhook')
    assert c.choice(s) == law
    assert c.demand(s) == pytest.approx(-(4000.0 if high else 300.0) * v_rel)
    # the same choice as the underlying laws in that state
    ref = ctl.SkyhookOnOff(4000.0, 300.0) if law == 'skyhook' else ctl.ADD(4000.0, 300.0)
    assert c.demand(s) == ref.demand(s)


def test_sh_add_rejects_bad_gains():
    with pytest.raises(ValueError, match='c_min'):
        ctl.ShAdd(100.0, 200.0)
    with pytest.raises(ValueError, match='f_switch_hz'):
        ctl.ShAdd(f_switch_hz=0.0)


def test_clipped_optimal_is_the_lqr_force_when_feasible_and_clipped_otherwise():
    gain = ctl.clipped_optimal_gain()
    inv = KwokCurrentInverse(presets.thesis_kwok_current()[1], tol_a=1e-4,
                             sign_convention='body')
    law = ctl.ClippedOptimal(gain, inv.body_force_range)
    lqr = ctl.LqrActive(gain)
    states = _random_states(4000, seed=3)
    n_equal = n_clipped = 0
    for s in states:
        f_lqr = lqr.demand(s)
        assert law.desired(s) == f_lqr
        lo, hi = inv.body_force_range(s.travel, s.v_rel)
        lo_d, hi_d = (lo, min(hi, 0.0)) if s.v_rel > 0 else (max(lo, 0.0), hi)
        d = law.demand(s)
        if lo_d <= f_lqr <= hi_d:
            assert d == f_lqr
            n_equal += 1
        else:
            # clipped: the nearest end of the reachable, dissipative range (0 if none)
            assert d * s.v_rel <= 0.0
            if lo_d <= hi_d:
                assert d == pytest.approx(lo_d if f_lqr < lo_d else hi_d)
                assert lo - 1e-9 <= d <= hi + 1e-9
            n_clipped += 1
    assert n_equal > 200 and n_clipped > 200


def test_clipped_optimal_without_range_clips_to_dissipative_only():
    law = ctl.ClippedOptimal([0.0, 1000.0, 0.0, 0.0])     # F = -1000 v_s
    assert law.demand(_state(v_s=0.3, v_rel=0.1)) == pytest.approx(-300.0)
    assert law.demand(_state(v_s=0.3, v_rel=-0.1)) == 0.0
    assert law.demand(_state(v_s=-0.3, v_rel=-0.1)) == pytest.approx(300.0)
    assert law.demand(_state(v_s=0.3, v_rel=0.0)) == 0.0


def test_clipped_optimal_gain_is_the_lqr_design():
    from semi_active_control.car.quarter_car_linear import lqr_design
    from semi_active_control.car.quarter_car import QuarterCarParams
    ref = lqr_design(QuarterCarParams(), **ctl.DEFAULT_CO_WEIGHTS).gain
    np.testing.assert_allclose(ctl.clipped_optimal_gain(), ref)
    with pytest.raises(ValueError, match='unknown LQR weight'):
        ctl.clipped_optimal_gain(q_magic=1.0)


def test_make_controller_clipped_optimal_uses_the_inverse_range():
    inv = KwokCurrentInverse(presets.thesis_kwok_current()[1], tol_a=1e-4,
                             sign_convention='body')
    c = ctl.make_controller('clipped-optimal', inverse=inv)
    assert c.force_range == inv.body_force_range
    assert ctl.make_controller('clipped-optimal').force_range is None


# frequency-shaped clipped-optimal (clipped-optimal-wk)

def _body_accel_states(a, dt=1e-3, seed=0):
    """States at t = k dt with body acceleration ``a`` and random other fields."""
    g = np.random.default_rng(seed)
    out = []
    for k, ak in enumerate(a):
        vs, vu = g.normal(0, 0.3, 2)
        zs, zu, zr = g.normal(0, 0.02, 3)
        out.append(CornerState(k * dt, zs, vs, float(ak), zu, vu, 0.0, zr, zs - zu, vs - vu,
                               3500.0, 0.0, 0.0))
    return out


@pytest.mark.parametrize('weights', [{'q_tyre': 1e3, 'r_force': 1e-5, 'q_travel': 0.0},
                                     {'q_tyre': 1e4, 'r_force': 1e-6, 'q_travel': 1e3}])
def test_wk_design_without_filter_is_the_plain_clipped_optimal_design(weights):
    # an identity filter: a_wk = a_s, so q_wk + q_accel is the plain acceleration weight
    d = ctl.wk_lqr_design(weighting='none', q_wk=0.25, q_accel=0.75, **weights)
    np.testing.assert_allclose(d.gain, ctl.clipped_optimal_gain(q_accel=1.0, **weights),
                               rtol=1e-7)
    law = ctl.ClippedOptimalWk(d)
    ref = ctl.ClippedOptimal(ctl.clipped_optimal_gain(q_accel=1.0, **weights))
    for s in _random_states(500, seed=5):
        assert law.demand(s) == pytest.approx(ref.demand(s), rel=1e-6, abs=1e-9)


def test_wk_design_model_is_the_car_in_series_with_the_wk_filter():
    # independent truth: python-control's series connection of the car (force -> a_s) and the
    # Wk filter has the frequency response of the design model's force -> a_wk
    import control
    from semi_active_control.car.quarter_car_linear import linear_model
    from semi_active_control.car.quarter_car import QuarterCarParams
    d = ctl.wk_lqr_design()
    car = linear_model(QuarterCarParams())
    truth = control.series(control.ss(car.A, car.B[:, [1]], car.C[[0]], car.D[[0], [1]]),
                           wk_state_space())
    cw = np.concatenate([np.asarray(d.filter.D).ravel()[0] * car.C[0],
                         np.asarray(d.filter.C).ravel()])
    dw = float(np.asarray(d.filter.D).ravel()[0] * car.D[0, 1])
    mine = control.ss(d.A, d.B, cw.reshape(1, -1), [[dw]])
    w = 2 * np.pi * np.logspace(-1, 2, 40)          # 0.1 .. 100 Hz
    np.testing.assert_allclose(mine(1j * w).ravel(), truth(1j * w).ravel(), rtol=1e-9)


def test_wk_design_is_optimal_among_gains_that_ignore_the_filter():
    # LQR truth: with white road velocity into the augmented car (its design model, checked
    # above), the expected cost of the optimal gain (trace(P B_r B_r')) is below that of any
    # other stabilising gain, here the plain (a_s-weighted) clipped-optimal gain with zeros on
    # the filter states, same weights
    import control
    from semi_active_control.car.quarter_car_linear import linear_model
    from semi_active_control.car.quarter_car import QuarterCarParams
    w = {'q_tyre': 1e3, 'r_force': 3e-6}
    d = ctl.wk_lqr_design(**w)
    car = linear_model(QuarterCarParams())
    n = d.A.shape[0]
    nw = n - 4
    Br = np.concatenate([car.B[:, 0], np.zeros(nw)]).reshape(n, 1)

    def cost(k):
        k = k.reshape(1, n)
        acl = d.A - d.B @ k
        assert np.all(np.linalg.eigvals(acl).real < 0.0)
        qk = d.Q - d.N @ k - k.T @ d.N.T + k.T @ d.R @ k
        p = control.lyap(acl.T, 0.5 * (qk + qk.T))
        return float(np.trace(Br.T @ p @ Br))

    plain = np.concatenate([ctl.clipped_optimal_gain(q_accel=1.0, **w), np.zeros(nw)])
    j_opt, j_plain = cost(d.gain), cost(plain)
    assert j_opt < j_plain
    # and it is a minimum: small changes of the gain do not lower the cost
    g = np.random.default_rng(4)
    for _ in range(5):
        assert cost(d.gain * (1.0 + 0.02 * g.normal(size=n))) >= j_opt * (1.0 - 1e-9)


def test_wk_filter_inside_the_law_is_the_metric_wk_filter():
    from semi_active_control.iso2631 import wk_filter
    g = np.random.default_rng(6)
    a = np.cumsum(g.normal(0.0, 0.5, 3000)) * 0.05 + g.normal(0.0, 1.0, 3000)
    law = ctl.ClippedOptimalWk(ctl.wk_lqr_design(), dt=1e-3)
    out = []
    for s in _body_accel_states(a):
        law.demand(s)
        out.append(law.a_wk)
    ref = wk_filter(a, 1000.0)
    np.testing.assert_allclose(out, ref, atol=1e-9 * np.max(np.abs(ref)))
    # a repeated state (same t) does not step the filter; reset() starts again from rest
    law.demand(s)
    assert law.a_wk == out[-1]
    law.reset()
    for s in _body_accel_states(a[:50]):
        law.demand(s)
    np.testing.assert_allclose(law.a_wk, ref[49], atol=1e-12)


def test_clipped_optimal_wk_feeds_back_the_analog_filter_state():
    # the law's force is -K [x, w] with w the analog Wk state: for a slow sine the bilinear
    # filter's trapezoidal state estimate equals the exact analog response (lsim) closely
    import control
    d = ctl.wk_lqr_design()
    dt = 1e-3
    t = np.arange(4000) * dt
    a = np.sin(2.0 * np.pi * 1.5 * t)
    resp = control.forced_response(d.filter, t, a, return_x=True)
    w_exact = resp.states.T
    law = ctl.ClippedOptimalWk(d, dt=dt)
    k = d.gain
    f_law, f_exact = [], []
    for j, s in enumerate(_body_accel_states(a, dt)):
        x = np.array([s.travel, s.v_s, s.z_u - s.z_r, s.v_u])
        f_law.append(law.desired(s))
        f_exact.append(-(k[:4] @ x + k[4:] @ w_exact[j]))
    err = np.array(f_law) - np.array(f_exact)
    assert np.max(np.abs(err[2000:])) < 1e-3 * np.max(np.abs(f_exact))


@pytest.mark.slow
def test_clipped_optimal_wk_on_the_car_is_dissipative_and_within_the_damper_range():
    from mr_damper_model.models.plant import KwokCurrentPlant
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.plant.road import iso8608
    from quarter_car_sim.simulate.quarter_car import simulate
    model, truth = presets.thesis_kwok_current()
    inv = KwokCurrentInverse(truth, i_ref_a=model.options['i_ref_a'], tol_a=1e-4,
                             sign_convention='body')
    plant = KwokCurrentPlant(truth, i_ref_a=model.options['i_ref_a'], coil_tau_s=0.0)
    params = QuarterCarParams()
    law = ctl.make_controller('clipped-optimal-wk', params=params, inverse=inv,
                              damper_only=True)
    road = iso8608('C', 20.0, 4.0, 1e-3, rng=3)
    r = simulate(params, road, law, plant, inverse=inv)
    assert np.all(r.demand * r.v_rel <= 0.0)
    rng = np.array([inv.body_force_range(x, v) for x, v in zip(r.travel, r.v_rel)])
    act = r.v_rel != 0.0
    assert np.all(r.demand[act] >= np.minimum(rng[act, 0], 0.0) - 1e-9)
    assert np.all(r.demand[act] <= np.maximum(rng[act, 1], 0.0) + 1e-9)
    assert np.mean(r.demand != 0.0) > 0.5 and np.mean(r.saturated) < 0.9
    # the same run again (simulate resets the law): the same demands
    np.testing.assert_array_equal(simulate(params, road, law, plant, inverse=inv).demand,
                                  r.demand)


def test_clipped_optimal_wk_rejects_bad_input():
    with pytest.raises(ValueError, match='unknown LQR weight'):
        ctl.wk_lqr_design(q_magic=1.0)
    with pytest.raises(ValueError, match='r_force'):
        ctl.wk_lqr_design(r_force=0.0)
    with pytest.raises(ValueError, match='q_tyre'):
        ctl.wk_lqr_design(q_tyre=-1.0)
    with pytest.raises(ValueError, match='weighting'):
        ctl.wk_lqr_design(weighting='iso')
    with pytest.raises(ValueError, match='dt'):
        ctl.ClippedOptimalWk(ctl.wk_lqr_design(), dt=0.0)
    with pytest.raises(ValueError, match='designs its own gain'):
        ctl.make_controller('clipped-optimal-wk', lqr_gain=[1.0, 2.0, 3.0, 4.0])
    d = ctl.wk_lqr_design()
    d.gain = d.gain[:6]
    with pytest.raises(ValueError, match='gain'):
        ctl.ClippedOptimalWk(d)
