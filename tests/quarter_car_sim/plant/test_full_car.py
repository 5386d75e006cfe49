"""Full car (7-DOF): modal frequencies, static loads, quarter-car limits, energy."""
import math

import numpy as np
import pytest

from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.quarter_car import LinearDamperPlant, QuarterCar
from quarter_car_sim.plant.full_car import FullCar, mechanical_energy
from semi_active_control.car.full_car import PASSENGER_CAR, symmetric_car
from semi_active_control.car.full_car_linear import natural_frequencies, state_matrices
from quarter_car_sim.plant.two_track_road import same_road_all_wheels, TwoTrackRoad
from semi_active_control.car.quarter_car_linear import analytic_frequencies
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import bump, RoadProfile


def _flat(duration=3.0, dt=1e-3):
    t = np.arange(int(round(duration / dt)) + 1) * dt
    z = np.zeros_like(t)
    return TwoTrackRoad(t, z, z, z, z)


def test_modal_frequencies_of_symmetric_car_match_hand_computed():
    # a symmetric car splits into heave, pitch, roll and warp modes; each body mode is a
    # 2-DOF quarter car with the mode's equivalent corner mass (M / 4, I / (4 l^2), ...)
    m, l, tr, mu, ks, kt, karb = 1300.0, 1.35, 1.5, 42.0, 26000.0, 185000.0, 6000.0
    w = tr / 2
    ip, ir = 0.8 * m * l * l, 0.6 * m * w * w
    car = symmetric_car(m_s=m, i_pitch=ip, i_roll=ir, half_wheelbase=l, track=tr, m_u=mu,
                        k_s=ks, k_t=kt, k_arb=karb)
    expected = []
    for m_eq, k_eq in ((m / 4, ks), (ip / (4 * l * l), ks), (ir / (4 * w * w), ks + 2 * karb)):
        expected += analytic_frequencies(QuarterCarParams(m_s=m_eq, m_u=mu, k_s=k_eq, k_t=kt))
    expected.append(math.sqrt((ks + 2 * karb + kt) / mu) / (2 * math.pi))     # warp
    np.testing.assert_allclose(natural_frequencies(car), np.sort(expected), rtol=1e-9)


def test_passenger_car_body_modes_in_ride_range():
    f = natural_frequencies(PASSENGER_CAR)
    assert 1.0 < f[0] < f[1] < f[2] < 2.5          # heave / pitch / roll
    assert np.all((f[3:] > 8.0) & (f[3:] < 16.0))  # wheel hop


def test_static_tyre_loads_from_axle_distances():
    p = PASSENGER_CAR.replace(k_arb_f=8000.0)
    A, _ = state_matrices(p)
    K = -p.mass_matrix @ A[7:, :7]
    gravity = -p.g * np.diag(p.mass_matrix) * np.array([1, 0, 0, 1, 1, 1, 1])
    q = np.linalg.solve(K, gravity)            # sag under gravity from unloaded springs
    tyre = -p.k_t * q[3:]
    L = p.a + p.b
    front = p.m_s * p.g * p.b / (2 * L) + p.m_u_f * p.g
    rear = p.m_s * p.g * p.a / (2 * L) + p.m_u_r * p.g
    np.testing.assert_allclose(tyre, [front, front, rear, rear], rtol=1e-12)
    np.testing.assert_allclose(p.static_tyre_loads, tyre, rtol=1e-12)
    assert tyre.sum() == pytest.approx((p.m_s + 2 * p.m_u_f + 2 * p.m_u_r) * p.g, rel=1e-12)


def test_car_at_rest_on_flat_road_stays_at_rest():
    car = FullCar(PASSENGER_CAR, None, _flat())
    for _ in range(100):
        s = car.step_force(1e-3, np.zeros(4))
    assert np.max(np.abs(s.q)) < 1e-15 and np.max(np.abs(s.acc)) < 1e-12
    np.testing.assert_allclose(s.tyre_force, PASSENGER_CAR.static_tyre_loads, rtol=1e-14)


@pytest.mark.parametrize('plant', ['kwok-current', 'spencer'])
@pytest.mark.slow
def test_heave_only_symmetric_car_is_the_quarter_car(plant):
    car_p = symmetric_car(i_pitch=900.0, i_roll=400.0)      # inertias do not matter here
    qc_p = QuarterCarParams(m_s=car_p.m_s / 4, m_u=car_p.m_u_f, k_s=car_p.k_s_f, k_t=car_p.k_t)
    prof = bump(0.05, 1.0, 10.0, 1.5)
    fc = FullCar(car_p, [make_plant(plant) for _ in range(4)], same_road_all_wheels(prof))
    qc = QuarterCar(qc_p, make_plant(plant), prof)
    peak = 0.0
    for k in range(prof.n - 1):
        cur = 0.4 + 0.3 * math.sin(0.01 * k)
        s = fc.step(1e-3, [cur] * 4)
        r = qc.step(1e-3, cur)
        for i in range(4):
            assert s.travel[i] == pytest.approx(r.travel, abs=1e-10)
            assert s.q[3 + i] == pytest.approx(r.z_u, abs=1e-10)
            assert s.tyre_force[i] == pytest.approx(r.tyre_force, rel=1e-9)
            assert s.body_a[i] == pytest.approx(r.a_s, abs=1e-7)
        assert s.q[0] == pytest.approx(r.z_s, abs=1e-10)
        assert abs(s.q[1]) < 1e-12 and abs(s.q[2]) < 1e-12
        peak = max(peak, abs(r.travel))
    assert peak > 0.01             # the bump did move the suspension


@pytest.mark.slow
def test_dynamic_index_one_axles_ride_as_independent_quarter_cars():
    # I_pitch = m a b: front and rear decouple, each a quarter car with its static mass share
    p = PASSENGER_CAR.replace(i_pitch=PASSENGER_CAR.m_s * PASSENGER_CAR.a * PASSENGER_CAR.b)
    speed, dt = 2.348 / 0.25, 1e-3             # delay 0.25 s = 250 samples
    prof = bump(0.04, 1.5, speed, 2.0, start_s=0.6)
    shift = 250
    road = TwoTrackRoad(prof.t, prof.z, prof.z, prof.zdot, prof.zdot, delay_s=0.25)
    assert road.delay_s == pytest.approx(p.wheelbase / speed)
    fc = FullCar(p, [LinearDamperPlant(1200.0) for _ in range(4)], road)
    front = RoadProfile(prof.t[:-shift], prof.z[shift:], prof.zdot[shift:])
    qcs = [QuarterCar(p.corner(i), LinearDamperPlant(1200.0), road_i)
           for i, road_i in ((0, front), (2, prof))]
    pitch = 0.0
    for _ in range(1500):
        s = fc.step(1e-3, [0.0] * 4)
        pitch = max(pitch, abs(s.q[1]))
        for i, qc in zip((0, 2), qcs):
            r = qc.step(dt, 0.0)
            assert s.travel[i] == pytest.approx(r.travel, abs=1e-9)
            assert s.tyre_force[i] == pytest.approx(r.tyre_force, rel=1e-8)
    assert pitch > 2e-3            # the body pitched, yet the axles stayed independent


@pytest.mark.slow
def test_free_vibration_without_dampers_conserves_energy():
    p = PASSENGER_CAR.replace(k_arb_f=9000.0, k_arb_r=4000.0)
    car = FullCar(p, None, _flat())
    car.set_state(np.array([0.01, 0.005, -0.004, 0.0, 0.001, 0.0, -0.002]),
                  v=np.array([0.1, 0.05, 0.2, 0.0, 0.0, 0.1, 0.0]))
    e0 = mechanical_energy(p, car.state)
    es = [mechanical_energy(p, car.step_force(1e-3, np.zeros(4))) for _ in range(2000)]
    np.testing.assert_allclose(es, e0, rtol=1e-9)


@pytest.mark.slow
def test_dampers_dissipate_exactly_their_power():
    p = PASSENGER_CAR.replace(k_arb_f=9000.0)
    car = FullCar(p, [LinearDamperPlant(c) for c in (1400.0, 1400.0, 1600.0, 1600.0)], _flat())
    car.set_state(np.zeros(7), v=np.array([0.3, 0.2, -0.3, 0.0, 0.0, 0.0, 0.0]))
    dt = 1e-4
    e_prev = mechanical_energy(p, car.state)
    e0 = e_prev
    dissipated = 0.0
    for _ in range(20000):
        s0 = car.state
        s1 = car.step(dt, [0.0] * 4)
        e = mechanical_energy(p, s1)
        assert e <= e_prev + 1e-12                       # passive: never gains energy
        e_prev = e
        # damper power F v_rel (force held over the step: F of the start, v_rel averaged)
        dissipated -= dt * float(s0.damper_force @ (0.5 * (s0.v_rel + s1.v_rel)))
    assert e0 - e_prev == pytest.approx(dissipated, rel=2e-3)
    assert e_prev < 0.05 * e0
