"""Tests of quarter_car_sim.bound.preview_mpc: the receding-horizon MPC with road preview."""
import numpy as np
import pytest

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import KwokCurrentPlant
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import simulate_full_car
from semi_active_control.car.full_car import PASSENGER_CAR
from quarter_car_sim.bound.full_car import corner_force_model
from semi_active_control.laws.full_car_lqr_wk import FullCarClippedOptimalWk
from semi_active_control.laws.full_car_preview import FedFullCarLaw, make_full_car_preview_law
from quarter_car_sim.bound.preview_mpc import make_full_car_mpc_preview
from quarter_car_sim.plant.preview_sensor import IDEAL_LOOK_AHEAD, LookAheadSpec, PreviewFeed

P = PASSENGER_CAR


@pytest.fixture(scope='module')
def kwok():
    _, truth = presets.thesis_kwok_current()
    return truth, [KwokCurrentPlant(truth, coil_tau_s=0.0) for _ in range(4)]


def test_the_prediction_is_the_cars_own_response(kwok):
    # from a moving state on a known road, with F = -c_ref v_rel, the linear prediction of the
    # travels, their rates and the body accelerations is the stepwise car's (wheels on the road)
    truth, _ = kwok
    law = make_full_car_mpc_preview(P, [corner_force_model(truth, P)] * 4, horizon_s=0.2)
    road = make_two_track_road('iso8608-A', P, speed_m_s=20.0, duration_s=1.0, rng=2)
    car = FullCar(P, None, road)
    s = car.state
    for k in range(300):                                  # a state that moves
        s = car.step_force(1e-3, 200.0 * np.sin(0.05 * k + np.arange(4)))
    H = law.H
    heights = np.array([road.at(s.t + k * 1e-3)[0] for k in range(H + 1)])
    z = (s.z_r[None, :] + heights - heights[0]).T
    x0 = np.concatenate([s.q, s.v])
    y = law._M @ x0 - law._MR1 @ z[:, 0] + law._conv_z(z[:, :H]).T
    out = np.empty((H, 11))
    for k in range(H):
        f = s.damper_force if k == 0 else -law.c_ref * s.v_rel
        fs = f - P.spring_matrix() @ s.travel - P.c_s * s.v_rel
        acc = (fs @ P.geometry) / np.array([P.m_s, P.i_pitch, P.i_roll])
        out[k] = np.concatenate([acc, s.travel, s.v_rel])
        s = car.step_force(1e-3, -law.c_ref * s.v_rel)
    # (sample 0: the prediction's force is -c_ref v_rel, the car's the one acting)
    np.testing.assert_allclose(y[1:, 3:], out[1:, 3:], atol=1e-9)
    np.testing.assert_allclose(y[1:, :3], out[1:, :3], atol=1e-6)


def test_plans_come_every_update_and_the_forces_are_dissipative(kwok):
    truth, plants = kwok
    road = make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=1.0, rng=3)
    law = make_full_car_mpc_preview(P, [corner_force_model(truth, P)] * 4, maxiter=30)
    fed = FedFullCarLaw(law, PreviewFeed(law.road, road, IDEAL_LOOK_AHEAD))
    res = simulate_full_car(P, road, fed, plants, [truth] * 4, settle_s=0.0, duration_s=0.3)
    st = law.status()
    # a plan every 20 periods once the map reaches the rear wheels (the first frame starts
    # 0.5 m ahead of the front axle: wheelbase + 0.5 m = 2.85 m, 143 periods at 20 m/s)
    assert st['law']['fallback_steps'] == pytest.approx(143, abs=2)
    assert st['plans'] == pytest.approx(st['law']['previewed_steps'] / 20, abs=1)
    # every applied force is inside the damper's range at the measured state (the projection),
    # and dissipative after the law's clip
    assert np.all(res.demand * res.v_rel <= 1e-9)
    assert len(law.solve_s) == st['plans']


@pytest.mark.slow
def test_mpc_beats_the_lq_preview_on_the_car(kwok):
    truth, plants = kwok
    road = make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=2.0, rng=1)
    lq = make_full_car_preview_law(P, source='look-ahead')
    mpc = make_full_car_mpc_preview(P, [corner_force_model(truth, P)] * 4)
    a_v = {}
    for law in (lq, mpc):
        fed = FedFullCarLaw(law, PreviewFeed(law.road, road, IDEAL_LOOK_AHEAD))
        a_v[law.name] = simulate_full_car(P, road, fed, plants, [truth] * 4).metrics(P)['a_v']
    assert a_v[mpc.name] < 0.95 * a_v[lq.name]


@pytest.mark.slow
def test_an_mpc_dropout_falls_back_to_todays_law_and_is_counted(kwok):
    # no frame at all after 0.2 s: once the map is driven through (15 m = 0.75 s) the law is
    # full-car-clipped-optimal-wk, exactly, step for step
    truth, plants = kwok
    road = make_two_track_road('iso8608-C', P, speed_m_s=20.0, duration_s=1.5, rng=4)
    mpc = make_full_car_mpc_preview(P, [corner_force_model(truth, P)] * 4)
    fed = FedFullCarLaw(mpc, PreviewFeed(mpc.road, road, LookAheadSpec(outages=((0.2, 9.0),))))
    base = FullCarClippedOptimalWk.from_car(P)
    rows = []

    class Spy:
        name, corner_laws = 'spy', mpc.corner_laws

        def reset(self):
            fed.reset()
            base.reset()

        def prepare(self, state):
            out = fed.prepare(state)
            rows.append((state.t, mpc.stats.fallback_steps, mpc.desired.copy(),
                         base.desired_forces(state)))
            return out

    simulate_full_car(P, road, Spy(), plants, [truth] * 4, settle_s=0.0)
    t = np.array([r[0] for r in rows])
    fallbacks = np.array([r[1] for r in rows])
    falling = np.diff(np.concatenate([[0], fallbacks])) > 0
    late = t > 1.2
    assert falling[late].all()
    for r, f in zip(rows, falling):
        if f:
            np.testing.assert_allclose(r[2], r[3], atol=1e-9)
    assert mpc.stats.dropouts == 2                                # the start and the outage
