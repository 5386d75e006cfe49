"""Tests of quarter_car_sim.simulate.quarter_car: closed loop, comparisons, identification."""
import math

import numpy as np
import pytest

from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from semi_active_control import laws as ctl
from quarter_car_sim.plant.quarter_car import LinearDamperPlant, QuarterCar
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.simulate.live_loop import ClosedLoop
from quarter_car_sim.plant.road import iso8608
from quarter_car_sim.simulate.quarter_car import compare, make_inverse, simulate

P = QuarterCarParams()
ROAD = iso8608('C', 20.0, 8.0, 1e-3, rng=4)
_, TRUTH = presets.thesis_kwok_current()


@pytest.mark.slow
def test_simulate_passive_linear_records_everything():
    r = simulate(P, ROAD, ctl.Passive(0.0), LinearDamperPlant(1200.0))
    assert r.t.size == ROAD.n and r.t[0] == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(r.current_cmd, 0.0) and not r.saturated.any()
    np.testing.assert_allclose(r.travel, r.z_s - r.z_u)
    np.testing.assert_allclose(r.damper_force, -1200.0 * r.v_rel, atol=1e-9)
    np.testing.assert_allclose(r.z_r, np.interp(r.t, ROAD.t, ROAD.z), atol=1e-12)
    assert r.states.shape == (ROAD.n, 4)
    m = r.metrics()
    assert 0.2 < m['rms_body_accel_wk'] < 3.0


def test_semi_active_commands_within_limits_and_logged():
    plant = make_plant('kwok-current')
    r = simulate(P, ROAD, ctl.Skyhook(), plant, damper_params=TRUTH)
    assert np.all((r.current_cmd >= 0.0) & (r.current_cmd <= 2.0))
    assert 0.0 < r.saturated.mean() < 1.0
    assert np.all(r.demand * r.v_rel <= 0.0)
    # the plant's coil follows the command (lag 1/190 s)
    assert np.corrcoef(r.coil_current[1:], r.current_cmd[:-1])[0, 1] > 0.8


def test_closed_loop_equals_simulate():
    plant = make_plant('kwok-current')
    inv = make_inverse(TRUTH)
    r = simulate(P, ROAD, ctl.Hybrid(), plant, inverse=inv, settle_s=0.0)
    car = QuarterCar(P, plant, ROAD)
    loop = ClosedLoop(car, ctl.Hybrid(), dt=1e-3, inverse=inv)
    samples = []                        # (state at the start of the period, command)
    for _ in range(500):
        state = car.state
        loop.step()
        samples.append((state, loop.i_cmd))
    np.testing.assert_allclose([i for _, i in samples], r.current_cmd[:500],
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose([s.a_s for s, _ in samples], r.a_s[:500], atol=1e-9)


@pytest.mark.slow
def test_compare_same_road_and_active_references():
    plant = make_plant('kwok-current')
    ctls = [ctl.Passive(0.0), ctl.Passive(2.0), ctl.Skyhook(), ctl.SkyhookIdeal(),
            ctl.make_controller('lqr-active')]
    res = compare(P, ROAD, ctls, plant, damper_params=TRUTH)
    assert list(res) == ['passive@0.0A', 'passive@2.0A', 'skyhook', 'skyhook-ideal',
                         'lqr-active']
    for r in res.values():
        np.testing.assert_array_equal(r.z_r, res['skyhook'].z_r)
    m = {k: r.metrics() for k, r in res.items()}
    # soft is comfortable, hard holds the road
    assert m['passive@0.0A']['rms_body_accel_wk'] < m['passive@2.0A']['rms_body_accel_wk']
    assert m['passive@2.0A']['rms_tyre_load_ratio'] < m['passive@0.0A']['rms_tyre_load_ratio']
    # skyhook through the inverse beats the best passive setting for comfort
    assert m['skyhook']['rms_body_accel_wk'] < m['passive@0.0A']['rms_body_accel_wk']
    assert math.isnan(m['lqr-active']['mean_current_a'])
    assert np.all(res['skyhook-ideal'].demand * res['skyhook-ideal'].v_rel <= 0.0)


@pytest.mark.slow
def test_seed_repeatable():
    plant = make_plant('kwok-current')
    a = simulate(P, ROAD, ctl.Skyhook(), plant, damper_params=TRUTH)
    b = simulate(P, ROAD, ctl.Skyhook(), plant, damper_params=TRUTH)
    np.testing.assert_array_equal(a.a_s, b.a_s)


def test_semi_active_needs_inverse_and_plant():
    with pytest.raises(ValueError, match='inverse'):
        simulate(P, ROAD, ctl.Skyhook(), make_plant('kwok-current'))
    with pytest.raises(ValueError, match='plant'):
        simulate(P, ROAD, ctl.Passive(0.0), None)
