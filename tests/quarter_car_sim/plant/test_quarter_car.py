"""Tests of quarter_car_sim.plant.quarter_car: exactness, energy balance, tyre lift-off, forces."""
import math

import control
import numpy as np
import pytest

from quarter_car_sim.plant.quarter_car import LinearDamperPlant, QuarterCar, state_matrices
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import iso8608, make_road, RoadProfile, step

P = QuarterCarParams()


def _reference(params, road):
    a, b = state_matrices(params)
    sys = control.ss(a, b[:, [0]], np.eye(4), np.zeros((4, 1)))
    z0 = road.z[0]
    return control.forced_response(sys, road.t, road.z, X0=[z0, 0, z0, 0]).states.T


def _run(car, n, fn):
    s = car.state
    out = [[s.z_s, s.v_s, s.z_u, s.v_u]]
    for _ in range(n - 1):
        s = fn()
        out.append([s.z_s, s.v_s, s.z_u, s.v_u])
    return np.array(out)


def _flat(duration=5.0, dt=1e-3):
    t = np.arange(int(round(duration / dt)) + 1) * dt
    return RoadProfile(t, np.zeros_like(t), np.zeros_like(t))


def test_linear_damping_matches_forced_response_exactly():
    # c_s inside the exactly discretised linear part: python-control's forced_response (linear
    # input interpolation) and the simulator agree to rounding on an ISO 8608 class C road
    road = iso8608('C', 20.0, 5.0, 1e-3, rng=2)
    p = P.replace(c_s=1500.0)
    car = QuarterCar(p, None, road)
    x = _run(car, road.n, lambda: car.step_force(1e-3, 0.0))
    ref = _reference(p, road)
    np.testing.assert_allclose(x, ref, rtol=0, atol=1e-8 * np.abs(ref).max())


@pytest.mark.parametrize('substeps, tol', [(1, 0.03), (10, 0.003)])
def test_linear_damper_plant_matches_forced_response(substeps, tol):
    # the plant force is held over each (sub)step: first-order coupling error; stated tolerance
    # (max error / max value per state) 3 % at 1 ms, 0.3 % with 10 sub-steps
    road = iso8608('C', 20.0, 5.0, 1e-3, rng=2)
    car = QuarterCar(P, LinearDamperPlant(1500.0), road, substeps=substeps)
    x = _run(car, road.n, lambda: car.step(1e-3, 0.0))
    ref = _reference(P.replace(c_s=1500.0), road)
    err = np.asarray(np.abs(x - ref).max(axis=0) / np.abs(ref).max(axis=0))
    assert np.all(err < tol), err


def _energy(p, s):
    return (0.5 * p.m_s * s.v_s ** 2 + 0.5 * p.m_u * s.v_u ** 2
            + 0.5 * p.k_s * (s.z_s - s.z_u) ** 2 + 0.5 * p.k_t * (s.z_u - s.z_r) ** 2)


def test_free_vibration_conserves_energy_without_damping():
    car = QuarterCar(P, None, _flat())
    s0 = car.set_state(z_s=0.02, v_u=0.1)
    e0 = _energy(P, s0)
    es = [_energy(P, car.step_force(1e-3, 0.0)) for _ in range(5000)]
    np.testing.assert_allclose(es, e0, rtol=1e-9)


def test_free_vibration_dissipation_equals_integral_c_v2():
    p = P.replace(c_s=800.0)
    car = QuarterCar(p, None, _flat())
    s0 = car.set_state(z_s=0.03)
    states = [s0] + [car.step_force(1e-3, 0.0) for _ in range(3000)]
    vr = np.array([s.v_rel for s in states])
    dissipated = np.trapezoid(p.c_s * vr ** 2, dx=1e-3)
    lost = _energy(p, s0) - _energy(p, states[-1])
    assert lost == pytest.approx(dissipated, rel=1e-5)
    assert lost > 0.9 * _energy(p, s0)


def test_free_vibration_dissipation_with_damper_plant():
    # plant force held over each step: energy lost = sum of F_held * travel increments
    car = QuarterCar(P, LinearDamperPlant(800.0), _flat(), substeps=4)
    s0 = car.set_state(z_s=0.03, damper_force=0.0)
    states = [s0] + [car.step(1e-3, 0.0) for _ in range(3000)]
    vr = np.array([s.v_rel for s in states])
    dissipated = np.trapezoid(800.0 * vr ** 2, dx=1e-3)
    lost = _energy(P, s0) - _energy(P, states[-1])
    assert lost == pytest.approx(dissipated, rel=0.01)


def test_static_equilibrium_is_at_rest():
    road = _flat(2.0)
    car = QuarterCar(P, LinearDamperPlant(1000.0), road)
    for _ in range(2000):
        s = car.step(1e-3, 0.0)
    assert abs(s.z_s) < 1e-12 and abs(s.a_s) < 1e-9
    assert s.tyre_force == pytest.approx(P.static_tyre_load)


def test_tyre_cannot_pull_and_wheel_falls_freely():
    # the road drops by 10 cm: the wheel leaves it, tyre force is exactly 0 and the wheel
    # accelerates down with the weight of car and wheel on it: a_u = -(m_s + m_u) g / m_u
    road = step(height=-0.1, duration_s=4.0, start_s=0.1)
    car = QuarterCar(P, LinearDamperPlant(1500.0), road)
    states = [car.step(1e-3, 0.0) for _ in range(4000)]
    ft = np.array([s.tyre_force for s in states])
    assert ft.min() == 0.0
    free = QuarterCar(P, LinearDamperPlant(0.0), road)
    first = next(s for s in (free.step(1e-3, 0.0) for _ in range(1000)) if s.t > 0.1 + 1e-9)
    assert first.tyre_force == 0.0
    assert first.a_u == pytest.approx(-P.static_tyre_load / P.m_u, rel=0.01)
    airborne = [s for s in states if s.tyre_force == 0.0]
    assert all(s.z_u - s.z_r > -P.static_tyre_load / P.k_t - 1e-9 for s in airborne)
    # it lands again and settles on the lower road
    assert states[-1].tyre_force == pytest.approx(P.static_tyre_load, rel=0.05)


def test_step_force_static_deflection():
    # constant force F up on the body, down on the wheel: travel -> F / k_s, tyre load unchanged
    p = P.replace(c_s=3000.0)
    car = QuarterCar(p, None, _flat(10.0))
    for _ in range(8000):
        s = car.step_force(1e-3, 800.0)
    assert s.travel == pytest.approx(800.0 / p.k_s, rel=1e-4)
    assert s.tyre_force == pytest.approx(p.static_tyre_load, rel=1e-6)
    assert s.damper_force == 800.0 and math.isnan(s.coil_current)


def test_damper_force_sign_is_on_the_body():
    # extension (v_rel > 0) with a viscous damper: the force on the body points down
    car = QuarterCar(P, LinearDamperPlant(1000.0), _flat())
    car.set_state(v_s=0.2)
    s = car.step(1e-3, 0.0)
    assert s.v_rel > 0 and s.damper_force < 0
    assert s.damper_force == pytest.approx(-1000.0 * s.v_rel)


def test_bad_arguments():
    with pytest.raises(ValueError, match='substeps'):
        QuarterCar(P, None, _flat(), substeps=0)
    car = QuarterCar(P, None, _flat())
    with pytest.raises(RuntimeError, match='step_force'):
        car.step(1e-3, 0.0)
    with pytest.raises(ValueError, match='dt'):
        car.step_force(0.0, 0.0)


def test_periodic_road_repeats_seamlessly_and_a_plain_one_is_held():
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=3,
                     duration_s=2.0, repeat=True)
    assert road.periodic and road.duration == pytest.approx(2.0, abs=2e-3)
    period = road.n * road.dt
    car = QuarterCar(QuarterCarParams(), None, road)
    flat = QuarterCar(QuarterCarParams(), None, make_road(
        'iso8608', road_class='C', speed_m_s=20.0, rng=3, duration_s=2.0))
    for t in (0.0123, 0.5, 1.2345, road.t[-1] + 0.4 * road.dt):
        z0, zd0 = car._road_at(t)
        for lap in (1, 2, 7):
            z, zd = car._road_at(t + lap * period)
            assert z == pytest.approx(z0, abs=1e-12) and zd == pytest.approx(zd0, abs=1e-9)
    # across the seam the height moves by about one step of the road, no jump
    dz = max(abs(car._road_at(period - 1e-4 * k)[0] - car._road_at(period + 1e-4 * k)[0])
             for k in range(1, 5))
    assert dz < 20 * road.dt * np.max(np.abs(road.zdot))
    assert flat._road_at(period * 3.3) == (road.z[-1], 0.0)
