"""Full-car clipped-optimal LQR: heave part equals the quarter car's LQR, warp ignored."""
import numpy as np
import pytest

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import simulate_full_car
from semi_active_control.laws.registry import make_full_car_law
from semi_active_control.car.full_car import PASSENGER_CAR, symmetric_car
from semi_active_control.laws.full_car_lqr import full_car_lqr_design, relative_model
from semi_active_control.car.quarter_car_linear import lqr_design
from semi_active_control.car.quarter_car import QuarterCarParams


def test_relative_model_matches_the_absolute_car():
    # the road-relative model's body accelerations equal those of the car's own matrices
    from semi_active_control.car.full_car_linear import state_matrices
    p = PASSENGER_CAR.replace(k_arb_f=7000.0, c_s_f=300.0)
    A, B = state_matrices(p)
    Ar, Br, _, _, n = relative_model(p)
    rng = np.random.default_rng(1)
    q, v, f = rng.normal(size=7), rng.normal(size=7), rng.normal(size=4) * 100
    x_abs = np.concatenate([q, v])
    acc = (A @ x_abs + B[:, 8:12] @ f)[7:]          # flat road
    T = p.geometry
    x_rel = np.concatenate([T @ q[:3] - q[3:], q[3:], v])
    np.testing.assert_allclose((Ar @ x_rel + Br @ f)[8:], acc, rtol=1e-10, atol=1e-9)
    assert np.allclose(T.T @ n, 0.0) and np.isclose(np.linalg.norm(n), 1.0)


def test_heave_part_of_a_symmetric_car_is_the_quarter_car_lqr():
    car = symmetric_car(i_pitch=1500.0, i_roll=600.0)
    w = dict(q_travel=1e3, q_tyre=1e4, r_force=1e-6)
    # the full-car cost weighs the body's heave once; four quarter cars weigh it four times
    d = full_car_lqr_design(car, q_heave=4.0, q_pitch=0.3, q_roll=0.5, **w)
    qc = QuarterCarParams(m_s=car.m_s / 4, m_u=car.m_u_f, k_s=car.k_s_f, k_t=car.k_t)
    k = lqr_design(qc, q_accel=1.0, **w).gain        # [travel, v_s, z_u - z_r, v_u]
    s, v, tyre, vu = 0.01, 0.2, -0.003, -0.1
    x = np.concatenate([[s] * 4, [tyre] * 4, [v, 0.0, 0.0], [vu] * 4])
    np.testing.assert_allclose(-d.gain @ x, -(k @ [s, v, tyre, vu]), rtol=1e-6)
    assert np.all(d.poles.real < 0)


def test_gain_ignores_the_road_warp_and_the_law_is_dissipative():
    d = full_car_lqr_design(PASSENGER_CAR)
    _, _, _, _, n = relative_model(PASSENGER_CAR)
    warp = np.concatenate([n, n, np.zeros(7)])
    np.testing.assert_allclose(d.gain @ warp, 0.0, atol=1e-9 * np.abs(d.gain).max())
    assert np.all(d.poles.real < 0)
    with pytest.raises(ValueError, match='unknown LQR weight'):
        full_car_lqr_design(PASSENGER_CAR, q_yaw=1.0)
    law = make_full_car_law('full-car-clipped-optimal', PASSENGER_CAR)
    _assert_dissipative_on_a_short_road(law)


def _assert_dissipative_on_a_short_road(law):
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=0.5,
                               rng=3)
    kw = presets.thesis_kwok_current()[1]
    res = simulate_full_car(PASSENGER_CAR, road, law,
                            [make_plant('kwok-current') for _ in range(4)], [kw] * 4)
    assert res.normal.all()
    assert np.all(res.demand * res.v_rel <= 0.0)        # every demand dissipative
    assert np.ptp(res.current_cmd) > 0.3


def test_weighted_law_runs_on_the_car_with_dissipative_demands():
    from semi_active_control.laws.full_car_lqr_wk import FullCarClippedOptimalWk
    law = make_full_car_law('full-car-clipped-optimal-wk', PASSENGER_CAR)
    assert isinstance(law, FullCarClippedOptimalWk) and law.name == 'full-car-clipped-optimal-wk'
    _assert_dissipative_on_a_short_road(law)
    assert np.any(np.abs(law.weighted) > 0)             # the filters ran on the car
