"""
The simulated full car as a vehicle controller's plant (``controller:=external``), without ROS.

The car's exact state goes out as the vehicle's ``FullCarState`` message, the controller's
command comes back as a ``FullCarCommand``: the message conversions both ways, the controller
core (:class:`VehicleControllerCore`) and the car's side (:class:`VehicleCommandInput`).
"""
import math

import numpy as np
import pytest

from mr_damper_common import messages
from mr_damper_common.contract import IdentifiedSet
from mr_damper_model.identification import presets
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.plant.two_track_road import make_two_track_road
from quarter_car_sim.runtime.command_input import VehicleCommandInput
from quarter_car_sim.runtime.full_car import FullCarRuntime
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.estimation.vehicle_estimator import VehicleEstimate
from semi_active_control.runtime.vehicle_controller import (full_car_state, MODE_FAIL_SAFE,
                                                            MODE_NORMAL, VehicleControllerCore)
from semi_active_control.supervision.corner_models import CornerModels

KW = presets.thesis_kwok_current()[1]
IDENTIFIED = IdentifiedSet(KW, current_min_a=0.0, current_max_a=2.0, valid=True)
SAFE_A = 0.7
DT = 1e-3


def over_the_wire(state, sequence, t=None):
    """Return the car's exact state as the controller reads it (FullCarState message, back)."""
    msg = messages.full_car_state_msg(VehicleEstimate.exact(state, sequence, t))
    f = messages.full_car_state_fields(msg)
    assert f['sequence'] == sequence and f['valid'] and f['reason'] == ''
    return full_car_state(PASSENGER_CAR.geometry, f['t'], f['body'], f['body_rates'],
                          f['body_acc'], f['travel'], f['travel_velocity'],
                          f['tyre_deflection'], f['wheel_velocity'], f['damper_force'])


def live_core(law, **kw):
    models = CornerModels([''] * 4, timeout_s=1e9, safe_current_a=SAFE_A, i_min_a=0.0,
                          i_max_a=2.0, min_current_span_a=1.0)
    core = VehicleControllerCore(PASSENGER_CAR, law, models, cycle_s=DT, **kw)
    core.configure(0.0)
    core.activate(0.0)
    return core


def test_the_exact_estimate_is_the_true_state():
    rt = FullCarRuntime(PASSENGER_CAR, make_two_track_road(
        'iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=1.0, rng=2),
        [make_plant('kwok-current') for _ in range(4)], 'passive@0.5A', settle_s=0.0)
    for k in range(300):
        rt.step(k * DT)
    true = rt.state
    s = over_the_wire(true, 7)
    np.testing.assert_array_equal(s.v[:3], true.v[:3])
    np.testing.assert_array_equal(s.travel, true.travel)
    np.testing.assert_array_equal(s.v_rel, true.v_rel)
    np.testing.assert_allclose(s.q[3:] - s.z_r, true.q[3:] - true.z_r, rtol=0, atol=1e-15)
    np.testing.assert_allclose(s.body_v, true.body_v, rtol=1e-12, atol=1e-15)
    assert s.t == pytest.approx(true.t, abs=1e-9)                  # a stamp: nanoseconds
    assert np.all(s.damper_force == true.damper_force)


@pytest.mark.parametrize('law', ['modal-skyhook', 'per-corner-skyhook',
                                 'full-car-clipped-optimal-wk'])
@pytest.mark.slow
def test_the_controller_on_the_cars_state_asks_the_built_in_laws_currents(law):
    # the same law on the same car and road: built into the car, or in the vehicle controller
    # on the car's state over the message; rr has no model in both (safe current)
    road = make_two_track_road('iso8608-C', PASSENGER_CAR, speed_m_s=20.0, duration_s=2.0,
                               rng=3)
    rt = FullCarRuntime(PASSENGER_CAR, road, [make_plant('kwok-current') for _ in range(4)],
                        law, dt=DT, timeout_s=1e9, safe_current_a=SAFE_A, settle_s=0.1)
    core = live_core(law)
    for corner in ('fl', 'fr', 'rl'):
        assert rt.offer_parameters(corner, IDENTIFIED, 0.0).accepted
        assert core.offer_parameters(corner, IDENTIFIED, 0.0).accepted
    n = 500
    got, want = [], []
    for k in range(n):
        s = over_the_wire(rt.state, k + 1, t=10.0 + k * DT)   # (stamps: the node clock's)
        cmd = core.command(s, k + 1, True, '', s.t)
        _, currents, _ = rt.step(k * DT)
        got.append(cmd.currents_a)
        want.append(currents)
        assert cmd.modes == [MODE_NORMAL] * 3 + [MODE_FAIL_SAFE], cmd
    got, want = np.asarray(got), np.asarray(want)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-4)     # inverse tolerance 1e-4 A
    assert np.all(got[:, 3] == SAFE_A)
    assert np.ptp(got[:, :3], axis=0).min() > 0.1          # the law, not the safe current
    st = core.status()
    assert st['states_answered'] == n and st['states']['lost'] == 0
    assert [st['corners'][c]['normal_commands'] for c in ('fl', 'fr', 'rl', 'rr')] == [
        n, n, n, 0]


def command(inp, seq, state_seq, currents, modes=(MODE_NORMAL,) * 4, reasons=('ok',) * 4,
            t=0.0):
    return inp.offer(seq, state_seq, currents, modes, reasons, t)


def test_the_cars_command_input_applies_holds_and_times_out_each_corner():
    inp = VehicleCommandInput(0.05, SAFE_A)
    assert inp.currents(0.0, 0.0) == [SAFE_A] * 4
    assert inp.mode_reason(0) == ('failsafe', 'no_command_yet')
    assert command(inp, 1, 1, [1.0, 1.2, 0.3, 0.5],
                   modes=(MODE_NORMAL,) * 3 + (MODE_FAIL_SAFE,),
                   reasons=('ok',) * 3 + ('stale',), t=0.01) == ['accepted'] * 4
    assert inp.currents(0.011, 1.0) == [1.0, 1.2, 0.3, 0.5]
    assert [inp.mode_reason(j) for j in range(4)] == [('normal', 'ok')] * 3 + [
        ('failsafe', 'stale')]
    assert inp.answered_sequence == 1 and inp.first_normal_t_sim[:3] == [1.0] * 3
    assert math.isnan(inp.first_normal_t_sim[3])
    # an older command (its number) is not used; a gap is counted lost
    assert command(inp, 1, 1, [0.0] * 4, t=0.02) is None
    assert command(inp, 4, 3, [0.9, math.nan, 5.0, 0.5], t=0.02) == [
        'accepted', 'refused_non_finite', 'clamped_high', 'accepted']
    assert inp.currents(0.021, 1.001) == [0.9, 1.2, 2.0, 0.5]      # fr keeps its last
    assert inp.sequence.lost == 2 and inp.answered_sequence == 3
    # nothing for longer than the timeout: every corner safe, counted, by its reason
    assert inp.currents(0.08, 1.06) == [SAFE_A] * 4
    assert [inp.mode_reason(j) for j in range(4)] == [('failsafe', 'command_timeout')] * 4
    st = inp.status()
    assert st['commands'] == 2 and st['command_sequence']['out_of_order'] + st[
        'command_sequence']['repeated'] == 1
    assert st['corners']['fl']['command_timeouts'] == 1
    # (the second command had rr on the law too)
    assert st['corners']['fl']['normal_steps'] == 2 and st['corners']['rr']['normal_steps'] == 1
    # car time off the law (each interval by the mode held over it): every corner until the
    # first command at 1.0 s, rr until the second at 1.001 s
    assert st['corners']['rr']['failsafe_s'] == pytest.approx(1.001)
    assert st['corners']['fl']['failsafe_s'] == pytest.approx(1.0)
