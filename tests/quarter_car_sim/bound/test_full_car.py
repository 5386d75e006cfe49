"""Tests of quarter_car_sim.bound.full_car: the full car's offline optimal semi-active bound."""
import numpy as np
import pytest

from bound_cases import WideLinearDamper
from mr_damper_model.identification import presets
from mr_damper_model.models.inverse import KwokCurrentInverse
from mr_damper_model.models.plant import KwokCurrentPlant
from quarter_car_sim.bound.quarter_car import KwokForceModel, semi_active_bound
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import compare_laws
from semi_active_control.car.full_car import PASSENGER_CAR, symmetric_car
from quarter_car_sim.bound.full_car import full_car_bound, impulse_responses
from quarter_car_sim.plant.two_track_road import same_road_all_wheels
from quarter_car_sim.plant.road import iso8608


def _run_forces(params, road, dt, u):
    """Drive the car by the corner forces ``u`` (n, 4); return the ISO axes and tyre loads."""
    car = FullCar(params, None, road)
    n = u.shape[0]
    acc = np.empty((n, 3))
    ft = np.empty((n, 4))
    s = car.state
    T = params.geometry
    inert = np.array([params.m_s, params.i_pitch, params.i_roll])
    for k in range(n):
        fs = u[k] - params.spring_matrix() @ s.travel - params.c_s * s.v_rel
        acc[k] = (T.T @ fs) / inert
        ft[k] = s.tyre_force - params.static_tyre_loads
        s = car.step_force(dt, u[k])
    return acc, ft


def _weighted(acc, dt):
    """ISO weighted seat axes (Wk z, 0.40 We pitch, 0.63 We roll) at the CG, shape (n, 3)."""
    from scipy import signal
    from semi_active_control.iso2631 import we_sos
    from semi_active_control.iso2631 import wk_sos
    fs = 1.0 / dt
    return np.column_stack([signal.sosfilt(wk_sos(fs), acc[:, 0]),
                            0.40 * signal.sosfilt(we_sos(fs), acc[:, 1]),
                            0.63 * signal.sosfilt(we_sos(fs), acc[:, 2])])


@pytest.mark.slow
def test_wide_linear_dampers_reproduce_the_unconstrained_optimum():
    # analytic limit: with no binding limit the bound is the least-squares optimum of the
    # quadratic cost over the four force sequences, built column by column from the car itself
    # (class A road: the wheels stay on the road, so the car is linear); the first period's
    # forces are the car's initial ones (0: no command reaches them), so they are no columns
    dt, rho = 2e-3, 0.5
    p = PASSENGER_CAR
    road = make_two_track_road('iso8608-A', p, speed_m_s=20.0, duration_s=0.2, dt=dt, rng=4)
    n = int(round(road.duration / dt)) + 1
    acc0, t0 = _run_forces(p, road, dt, np.zeros((n, 4)))
    y_a0 = _weighted(acc0, dt)
    a0 = np.sum(y_a0 ** 2) / n               # a_v^2 with no damper force at all
    t0_i = np.mean(t0 ** 2, axis=0)
    scale_t = np.sqrt(rho / (4.0 * t0_i))
    y0 = np.concatenate([(y_a0 / np.sqrt(a0)).ravel(order='F'),
                         (t0 * scale_t).ravel(order='F')])
    cols = []
    for j in range(4 * n):
        if j % n == 0:
            cols.append(np.zeros(y0.size))
            continue
        e = np.zeros((n, 4))
        e[j % n, j // n] = 1.0
        acc, ft = _run_forces(p, road, dt, e)
        cols.append(np.concatenate([(_weighted(acc, dt) / np.sqrt(a0)).ravel(order='F'),
                                    (ft * scale_t).ravel(order='F')]) - y0)
    m = np.column_stack(cols)
    u_opt = np.linalg.lstsq(m, -y0, rcond=None)[0]
    j_opt = float(np.sum((m @ u_opt + y0) ** 2)) / n

    res = full_car_bound(p, road, [WideLinearDamper()] * 4, rho=rho, dt=dt, outer=3,
                         maxiter=10000, kernel_s=1.0, settle_s=0.0)
    assert res.cost_start == pytest.approx(1.0 + rho)      # start: no damper force at all
    assert res.cost == pytest.approx(j_opt, rel=2e-3)
    assert res.cost >= j_opt * (1.0 - 1e-9)                 # cannot beat the optimum
    acc, ft = _run_forces(p, road, dt, res.force)
    y_res = np.concatenate([(_weighted(acc, dt) / np.sqrt(a0)).ravel(order='F'),
                            (ft * scale_t).ravel(order='F')])
    y_opt = m @ u_opt + y0
    assert np.linalg.norm(y_res - y_opt) < 0.1 * np.linalg.norm(y_opt)
    assert np.all(np.abs(res.current - 1.0) < 1e-2)         # far inside the current range


def test_impulse_responses_are_the_cars_own():
    # a unit force pulse at one corner through the nonlinear car (all wheels on a flat road)
    p, dt, n = PASSENGER_CAR, 1e-3, 400
    road = make_two_track_road('iso8608-A', p, speed_m_s=20.0, duration_s=1.0, dt=dt, rng=1)
    flat = type(road)(road.t, 0 * road.z_left, 0 * road.z_right, 0 * road.zdot_left,
                      0 * road.zdot_right, delay_s=road.delay_s)
    h = impulse_responses(p, dt, 0.0, n)
    for corner in (0, 3):
        u = np.zeros((n, 4))
        u[0, corner] = 1.0
        acc, ft = _run_forces(p, flat, dt, u)
        np.testing.assert_allclose(h[:3, corner].T, acc, atol=1e-12)
        np.testing.assert_allclose(h[11:15, corner].T, ft, atol=1e-9)


@pytest.fixture(scope='module')
def kwok_case():
    # each corner's damper model is its plant (no coil lag): the replay reproduces the plan
    _, truth = presets.thesis_kwok_current()
    inverse = KwokCurrentInverse(truth, tol_a=1e-6, sign_convention='body')
    plants = [KwokCurrentPlant(truth, coil_tau_s=0.0) for _ in range(4)]
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=3.0,
                               rng=2)
    res = full_car_bound(PASSENGER_CAR, road, [KwokForceModel(inverse)] * 4, plants,
                         [truth] * 4)
    return truth, plants, road, res


@pytest.mark.slow
def test_bound_is_no_worse_than_every_passive_setting_and_live_law(kwok_case):
    truth, plants, road, res = kwok_case
    a_v = res.metrics(PASSENGER_CAR)['a_v']
    laws = [f'passive@{i:g}A' for i in (0.0, 0.25, 0.5, 1.0, 1.5, 2.0)]
    laws += ['per-corner-skyhook', 'per-corner-clipped-optimal-wk', 'modal-skyhook',
             'full-car-clipped-optimal', 'full-car-clipped-optimal-wk']
    others = {k: m['a_v'] for k, m in compare_laws(PASSENGER_CAR, road, laws, plants,
                                                   [truth] * 4).items()}
    worse = {k: v for k, v in others.items() if v < a_v}
    assert not worse, f'bound {a_v:.4f} beaten by {worse}'
    assert a_v < 0.97 * min(others.values())
    assert res.cost < res.cost_start
    assert res.cost == min(res.cost_history)


@pytest.mark.slow
def test_bound_respects_every_corners_limits_at_every_step(kwok_case):
    _, _, _, res = kwok_case
    assert np.all(res.force >= res.force_lo - 1e-6) and np.all(res.force <= res.force_hi + 1e-6)
    assert np.all((res.current >= 0.0) & (res.current <= 2.0))
    at_limit = ((np.abs(res.force - res.force_lo) < 1e-6)
                | (np.abs(res.force - res.force_hi) < 1e-6))
    assert np.all(np.mean(at_limit, axis=0) > 0.2)          # the limits bind at every corner
    # the limits are each corner's damper range at the state the run reached
    p = res.predicted
    lo, hi = KwokForceModel(KwokCurrentInverse(presets.thesis_kwok_current()[1],
                                               sign_convention='body')).body_force_range_array(
        p.travel[:, 2], p.v_rel[:, 2])
    k0 = res.force.shape[0] - p.t.size
    np.testing.assert_allclose(res.force_lo[k0:, 2], lo, atol=1e-9)
    np.testing.assert_allclose(res.force_hi[k0:, 2], hi, atol=1e-9)


@pytest.mark.slow
def test_replayed_currents_make_the_planned_ride(kwok_case):
    res = kwok_case[3]
    rep = res.replay
    assert rep.law == 'bound'
    k0 = res.force.shape[0] - rep.t.size                   # the settling samples
    assert res.t0 == pytest.approx(-0.5) and k0 == 500
    np.testing.assert_allclose(rep.current_cmd[:-1], res.current[k0 + 1:], atol=1e-12)
    # the plants are the model and the plan starts where the replay does (the first period's
    # forces the car's own), so the replay follows the plan to the inverse's tolerance
    # (1e-6 A), on any machine: before, a first force the replay could not make started it
    # off the plan, and the model's jump at zero travel spread that by round-off (issue 32)
    assert np.max(np.abs(rep.damper_force[1:] - res.force[k0 + 1:])) < 1e-3
    m_rep = rep.metrics(PASSENGER_CAR)
    for key in ('a_v', 'a_wz', 'a_w_pitch', 'a_w_roll'):
        assert m_rep[key] == pytest.approx(res.predicted_metrics[key], rel=1e-5)
    # the cost is the metric: J = a_v^2 / a_v(start)^2, the start being every damper at 0 A
    # (here the plant is the model, so passive 0 A on the plants is that start, up to the
    # simulation's force timing: the plant's force reaches the record one sample later)
    truth, plants, road, _ = kwok_case
    a_v0 = compare_laws(PASSENGER_CAR, road, ['passive@0A'], plants,
                        [truth] * 4)['passive@0.0A']['a_v']
    assert res.cost == pytest.approx((res.predicted_metrics['a_v'] / a_v0) ** 2, rel=0.02)


@pytest.mark.slow
def test_heave_only_symmetric_car_gives_the_quarter_car_bound():
    # quarter-car limit: the same road under all four wheels of a symmetric car excites heave
    # only, so the full-car bound is the quarter-car bound of one corner
    car = symmetric_car()
    qc = car.corner(0)
    prof = iso8608('C', 20.0, 2.0, 1e-3, rng=3)
    _, truth = presets.thesis_kwok_current()
    model = KwokForceModel(KwokCurrentInverse(truth, tol_a=1e-6, sign_convention='body'))
    full = full_car_bound(car, same_road_all_wheels(prof), [model] * 4, settle_s=0.0)
    quarter = semi_active_bound(qc, prof, model, settle_s=0.0)
    # (the corner forces need not be equal: a warp pattern (+ - - +) moves no body mode and
    # is free in a comfort-only cost, so only the body's motion is compared)
    m = full.predicted_metrics
    assert m['a_w_pitch'] < 1e-2 * m['a_wz'] and m['a_w_roll'] < 1e-2 * m['a_wz']
    assert m['a_wz'] == pytest.approx(quarter.predicted_metrics['rms_body_accel_wk'], rel=0.005)
    assert full.cost == pytest.approx(quarter.cost, rel=0.005)


@pytest.mark.parametrize('kw, msg', [
    (dict(rho=-1.0), 'rho'), (dict(dt=0.0), 'dt'), (dict(settle_s=-1.0), 'settle_s'),
    (dict(outer=-1), 'outer'), (dict(models=3), 'force_models')])
def test_bad_arguments_are_refused(kw, msg):
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, duration_s=0.2, rng=1)
    n = kw.pop('models', 4)
    with pytest.raises(ValueError, match=msg):
        full_car_bound(PASSENGER_CAR, road, [WideLinearDamper()] * n, **kw)
