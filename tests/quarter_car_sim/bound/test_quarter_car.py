"""Tests of quarter_car_sim.bound.quarter_car: the offline optimal semi-active bound."""
import numpy as np
import pytest

from bound_cases import WideLinearDamper
from mr_damper_model.identification import presets
from mr_damper_model.models.inverse import KwokCurrentInverse
from mr_damper_model.models.plant import KwokCurrentPlant
from semi_active_control import laws as ctl
from quarter_car_sim.bound.quarter_car import (bound_name, CurrentSchedule, KwokForceModel,
                                               semi_active_bound)
from mr_damper_common.contract import CornerState
from quarter_car_sim.plant.quarter_car import QuarterCar
from semi_active_control.car.quarter_car import QuarterCarParams
from semi_active_control.iso2631 import wk_filter
from quarter_car_sim.plant.road import iso8608
from quarter_car_sim.simulate.quarter_car import simulate

PARAMS = QuarterCarParams()


def _run_forces(road, dt, u):
    """Drive the car by the force sequence u; return a_s and the dynamic tyre load."""
    car = QuarterCar(PARAMS, None, road, t0=float(road.t[0]))
    n = len(u)
    a = np.empty(n)
    ft = np.empty(n)
    s = car.state
    for k in range(n):
        a[k] = (u[k] - PARAMS.k_s * s.travel - PARAMS.c_s * s.v_rel) / PARAMS.m_s
        ft[k] = s.tyre_force - PARAMS.static_tyre_load
        s = car.step_force(dt, u[k])
    return a, ft


@pytest.mark.slow
def test_wide_linear_damper_reproduces_the_unconstrained_optimum():
    # analytic limit: with no binding limit the bound is the least-squares optimum of the
    # quadratic cost over the force sequence, built here column by column from the car itself
    # (class A road: the wheel stays on the road, so the car is linear); the first period's
    # force is the car's initial one (0: no command reaches it), so it is no column
    dt, rho = 2e-3, 0.5
    road = iso8608('A', 20.0, 0.5, dt, rng=4)
    n = int(round(road.duration / dt)) + 1
    fs = 1.0 / dt
    a_free, t_free = _run_forces(road, dt, np.zeros(n))
    y_a0, y_t0 = wk_filter(a_free, fs), t_free
    a0, t0 = np.mean(y_a0 ** 2), np.mean(y_t0 ** 2)
    m_a = np.zeros((n, n))
    m_t = np.zeros((n, n))
    for j in range(1, n):
        e = np.zeros(n)
        e[j] = 1.0
        a, ft = _run_forces(road, dt, e)
        m_a[:, j] = wk_filter(a, fs) - y_a0
        m_t[:, j] = ft - y_t0
    lhs = np.vstack([m_a / np.sqrt(a0), m_t * np.sqrt(rho / t0)])
    rhs = -np.concatenate([y_a0 / np.sqrt(a0), y_t0 * np.sqrt(rho / t0)])
    u_opt = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    j_opt = float(np.sum((lhs @ u_opt - rhs) ** 2)) / n

    res = semi_active_bound(PARAMS, road, WideLinearDamper(), rho=rho, dt=dt, outer=3,
                            maxiter=3000, kernel_s=2.0, settle_s=0.0)
    assert res.cost_start == pytest.approx(1.0 + rho)      # start: no damper force at all
    assert res.cost == pytest.approx(j_opt, rel=2e-3)
    assert res.cost >= j_opt * (1.0 - 1e-9)                 # cannot beat the optimum
    # the outputs are those of the optimum (the forces themselves are not unique: the problem
    # is ill-conditioned, directions that barely change the outputs are free)
    a, ft = _run_forces(road, dt, res.force)
    y_opt = lhs @ u_opt - rhs
    y_res = np.concatenate([wk_filter(a, fs) / np.sqrt(a0), ft * np.sqrt(rho / t0)])
    assert np.linalg.norm(y_res - y_opt) < 0.1 * np.linalg.norm(y_opt)
    assert np.all(np.abs(res.current - 1.0) < 1e-3)         # far inside the current range


@pytest.fixture(scope='module')
def kwok_case():
    # the damper model is the plant (no coil lag): the replay reproduces the prediction
    _, truth = presets.thesis_kwok_current()
    inverse = KwokCurrentInverse(truth, tol_a=1e-6, sign_convention='body')
    plant = KwokCurrentPlant(truth, coil_tau_s=0.0)
    road = iso8608('C', 20.0, 3.0, 1e-3, rng=2)
    res = semi_active_bound(PARAMS, road, KwokForceModel(inverse), plant, settle_s=0.0)
    return truth, inverse, plant, road, res


@pytest.mark.slow
def test_bound_is_no_worse_than_every_passive_setting_and_live_law(kwok_case):
    _, inverse, plant, road, res = kwok_case
    wk_bound = res.metrics()['rms_body_accel_wk']
    laws = [ctl.Passive(i) for i in (0.0, 0.25, 0.5, 1.0, 1.5, 2.0)]
    laws += [ctl.make_controller(n, params=PARAMS, inverse=inverse)
             for n in ('skyhook', 'skyhook-onoff', 'groundhook', 'hybrid', 'add', 'sh-add',
                       'clipped-optimal')]
    laws += [ctl.Skyhook(c, 150.0) for c in (1000.0, 3000.0)]
    others = {c.name + repr(vars(c)): simulate(PARAMS, road, c, plant, inverse=inverse,
                                               settle_s=0.0).metrics()['rms_body_accel_wk']
              for c in laws}
    worse = {k: v for k, v in others.items() if v < wk_bound}
    assert not worse, f'bound {wk_bound:.4f} beaten by {worse}'
    assert wk_bound < 0.97 * others['passive@0.0A' + repr(vars(ctl.Passive(0.0)))]
    assert res.cost < res.cost_start


@pytest.mark.slow
def test_bound_respects_the_force_limits_at_every_step(kwok_case):
    _, inverse, _, _, res = kwok_case
    p = res.predicted
    # the first period's force is the car's initial one (no command reaches it), then every
    # force lies in the damper's range at the state reached
    assert res.force[0] == 0.0 == p['force_lo'][0] == p['force_hi'][0]
    lo, hi = KwokForceModel(inverse).body_force_range_array(p['travel'][1:], p['v_rel'][1:])
    f = res.force[1:]
    assert np.all(f >= lo - 1e-6) and np.all(f <= hi + 1e-6)
    assert np.all((res.current >= 0.0) & (res.current <= 2.0))
    # the limits bind (the problem is really constrained) and the force is dissipative-range
    at_limit = (np.abs(f - lo) < 1e-6) | (np.abs(f - hi) < 1e-6)
    assert np.mean(at_limit) > 0.2


def test_replayed_current_sequence_makes_the_planned_forces(kwok_case):
    _, _, _, _, res = kwok_case
    rep = res.replay
    assert rep.controller == bound_name() == 'bound'
    np.testing.assert_allclose(rep.current_cmd[:-1], res.current[1:])
    # the plant is the model and the plan starts where the replay does (the first period's
    # force the car's own), so the replay follows the plan to the inverse's tolerance (1e-6 A)
    assert np.max(np.abs(rep.damper_force - res.force)) < 1e-3
    assert rep.metrics()['rms_body_accel_wk'] == pytest.approx(
        res.predicted_metrics['rms_body_accel_wk'], rel=1e-5)


def test_current_schedule_commands_the_next_sample():
    sched = CurrentSchedule([0.1, 0.2, 0.3], t0=1.0, dt=0.01)
    assert sched.kind == 'current'

    def at(t):
        return CornerState(t, *([0.0] * 12))
    assert sched.demand(at(0.5)) == 0.1        # settling before the road
    assert sched.demand(at(1.0)) == 0.2
    assert sched.demand(at(1.01)) == 0.3
    assert sched.demand(at(1.02)) == 0.3       # held after the end
    with pytest.raises(ValueError, match='currents'):
        CurrentSchedule([0.1, float('nan')], 0.0, 0.01)


def test_bound_rejects_bad_input():
    road = iso8608('C', 20.0, 0.2, 1e-3, rng=1)
    with pytest.raises(ValueError, match='rho'):
        semi_active_bound(PARAMS, road, WideLinearDamper(), rho=-1.0)
    with pytest.raises(ValueError, match='dt'):
        semi_active_bound(PARAMS, road, WideLinearDamper(), dt=0.0)
    assert bound_name(0.5) == 'bound(rho=0.5)'
