"""Full-car control: modal skyhook mapping and clipping, per-corner laws, corner fail-safe."""
import math

import numpy as np
import pytest

from mr_damper_common.contract import IdentifiedSet
from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from semi_active_control.laws import Skyhook
from semi_active_control.supervision.failsafe import ModelSupervisor
from quarter_car_sim.plant.full_car import FullCar
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.simulate.full_car import simulate_full_car
from semi_active_control.runtime.full_car_controller_core import FullCarController
from semi_active_control.laws.full_car import ModalSkyhook
from semi_active_control.laws.registry import make_full_car_law
from semi_active_control.car.full_car import PASSENGER_CAR, symmetric_car
from quarter_car_sim.plant.two_track_road import same_road_all_wheels
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import bump
from quarter_car_sim.simulate.quarter_car import identified_set_of, make_inverse, simulate

KW = presets.thesis_kwok_current()[1]


class _State:
    def __init__(self, v, v_rel):
        self.v = np.asarray(v, dtype=float)
        self.v_rel = np.asarray(v_rel, dtype=float)


def test_modal_skyhook_maps_modes_to_corners_and_clips_each_damper():
    p = PASSENGER_CAR
    law = ModalSkyhook(p.geometry, 3000.0, 2500.0, 1200.0, c_p=100.0)
    T = p.geometry
    rng = np.random.default_rng(0)
    for _ in range(200):
        v = np.concatenate([rng.normal(0, 0.2, 3), np.zeros(4)])
        v_rel = rng.normal(0, 0.2, 4)
        forces = law.prepare(_State(v, v_rel))
        # unclipped: the corner forces make exactly the modal sky forces (+ the passive part)
        q = T.T @ (law.desired + 100.0 * v_rel)
        np.testing.assert_allclose(q, -np.array([3000.0, 2500.0, 1200.0]) * v[:3], atol=1e-9)
        for f, d, vr in zip(forces, law.desired, v_rel):
            assert f * vr <= 0.0                         # a damper can only dissipate
            assert f == (d if d * vr < 0 else 0.0)       # dissipative demands pass unchanged


def test_modal_gains_from_damping_ratios():
    law = ModalSkyhook.from_car(PASSENGER_CAR, zeta={'heave': 0.5, 'pitch': 0.0, 'roll': 1.0})
    assert law.c_modal[1] == 0.0
    from semi_active_control.laws.full_car import body_mode_stiffness
    k_h, _, k_r = body_mode_stiffness(PASSENGER_CAR)
    assert law.c_modal[0] == pytest.approx(2 * 0.5 * math.sqrt(k_h * PASSENGER_CAR.m_s))
    assert law.c_modal[2] == pytest.approx(2 * math.sqrt(k_r * PASSENGER_CAR.i_roll))
    with pytest.raises(ValueError, match='unknown full-car law'):
        make_full_car_law('sideways', PASSENGER_CAR)


@pytest.mark.slow
def test_per_corner_skyhook_on_heave_only_car_is_the_quarter_car_loop():
    # the same law, inverse and plant per corner: the full car's supervised loop reproduces
    # the quarter car's offline loop when the body only heaves
    car_p = symmetric_car()
    qc_p = QuarterCarParams(m_s=car_p.m_s / 4, m_u=car_p.m_u_f, k_s=car_p.k_s_f, k_t=car_p.k_t)
    prof = bump(0.05, 1.0, 10.0, 1.5)
    law = make_full_car_law('per-corner-skyhook', car_p)
    assert all(isinstance(cl, Skyhook) for cl in law.corner_laws)
    res = simulate_full_car(car_p, same_road_all_wheels(prof), law,
                            [make_plant('kwok-current') for _ in range(4)], [KW] * 4)
    ref = simulate(qc_p, prof, Skyhook(), make_plant('kwok-current'), inverse=make_inverse(KW))
    assert res.normal.all()
    for i in range(4):
        np.testing.assert_allclose(res.current_cmd[:, i], ref.current_cmd, atol=1e-6)
        np.testing.assert_allclose(res.travel[:, i], ref.travel, atol=1e-9)
    np.testing.assert_allclose(res.q[:, 0], ref.z_s, atol=1e-9)
    assert np.ptp(ref.current_cmd) > 0.5


@pytest.mark.parametrize('law', ['modal-skyhook', 'per-corner-skyhook'])
@pytest.mark.slow
def test_one_corner_without_model_fails_safe_and_the_others_control(law):
    p = PASSENGER_CAR
    road = make_two_track_road('iso8608-C', p, speed_m_s=20.0, duration_s=1.0, rng=1)
    ctl = FullCarController(make_full_car_law(law, p), timeout_s=1e9, safe_current_a=0.7)
    res = simulate_full_car(p, road, law, [make_plant('kwok-current') for _ in range(4)],
                            [None, KW, KW, KW], controller=ctl)
    assert not res.normal[:, 0].any()
    assert np.all(res.current_cmd[:, 0] == 0.7)
    assert res.normal[:, 1:].all()
    for i in (1, 2, 3):
        assert np.ptp(res.current_cmd[:, i]) > 0.3          # still controlling
        assert np.all(np.isfinite(res.demand[:, i]))
    assert res.status['fl']['mode'] == 'failsafe'
    assert res.status['fl']['reason'] == 'no_parameters_yet'
    assert [res.status[c]['mode'] for c in ('fr', 'rl', 'rr')] == ['normal'] * 3


@pytest.mark.slow
def test_corner_dropping_to_failsafe_mid_run_leaves_the_others():
    p = PASSENGER_CAR
    road = make_two_track_road('iso8608-C', p, speed_m_s=20.0, duration_s=1.0, rng=2)
    sups = [ModelSupervisor(timeout_s=0.2, safe_current_a=1.0) for _ in range(4)]
    ctl = FullCarController(make_full_car_law('modal-skyhook', p), sups)
    car = FullCar(p, [make_plant('kwok-current') for _ in range(4)], road)
    msg = IdentifiedSet(KW, current_min_a=0.0, current_max_a=2.0, valid=True)
    s = car.state
    log = []
    for k in range(1000):
        t = k * 1e-3
        if k % 100 == 0:
            for i in range(4):
                # the identifier of fr publishes an invalid fit at 0.5 s and goes silent
                if i == 1 and k >= 500:
                    if k == 500:
                        assert not ctl.offer_parameters('fr', msg.replace(valid=False), t).accepted
                    continue
                assert ctl.offer_parameters(i, msg, t).accepted
        cur = ctl.command(s, t)
        log.append((cur, ctl.modes))
        s = car.step(1e-3, cur)
    cur = np.array([c for c, _ in log])
    modes = [m for _, m in log]
    assert all(m == ['normal'] * 4 for m in modes[:500])
    assert all(m == ['normal', 'failsafe', 'normal', 'normal'] for m in modes[500:])
    assert np.all(cur[500:, 1] == 1.0)
    assert all(np.ptp(cur[500:, i]) > 0.3 for i in (0, 2, 3))
    assert sups[1].rejected['invalid_flag'] == 1


def test_identified_set_of_parameter_files(tmp_path):
    from mr_damper_model.io.params_file import save_params
    d = {'model': 'kwok-current', 'parameters': KW, 'model_options': {'i_ref_a': 2.0},
         'current_min_a': 0.0, 'current_max_a': 2.0}
    save_params(tmp_path / 'fit.json', d)
    for src in (KW, d, tmp_path / 'fit.json', str(tmp_path / 'fit.json')):
        msg = identified_set_of(src)
        assert ModelSupervisor().offer(msg, 0.0).accepted
        assert msg.parameters == pytest.approx(KW)
    narrow = identified_set_of({**d, 'current_min_a': 1.0, 'current_max_a': 1.0})
    assert ModelSupervisor().offer(narrow, 0.0).reason == 'narrow_current_range'
