"""VehicleControllerCore: the law on one state per cycle, per-corner fail-safe, the watchdog."""
import json
import math

import numpy as np
import pytest

from conftest import REPO
from semi_active_control.laws.registry import make_full_car_law
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.runtime.vehicle_controller import (full_car_state, MODE_FAIL_SAFE,
                                                            MODE_INACTIVE, MODE_NORMAL,
                                                            VehicleControllerCore)
from semi_active_control.runtime.full_car_controller_core import FullCarController
from semi_active_control.supervision.corner_models import CornerModels, load_model_file

MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
FILES = [str(MODELS / f'{c}.json') for c in ('fl', 'fr', 'rl', 'rr')]
P = 0.002
SUP = dict(safe_current_a=0.5, i_min_a=0.0, i_max_a=2.0, min_current_span_a=1.0)


def make_core(files=FILES, **kw):
    core = VehicleControllerCore(PASSENGER_CAR, 'modal-skyhook', CornerModels(files, **SUP),
                                 cycle_s=P, **kw)
    core.configure(0.0)
    return core


def states(n, seed=1, t0=10.0):
    """Plausible estimates: body rates, travels and their rates (random, smooth enough)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        yield full_car_state(PASSENGER_CAR.geometry, t0 + k * P, rng.normal(size=3) * 0.01,
                             rng.normal(size=3) * 0.1, rng.normal(size=3), rng.normal(size=4)
                             * 0.01, rng.normal(size=4) * 0.1, rng.normal(size=4) * 0.002,
                             rng.normal(size=4) * 0.2, rng.normal(size=4) * 300)


def test_the_commands_are_the_full_car_controllers_on_the_same_states():
    core = make_core()
    core.activate(10.0)
    ref = FullCarController(make_full_car_law('modal-skyhook', PASSENGER_CAR, dt=P),
                            timeout_s=1e9, safe_current_a=0.5)
    for i, f in enumerate(FILES):
        ref.offer_parameters(i, load_model_file(f), 0.0)
    for k, s in enumerate(states(50)):
        cmd = core.command(s, k + 1, True, '', s.t + 0.0005)
        np.testing.assert_allclose(cmd.currents_a, ref.command(s, s.t + 0.0005), atol=1e-12)
        assert cmd.modes == [MODE_NORMAL] * 4 and cmd.reasons == ['ok'] * 4
        assert cmd.state_sequence == k + 1 and cmd.sequence == k + 1
    assert core.monitor.misses == 0 and core.status()['corners_normal'] == 4
    assert core.status()['corners']['fr']['source'] == 'file'


def test_one_corner_without_a_valid_model_the_other_three_on_the_law(tmp_path):
    bad = tmp_path / 'rr_failed.json'
    bad.write_text(json.dumps(dict(json.loads(open(FILES[3]).read()), valid=False)))
    core = make_core(FILES[:3] + [str(bad)])
    core.activate(10.0)
    currents = []
    for k, s in enumerate(states(40)):
        cmd = core.command(s, k + 1, True, '', s.t + 0.0005)
        assert cmd.modes == [MODE_NORMAL] * 3 + [MODE_FAIL_SAFE]
        assert cmd.reasons[3] == 'invalid_flag' and cmd.currents_a[3] == 0.5
        currents.append(cmd.currents_a[:3])
    assert np.ptp(np.array(currents), axis=0).min() > 0.05      # the law moves the others
    assert core.status()['corners']['rr']['params_rejected']['invalid_flag'] == 1


def test_invalid_estimate_all_corners_safe_with_its_reason():
    core = make_core()
    core.activate(10.0)
    s = next(states(1))
    cmd = core.command(s, 1, False, 'too_few_sensors', s.t + 0.0005)
    assert cmd.reasons == ['estimate_too_few_sensors'] * 4
    assert list(cmd.currents_a) == [0.5] * 4 and cmd.modes == [MODE_FAIL_SAFE] * 4


def test_consecutive_late_answers_fail_safe_then_recover():
    core = make_core(max_consecutive_misses=3, recover_cycles=5)
    core.activate(10.0)
    reasons = []
    for k, s in enumerate(states(20)):
        late = 4 <= k < 7                     # three cycles answered 3 ms after their stamp
        cmd = core.command(s, k + 1, True, '', s.t + (0.003 if late else 0.0005))
        reasons.append(cmd.reasons[0])
    # a cycle's lateness is known once it is answered: the cycle after the third late one is
    # safe; five answered on time in a row bring the law back
    assert reasons[:7] == ['ok'] * 7
    assert reasons[7:12] == ['deadline_misses'] * 5 and reasons[12:] == ['ok'] * 8
    st = core.status(20.0)['deadline']
    assert st['deadline_misses'] == 3 and st['entries']['deadline_misses'] == 1
    assert st['lateness']['max_s'] == pytest.approx(0.001)


def test_sensor_timeout_answers_safe_until_the_states_come_back():
    core = make_core(input_timeout_s=0.02)
    assert core.check(10.0) is None                       # not active: nothing
    core.activate(10.0)
    it = states(10)
    s = next(it)
    assert core.command(s, 1, True, '', 10.0005).reasons == ['ok'] * 4
    assert core.check(10.015) is None
    cmd = core.check(10.03)
    assert cmd.reasons == ['sensor_timeout'] * 4 and cmd.state_sequence == 0
    assert core.check(10.05).reasons == ['sensor_timeout'] * 4
    s = next(it)
    assert core.command(s, 2, True, '', 10.051).reasons == ['ok'] * 4
    assert core.check(10.052) is None
    assert core.monitor.entries['sensor_timeout'] == 1


def test_lifecycle_inactive_safe_and_old_states_not_answered():
    core = make_core()
    it = states(5)
    s = next(it)
    assert core.command(s, 1, True, '', s.t) is None       # configured, not active
    core.activate(10.0)
    s = next(it)
    assert core.command(s, 5, True, '', s.t + 0.0005).modes == [MODE_NORMAL] * 4
    assert core.command(s, 4, True, '', s.t + 0.0006) is None   # older: not answered
    assert core.states.status()['out_of_order'] == 1
    cmd = core.deactivate(11.0)
    assert cmd.modes == [MODE_INACTIVE] * 4 and cmd.reasons == ['inactive'] * 4
    assert list(cmd.currents_a) == [0.5] * 4 and math.isnan(cmd.state_t)
    assert core.command(next(it), 6, True, '', 11.0) is None
    assert core.status()['states_while_inactive'] == 2


@pytest.mark.parametrize('law', ['full-car-clipped-optimal', 'modal-skyhook'])
def test_a_non_finite_corner_never_reaches_an_inverse_and_the_law_comes_back(law):
    # a full-car law couples the corners: one corner's NaN wheel velocity can make every
    # corner's demand NaN; the inverse raises on that, so each such corner gets the safe
    # current, counted, and the next finite state is answered by the law again
    core = VehicleControllerCore(PASSENGER_CAR, law, CornerModels(FILES, **SUP), cycle_s=P)
    core.configure(0.0)
    core.activate(10.0)
    rng = np.random.default_rng(3)

    def state(k, nan_corner=None):
        wheel_v = rng.normal(size=4) * 0.2
        if nan_corner is not None:
            wheel_v[nan_corner] = math.nan       # e.g. a wheel accelerometer's estimate
        return full_car_state(PASSENGER_CAR.geometry, 10.0 + k * P, rng.normal(size=3) * 0.01,
                              rng.normal(size=3) * 0.1, rng.normal(size=3),
                              rng.normal(size=4) * 0.01, rng.normal(size=4) * 0.1,
                              rng.normal(size=4) * 0.002, wheel_v, rng.normal(size=4) * 300)

    s = state(0)
    assert core.command(s, 1, True, '', s.t + 0.0005).modes == [MODE_NORMAL] * 4
    s = state(1, nan_corner=2)
    cmd = core.command(s, 2, True, '', s.t + 0.0005)
    assert cmd.reasons[2] == 'state_non_finite' and cmd.currents_a[2] == 0.5
    for k in (0, 1, 3):
        assert cmd.reasons[k] in ('ok', 'non_finite_demand'), cmd.reasons
        assert (cmd.modes[k] == MODE_FAIL_SAFE) == (cmd.reasons[k] == 'non_finite_demand')
        assert math.isfinite(cmd.currents_a[k])
    refused = sum(r == 'non_finite_demand' for r in cmd.reasons)
    corners = core.status()['corners']
    assert sum(corners[c]['non_finite_demands'] for c in ('fl', 'fr', 'rl', 'rr')) == refused
    if law == 'full-car-clipped-optimal':
        assert refused == 3          # the optimal law's four forces from one state vector
    s = state(2)
    cmd = core.command(s, 3, True, '', s.t + 0.0005)
    assert cmd.modes == [MODE_NORMAL] * 4 and cmd.reasons == ['ok'] * 4


def test_a_state_arriving_after_its_deadline_gets_no_law_command_after_a_safe_one():
    """
    The three-node layout under starvation: a state held up after the sensor timeout.

    The sensor timeout put every corner on the safe current, then a state held up on its way
    arrives; no law command may follow the safe one.
    """
    core = make_core(input_timeout_s=0.02, max_consecutive_misses=3)
    core.activate(10.0)
    it = states(10)
    s1, s2, s3 = next(it), next(it), next(it)
    cmd = core.answer(s1, 1, True, '', s1.t + 0.0005)
    assert cmd.reasons == ['ok'] * 4
    core.sent(s1.t + 0.0008)                              # its deadline judged when sent
    assert core.monitor.cycles == 1 and core.monitor.misses == 0
    assert core.check(s1.t + 0.03).reasons == ['sensor_timeout'] * 4
    # s2 was stamped before the timeout and arrives 30 ms later: skipped, a miss, no command
    assert core.answer(s2, 2, True, '', s2.t + 0.03) is None
    core.sent(s2.t + 0.031)                               # nothing left to judge
    st = core.status(s2.t + 0.03)
    assert st['states_skipped_late'] == 1 and st['states_answered'] == 1
    assert st['deadline']['deadline_misses'] == 1 and core.monitor.cycles == 2
    # a fresh state is answered by the law again
    cmd = core.answer(s3, 3, True, '', s3.t + 0.0005)
    assert cmd.reasons == ['ok'] * 4 and cmd.state_sequence == 3
    # an answer whose sending ran past the deadline is a miss, judged at sent()
    s4 = next(it)
    assert core.answer(s4, 4, True, '', s4.t + 0.0005).reasons == ['ok'] * 4
    core.sent(s4.t + 0.0025)
    assert core.monitor.misses == 2


def test_late_states_in_a_row_trip_the_watchdog_and_get_the_safe_command():
    core = make_core(max_consecutive_misses=3)
    core.activate(10.0)
    got = [core.answer(s, k + 1, True, '', s.t + 0.004) for k, s in enumerate(states(5))]
    assert got[:2] == [None, None]                        # misses: nothing sent
    assert all(c.reasons == ['deadline_misses'] * 4 and list(c.currents_a) == [0.5] * 4
               for c in got[2:])
    assert core.status(11.0)['states_answered'] == 0
