"""Tests of semi_active_control.runtime.controller_core: law + inverse + supervisor."""
import dataclasses
import math

import numpy as np
import pytest

from mr_damper_model.models.inverse import KwokCurrentInverse
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.simulate import live_loop
from mr_damper_common.contract import CornerState
from quarter_car_sim.runtime.command_input import CommandInput
from semi_active_control.runtime.controller_core import ControllerCore, LAW_FIELDS
from semi_active_control.laws import ADD, Groundhook, Passive, Skyhook
from quarter_car_sim.plant.quarter_car import QuarterCar
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import make_road

SAFE = 0.5


def _truth():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    msg = dict(params, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
               valid=1.0)
    return params, msg


def _states(n=2000, seed=4):
    """Car states of a passive ride on an ISO 8608 C road (the laws' inputs)."""
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=seed,
                     duration_s=n * 1e-3 + 1.0)
    car = QuarterCar(QuarterCarParams(), make_plant('kwok-current'), road, t0=-0.1)
    out = []
    for _ in range(n):
        out.append(car.step(1e-3, 0.7))
    return out


def _vehicle(state, **extra):
    return CornerState(t=state.t, **{n: getattr(state, n) for n in LAW_FIELDS}, **extra)


def test_no_model_then_model_then_stale_then_refused():
    _, msg = _truth()
    core = ControllerCore(Skyhook(3000.0), ModelSupervisor(timeout_s=1.0, safe_current_a=SAFE))
    states = _states(400)
    for k, s in enumerate(states[:100]):
        assert core.command(s, 0.001 * k) == SAFE
    assert core.sup.reason == 'no_parameters_yet' and core.n_normal == 0
    core.offer_parameters(msg, 0.1)
    currents = [core.command(s, 0.1 + 0.001 * k) for k, s in enumerate(states[100:300])]
    assert core.n_normal == 200 and core.sup.mode == 'normal'
    assert len(set(np.round(currents, 4))) > 20          # a law, not a constant
    assert all(0.0 <= c <= 2.0 for c in currents)
    assert core.command(states[300], 1.2) == SAFE       # accepted at 0.1 s: stale after 1.1 s
    assert core.sup.reason == 'stale' and math.isnan(core.f_demand)
    core.offer_parameters(msg, 1.3)
    core.command(states[301], 1.3)
    assert core.sup.mode == 'normal'
    verdict = core.offer_parameters(dict(msg, valid=0.0), 1.31)
    assert not verdict.accepted
    assert core.command(states[302], 1.31) == SAFE and core.sup.reason == 'invalid_flag'
    st = core.status()
    assert st['commands'] == 303 and st['commands_normal'] == 201
    assert st['params_accepted'] == 2 and st['params_rejected']['invalid_flag'] == 1


def test_command_equals_law_through_the_identified_inverse():
    """Reference: the law's force through ``KwokCurrentInverse`` of the identified range."""
    truth, msg = _truth()
    msg = dict(msg, current_min_a=0.1, current_max_a=1.8)
    for law in (Skyhook(2500.0, 150.0), Groundhook(), ADD()):
        core = ControllerCore(law, ModelSupervisor(timeout_s=10.0, safe_current_a=SAFE))
        core.offer_parameters(msg, 0.0)
        inv = KwokCurrentInverse(truth, i_ref_a=msg['i_ref_a'], i_min=0.1, i_max=1.8,
                                 tol_a=1e-4, sign_convention='body')
        n_sat = 0
        for s in _states(600)[::3]:
            want, flag = inv.current(law.demand(s), s.travel, s.v_rel)
            sat = flag != 0                       # flag 0: reachable; +-1: saturated
            assert core.command(s, 0.0) == pytest.approx(want, abs=1e-12)
            assert core.f_demand == law.demand(s) and core.last_saturated == sat
            n_sat += sat
        assert core.saturated == n_sat


def test_vehicle_state_and_car_state_give_the_same_command():
    _, msg = _truth()
    a = ControllerCore(Skyhook(), ModelSupervisor(safe_current_a=SAFE))
    b = ControllerCore(Skyhook(), ModelSupervisor(safe_current_a=SAFE))
    a.offer_parameters(msg, 0.0)
    b.offer_parameters(msg, 0.0)
    for s in _states(300):
        assert a.command(s, 0.0) == b.command(_vehicle(s), 0.0)


@pytest.mark.parametrize('name', ['clipped-optimal', 'clipped-optimal-wk'])
def test_lqr_laws_read_the_tyre_deflection_and_refuse_a_state_without_it(name):
    from semi_active_control.laws import make_controller
    _, msg = _truth()
    laws = [make_controller(name, damper_only=True) for _ in range(2)]
    assert laws[0].state_fields == ('z_u', 'z_r')
    a = ControllerCore(laws[0], ModelSupervisor(safe_current_a=SAFE))
    b = ControllerCore(laws[1], ModelSupervisor(safe_current_a=SAFE))
    a.offer_parameters(msg, 0.0)
    b.offer_parameters(msg, 0.0)
    states = _states(300)
    currents = []
    for s in states:          # a vehicle state with z_u, z_r: the car state's command
        want = a.command(s, 0.0)
        assert b.command(_vehicle(s, z_u=s.z_u, z_r=s.z_r), 0.0) == want
        currents.append(want)
    assert len(set(currents)) > 10                   # the law works, not the safe current
    # without the tyre deflection (a vehicle that does not measure it): refused, safe current
    blind = _vehicle(states[-1])
    assert math.isnan(blind.z_r)
    assert b.command(dataclasses.replace(blind, t=blind.t + 1e-3), 0.0) == SAFE
    assert b.state_rejected['non_finite'] == 1
    # a law without them (skyhook) does not need them
    sky = ControllerCore(Skyhook(), ModelSupervisor(safe_current_a=SAFE))
    sky.offer_parameters(msg, 0.0)
    sky.command(blind, 0.0)
    assert sky.state_rejected['non_finite'] == 0


def test_closed_loop_uses_the_core_step_for_step():
    """The built-in loop's commands are the core's on the same states (one home)."""
    _, msg = _truth()
    params = QuarterCarParams()
    road = make_road('iso8608', rng=2, duration_s=2.0)
    car = QuarterCar(params, make_plant('kwok-current'), road, t0=-0.2)
    loop = live_loop.ClosedLoop(car, Skyhook(), ModelSupervisor(safe_current_a=SAFE))
    ref = ControllerCore(Skyhook(), ModelSupervisor(safe_current_a=SAFE))
    loop.sup.offer(msg, 0.0)
    ref.offer_parameters(msg, 0.0)
    for _ in range(500):
        want = ref.command(car.state, 0.0)
        loop.step(0.0)
        assert loop.i_cmd == want
    assert loop.saturated == ref.saturated and loop.steps == 500


def test_non_finite_and_out_of_order_states_get_the_safe_current():
    _, msg = _truth()
    core = ControllerCore(Skyhook(), ModelSupervisor(safe_current_a=SAFE))
    core.offer_parameters(msg, 0.0)
    good = _vehicle(_states(50)[-1])
    core.command(good, 0.0)
    n = 0
    for name in LAW_FIELDS + ('t',):
        for bad in (math.nan, math.inf):
            assert core.command(dataclasses.replace(good, **{name: bad}), 0.0) == SAFE
            n += 1
            assert core.state_rejected['non_finite'] == n
    older = dataclasses.replace(good, t=good.t - 0.01)
    assert core.command(older, 0.0) == SAFE
    assert core.state_rejected == {'non_finite': n, 'future_stamp': 0, 'out_of_order': 1}
    assert core.status()['reason'] == 'state_out_of_order'
    core.command(good, 0.0)                          # the same stamp again is in order
    assert core.state_rejected == {'non_finite': n, 'future_stamp': 0, 'out_of_order': 1}
    assert core.last_state_t == good.t and core.n_commands == n + 3


def _normal_core(**kwargs):
    _, msg = _truth()
    core = ControllerCore(Skyhook(), ModelSupervisor(timeout_s=1e3, safe_current_a=SAFE),
                          **kwargs)
    core.offer_parameters(msg, 1.7e9)
    return core


def _stamped(states, t0):
    """Vehicle states stamped ``t0 + 1 ms * k`` (a vehicle clock)."""
    return [_vehicle(dataclasses.replace(s, t=t0 + 1e-3 * k)) for k, s in enumerate(states)]


@pytest.mark.parametrize('t0', [0.0, 1.7e9])
def test_one_future_stamped_state_costs_one_safe_answer(t0):
    """Issue 21: a state stamped +1e6 s once; every later valid state is answered normally."""
    core = _normal_core(max_future_s=1.0, rebase_after=20)
    ref = _normal_core()
    states = _stamped(_states(300), t0)
    clock = 1.7e9 + 1e-3 * np.arange(300)           # the node clock (ROS time)
    modes = []
    for k, s in enumerate(states):
        want = ref.command(s, clock[k])
        if k == 150:
            assert core.command(dataclasses.replace(s, t=s.t + 1e6), clock[k]) == SAFE
            assert core.status()['mode'] == 'failsafe'
            assert core.status()['reason'] == 'state_future_stamp'
        else:
            assert core.command(s, clock[k]) == want
        modes.append(core.mode_reason())
    assert core.state_rejected == {'non_finite': 0, 'future_stamp': 1, 'out_of_order': 0}
    assert core.n_commands == 300 and core.n_normal == 299
    assert modes.count(('failsafe', 'state_future_stamp')) == 1
    assert modes[151:] == [('normal', 'ok')] * 149
    assert core.status()['stamp_rebases'] == 0 and core.last_state_t == states[-1].t


def test_backward_clock_jump_is_re_based_after_a_run():
    core = _normal_core(rebase_after=10)
    states = _states(200)
    before = _stamped(states[:100], 500.0)
    after = _stamped(states[100:], 20.0)           # the vehicle clock jumped back 480 s
    clock = 1.7e9 + 1e-3 * np.arange(200)
    out = [core.command(s, c) for s, c in zip(before + after, clock)]
    assert core.state_rejected['out_of_order'] == 9           # the run, less the re-base
    assert core.stamps.rebases_backward == 1 and core.status()['stamp_rebases'] == 1
    assert core.status()['last_stamp_rebase'] == {'direction': 'backward',
                                                  'from_s': before[-1].t, 'to_s': after[9].t}
    assert out[100:109] == [SAFE] * 9 and core.n_normal == 200 - 9
    assert core.mode_reason() == ('normal', 'ok') and core.last_state_t == after[-1].t


def test_forward_clock_jump_within_the_horizon_is_accepted():
    core = _normal_core(max_future_s=1.0)
    states = _states(200)
    seq = _stamped(states[:100], 500.0) + _stamped(states[100:], 500.9)   # +0.8 s at once
    clock = 1.7e9 + 1e-3 * np.arange(200)
    for s, c in zip(seq, clock):
        core.command(s, c)
    assert sum(core.state_rejected.values()) == 0 and core.n_normal == 200
    assert core.stamps.rebases == 0


def test_forward_clock_jump_beyond_the_horizon_is_re_based_after_a_run():
    core = _normal_core(max_future_s=1.0, rebase_after=10)
    states = _states(200)
    seq = _stamped(states[:100], 500.0) + _stamped(states[100:], 4100.0)  # +1 h
    clock = 1.7e9 + 1e-3 * np.arange(200)
    for s, c in zip(seq, clock):
        core.command(s, c)
    assert core.state_rejected == {'non_finite': 0, 'future_stamp': 9, 'out_of_order': 0}
    assert core.stamps.rebases_forward == 1 and core.n_normal == 191


def test_passive_law_ignores_the_model():
    core = ControllerCore(Passive(1.2), ModelSupervisor(safe_current_a=SAFE))
    s = _states(10)[-1]
    assert core.command(s, 0.0) == 1.2 and core.sup.mode == 'failsafe'


def test_reconfigure_changes_gains_supervisor_and_command_input_all_or_nothing():
    from semi_active_control.runtime.controller_core import reconfigure
    from semi_active_control.laws import make_controller
    _, msg = _truth()
    sup = ModelSupervisor(timeout_s=10.0, safe_current_a=SAFE)
    core = ControllerCore(Skyhook(3000.0), sup)
    sup.offer(msg, 0.0)
    s = _states(300)[-1]

    def make_law(options):
        return make_controller('skyhook', **options)
    f1 = (core.command(s, 0.1), core.f_demand)[1]
    assert reconfigure({'controller_options': '{"c_sky": 6000.0}'}, sup, core=core,
                       make_law=make_law) == ''
    core.command(s, 0.2)
    assert core.controller.c_sky == 6000.0 and core.f_demand != f1
    assert core.f_demand == Skyhook(6000.0).demand(s)
    # a bad option, a bad JSON, an active law: refused with the reason, nothing changed
    assert 'controller_options refused' in reconfigure(
        {'controller_options': '{"c_skyy": 1.0}', 'safe_current_a': 0.9}, sup, core=core,
        make_law=make_law)
    assert 'controller_options refused' in reconfigure({'controller_options': '[1]'}, sup,
                                                       core=core, make_law=make_law)
    from semi_active_control.laws import SkyhookIdeal
    assert 'cannot drive an MR damper' in reconfigure(
        {'controller_options': '{}'}, sup, core=core, make_law=lambda o: SkyhookIdeal(3000.0))
    assert core.controller.c_sky == 6000.0 and sup.safe_current_a == SAFE
    # supervisor settings, by node parameter name
    assert reconfigure({'param_timeout_s': 0.05, 'safe_current_a': 0.9}, sup) == ''
    assert (sup.timeout_s, sup.safe_current_a) == (0.05, 0.9)
    assert core.command(s, 0.3) == 0.9 and sup.reason == 'stale'
    assert 'safe_current_a' in reconfigure({'safe_current_a': 5.0}, sup)
    assert 'not changeable while running: i_max_a' == reconfigure({'i_max_a': 1.0}, sup)
    assert 'only with controller:=external' in reconfigure({'command_timeout_s': 1.0}, sup)
    assert 'no built-in controller' in reconfigure({'controller_options': '{}'}, sup)
    # the command input of an external controller takes the timeout and the safe current
    cmd = CommandInput(0.05, 0.9)
    assert reconfigure({'command_timeout_s': 2.0, 'safe_current_a': 0.2}, sup,
                       command_input=cmd) == ''
    assert (cmd.timeout_s, cmd.safe_current_a, sup.safe_current_a) == (2.0, 0.2, 0.2)
    assert cmd.current(0.0) == 0.2
    assert 'timeout_s' in reconfigure({'command_timeout_s': 0.0}, sup, command_input=cmd)
    assert cmd.timeout_s == 2.0


def test_set_controller_refuses_an_active_law():
    from semi_active_control.laws import SkyhookIdeal
    core = ControllerCore(Skyhook(3000.0), ModelSupervisor(safe_current_a=SAFE))
    with pytest.raises(ValueError, match='cannot drive an MR damper'):
        core.set_controller(SkyhookIdeal(3000.0))
    core.set_controller(Passive(1.2))
    assert core.passive and core.command(_vehicle(_states(5)[-1]), 0.0) == 1.2


def test_a_stateful_law_follows_the_car_through_a_fail_safe_episode():
    """The Wk filter of clipped-optimal-wk sees every state, with or without a model."""
    from semi_active_control.laws import make_controller
    _, msg = _truth()
    gap = ControllerCore(make_controller('clipped-optimal-wk', damper_only=True),
                         ModelSupervisor(timeout_s=0.1, safe_current_a=SAFE))
    ref = ControllerCore(make_controller('clipped-optimal-wk', damper_only=True),
                         ModelSupervisor(timeout_s=1e9, safe_current_a=SAFE))
    ref.offer_parameters(msg, 0.0)
    gap.offer_parameters(msg, 0.0)
    states = _states(600)
    for k, s in enumerate(states):
        t_clock = 0.0 if k < 200 or k >= 400 else 1.0      # stale from 200 to 399
        if k == 400:
            gap.offer_parameters(msg, 0.0)                 # a fresh set: normal again
        want = ref.command(s, 0.0)
        got = gap.command(s, t_clock)
        if 200 <= k < 400:
            assert got == SAFE
        else:
            assert got == want, k
