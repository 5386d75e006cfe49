"""VehicleLoop: the chain's estimator and controller on each sensor cycle, one call, its frame."""
import json
import math

import numpy as np
import pytest

from conftest import REPO
from semi_active_control.car.full_car import PASSENGER_CAR
from semi_active_control.estimation.vehicle_estimator import (EstimatorSettings,
                                                              VehicleEstimatorCore)
from semi_active_control.runtime import full_car_state, VehicleControllerCore, VehicleLoop
from semi_active_control.runtime.vehicle_loop import MISS_CAUSES
from semi_active_control.supervision.corner_models import CornerModels

MODELS = REPO / 'src' / 'semi_active_control' / 'config' / 'models'
FILES = [str(MODELS / f'{c}.json') for c in ('fl', 'fr', 'rl', 'rr')]
P = 0.002
SAFE_A = 0.5
SUP = dict(safe_current_a=SAFE_A, i_min_a=0.0, i_max_a=2.0, min_current_span_a=1.0)


@pytest.fixture(scope='module')
def designed():
    """One filter design (control.dlqe: seconds), reset by each loop's configure."""
    return VehicleEstimatorCore(PASSENGER_CAR, EstimatorSettings(cycle_s=P))


def controller(files=FILES):
    return VehicleControllerCore(PASSENGER_CAR, 'modal-skyhook', CornerModels(files, **SUP),
                                 cycle_s=P, max_consecutive_misses=100000)


class Bus:
    """What the loop sends: (currents, failsafe flags, cycle) per frame."""

    def __init__(self):
        self.frames = []

    def __call__(self, currents_a, failsafe, cycle):
        self.frames.append((np.array(currents_a, dtype=float), list(failsafe), int(cycle)))


def cycles(n, seed=2, t0=100.0):
    """Sensor cycles of a car on a rough road: (sequence, t, body accelerations, travels)."""
    rng = np.random.default_rng(seed)
    t = t0 + P * np.arange(1, n + 1)
    for k in range(n):
        w = 2 * math.pi * np.array([1.2, 1.5, 9.0, 11.0]) * t[k]
        yield (k + 1, float(t[k]), 1.5 * np.sin(w) + rng.normal(0, 0.05, 4),
               0.01 * np.sin(w + 0.3) + rng.normal(0, 1e-4, 4))


def make_loop(designed, files=FILES):
    bus = Bus()
    loop = VehicleLoop(designed, controller(files), bus)
    verdicts = loop.configure(0.0)
    return loop, bus, verdicts


def test_the_frames_are_the_chains_estimator_then_controller_on_each_cycle(designed):
    # the chain's two cores, each run as its node runs it, on the same cycles
    ref_est = VehicleEstimatorCore(PASSENGER_CAR, EstimatorSettings(cycle_s=P))
    ref_est.reset()
    ref_ctl = controller()
    ref_ctl.configure(0.0)
    loop, bus, _ = make_loop(designed)
    ref_ctl.activate(100.0)
    loop.activate(100.0)
    for seq, t, acc, travel in cycles(300):
        est, cmd = loop.cycle(seq, t, acc, travel, t + 0.0005)
        e = ref_est.step(seq, t, acc, travel)
        s = full_car_state(PASSENGER_CAR.geometry, e.t, e.body, e.body_rates, e.body_acc,
                           e.travel, e.travel_velocity, e.tyre_deflection, e.wheel_velocity,
                           e.damper_force)
        ref = ref_ctl.command(s, e.sequence, e.valid, e.reason, t + 0.0005)
        np.testing.assert_array_equal(est.body, e.body)
        np.testing.assert_array_equal(cmd.currents_a, ref.currents_a)
        assert cmd.modes == ref.modes and cmd.state_sequence == seq
        currents, failsafe, cycle = bus.frames[-1]
        np.testing.assert_array_equal(currents, ref.currents_a)
        assert failsafe == [m != 0 for m in ref.modes] and cycle == seq
    assert len(bus.frames) == 300
    # the law moved the currents: not a constant answer
    assert np.ptp(np.array([f[0] for f in bus.frames[50:]]), axis=0).min() > 0.05
    assert loop.status()['controller']['corners_normal'] == 4


def test_inactive_estimates_sends_nothing_then_deactivation_is_one_safe_frame(designed):
    loop, bus, _ = make_loop(designed)
    gen = cycles(200)
    for _ in range(50):                       # configured, not active: the filter runs
        seq, t, acc, travel = next(gen)
        est, cmd = loop.cycle(seq, t, acc, travel, t + 0.0005)
        assert est is not None and est.sequence == seq and cmd is None
    assert bus.frames == [] and loop.status()['loop']['cycles_inactive'] == 50
    loop.activate(t)
    for _ in range(50):
        seq, t, acc, travel = next(gen)
        loop.cycle(seq, t, acc, travel, t + 0.0005)
    assert [f[2] for f in bus.frames] == list(range(51, 101))
    cmd = loop.deactivate(t + 0.001)
    assert cmd.reasons == ['inactive'] * 4
    currents, failsafe, cycle = bus.frames[-1]
    assert list(currents) == [SAFE_A] * 4 and failsafe == [True] * 4 and cycle == 0
    n = len(bus.frames)
    for _ in range(20):                       # nothing after the deactivation's frame
        seq, t, acc, travel = next(gen)
        assert loop.cycle(seq, t, acc, travel, t + 0.0005)[1] is None
    assert len(bus.frames) == n and loop.status()['loop']['cycles_inactive'] == 70


def test_an_old_cycle_is_not_used_and_a_silent_bus_gets_the_safe_frame(designed):
    loop, bus, _ = make_loop(designed)
    loop.activate(100.0)
    for seq, t, acc, travel in cycles(30):
        loop.cycle(seq, t, acc, travel, t + 0.0005)
    n = len(bus.frames)
    assert loop.cycle(seq, t, acc, travel, t + 0.0006) == (None, None)   # repeated
    assert loop.cycle(seq - 5, t, acc, travel, t + 0.0007) == (None, None)
    assert len(bus.frames) == n and loop.status()['loop']['cycles_unused'] == 2
    # no cycle for longer than the sensor timeout (20 ms): the check sends the safe frame
    assert loop.check(t + 0.01) is None and len(bus.frames) == n
    cmd = loop.check(t + 0.05)
    assert cmd.reasons == ['sensor_timeout'] * 4
    currents, failsafe, cycle = bus.frames[-1]
    assert list(currents) == [SAFE_A] * 4 and failsafe == [True] * 4 and cycle == 0


def test_one_corner_with_an_invalid_record_the_other_three_on_the_law(designed, tmp_path):
    bad = tmp_path / 'rr_failed.json'
    bad.write_text(json.dumps(dict(json.loads(open(FILES[3]).read()), valid=False)))
    loop, bus, verdicts = make_loop(designed, FILES[:3] + [str(bad)])
    assert [v.accepted for v in verdicts.values()] == [True, True, True, False]
    loop.activate(100.0)
    for seq, t, acc, travel in cycles(200):
        loop.cycle(seq, t, acc, travel, t + 0.0005)
    frames = bus.frames[50:]
    assert all(f[1] == [False, False, False, True] and f[0][3] == SAFE_A for f in frames)
    assert np.ptp(np.array([f[0][:3] for f in frames]), axis=0).min() > 0.01  # the law moves


def test_cycles_past_their_deadline_are_skipped_as_misses_and_trip_the_watchdog(designed):
    bus = Bus()
    ctl = VehicleControllerCore(PASSENGER_CAR, 'modal-skyhook', CornerModels(FILES, **SUP),
                                cycle_s=P, max_consecutive_misses=5, recover_cycles=20)
    # the loop's own execution takes no time on this clock: each cycle is answered when the
    # test says it is reached (a cold first cycle on a slow machine is no miss here)
    loop = VehicleLoop(designed, ctl, bus, clock=lambda: 0.0)
    loop.configure(0.0)
    loop.activate(100.0)
    gen = cycles(200)
    for _ in range(30):                       # on time: answered
        seq, t, acc, travel = next(gen)
        loop.cycle(seq, t, acc, travel, t + 0.0005)
    assert len(bus.frames) == 30
    # the loop falls behind the bus: each cycle comes to it 5 ms after its bus time (its
    # deadline, one 2 ms cycle, gone): estimated, not answered, a miss each
    for k in range(4):
        seq, t, acc, travel = next(gen)
        est, cmd = loop.cycle(seq, t, acc, travel, t + 0.005)
        assert est.sequence == seq and cmd is None
    assert len(bus.frames) == 30
    seq, t, acc, travel = next(gen)           # the fifth miss in a row trips the watchdog
    est, cmd = loop.cycle(seq, t, acc, travel, t + 0.005)
    assert cmd.reasons == ['deadline_misses'] * 4
    currents, failsafe, cycle = bus.frames[-1]
    assert list(currents) == [SAFE_A] * 4 and failsafe == [True] * 4 and cycle == 0
    # still behind: each skipped cycle now sends the safe frame (the drivers keep getting
    # commands), no law
    for _ in range(3):
        seq, t, acc, travel = next(gen)
        assert loop.cycle(seq, t, acc, travel, t + 0.005)[1].reasons == ['deadline_misses'] * 4
    assert len(bus.frames) == 34 and all(f[1] == [True] * 4 for f in bus.frames[30:])
    st = loop.status()['controller']
    assert st['states_skipped_late'] == 8 and st['deadline']['deadline_misses'] == 8
    # on time again: answered on the safe current until 20 in a row are on time, then the law
    reasons = []
    for _ in range(30):
        seq, t, acc, travel = next(gen)
        reasons.append(loop.cycle(seq, t, acc, travel, t + 0.0005)[1].reasons[0])
    assert reasons[:19] == ['deadline_misses'] * 19 and set(reasons[20:]) == {'ok'}


class TickClock:
    """A clock that advances 100 us per reading, and by what the test adds (a slow stage)."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        self.t += 1e-4
        return self.t


def test_each_stages_execution_time_is_counted_where_it_is_spent(designed):
    clock = TickClock()
    sent = []

    def slow_bus(currents_a, failsafe, cycle):     # the bus write takes 500 us
        clock.t += 5e-4
        sent.append(cycle)

    ctl = VehicleControllerCore(PASSENGER_CAR, 'modal-skyhook', CornerModels(FILES, **SUP),
                                cycle_s=P, max_consecutive_misses=100000)
    loop = VehicleLoop(designed, ctl, slow_bus, clock=clock)
    loop.configure(0.0)
    gen = cycles(60)
    for _ in range(10):                           # inactive: estimated only
        seq, t, acc, travel = next(gen)
        loop.cycle(seq, t, acc, travel, t + 0.0005)
    loop.activate(100.0)
    for _ in range(40):                           # answered
        seq, t, acc, travel = next(gen)
        loop.cycle(seq, t, acc, travel, t + 0.0005)
    for _ in range(5):                            # past their deadline: not answered
        seq, t, acc, travel = next(gen)
        loop.cycle(seq, t, acc, travel, t + 0.005)
    loop.cycle(seq, t, acc, travel, t + 0.0005)   # a repeat: not used, its step counted
    ex = loop.status()['loop']['execution_s']
    assert set(ex) == {'estimate', 'control', 'send'}
    assert (ex['estimate']['n'], ex['control']['n'], ex['send']['n']) == (56, 40, 40)
    assert len(sent) == 40
    # one clock tick a stage, the bus write's 500 us in the send stage only (bins: 2.3 %)
    for stage, expect in (('estimate', 1e-4), ('control', 1e-4), ('send', 6e-4)):
        assert ex[stage]['p50_s'] == pytest.approx(expect, rel=0.03), stage
        assert ex[stage]['max_s'] == pytest.approx(expect, rel=1e-9), stage
    # reception: every cycle's bus time to the loop's start (0.5 ms; the late ones 5 ms); a
    # cycle answered 0.9 ms after its start leaves the next one free, but each late one
    # ends 5 ms after its bus time: the four late ones after the first and the repeat came
    # while the loop was still on the cycle before
    st = loop.status()['loop']
    assert st['reception_s']['n'] == 56
    assert st['reception_s']['p50_s'] == pytest.approx(5e-4, rel=0.03)
    assert st['reception_s']['max_s'] == pytest.approx(5e-3, rel=1e-9)
    assert st['cycles_queued'] == 5
    json.dumps(loop.status())


def test_each_miss_is_named_by_its_cause(designed):
    """Slow, reached late, queued behind a late cycle, bunched behind a late frame: counted."""
    clock = TickClock()
    slow = []

    def bus(currents_a, failsafe, cycle):
        clock.t += slow.pop() if slow else 0.0

    ctl = VehicleControllerCore(PASSENGER_CAR, 'modal-skyhook', CornerModels(FILES, **SUP),
                                cycle_s=P, max_consecutive_misses=100000)
    loop = VehicleLoop(designed, ctl, bus, clock=clock)
    loop.configure(0.0)
    loop.activate(0.0)
    gen = cycles(40)

    def run(lag_s, shift_s=0.0):
        seq, t, acc, travel = next(gen)
        loop.cycle(seq, t + shift_s, acc, travel, t + shift_s + lag_s)

    for _ in range(20):                         # on time: 0.5 ms in, a few ticks' work
        run(0.0005)
    assert loop.misses == dict.fromkeys(MISS_CAUSES, 0) and loop.cycles_queued == 0
    slow.append(0.002)                          # a bus write of 2 ms: the cycle ends late
    run(0.0005)
    run(0.0005)                                 # behind it, queued, yet answered in time
    assert loop.misses['slow'] == 1 and loop.cycles_queued == 1
    assert sum(loop.misses.values()) == 1
    run(0.0019)                                 # reached 1.9 ms after its frame: late
    assert loop.misses['reached_late'] == 1
    run(0.0019, shift_s=0.0015)                 # its frame 1.5 ms late, reached late too
    run(0.0018)                                 # 0.5 ms behind that frame: bunched
    assert loop.misses['reached_late'] == 2 and loop.misses['bunched'] == 1
    run(0.0005)                                 # in time (queued behind that one)
    run(0.005)                                  # skipped late: reached late
    run(0.005)                                  # behind it (a full period after): queued
    assert loop.misses == {'bunched': 1, 'queued': 1, 'reached_late': 3, 'slow': 1}
    assert loop.status()['loop']['misses'] == loop.misses
    # the controller's deadline supervision judges an answered cycle when its command has
    # left, a skipped one when the loop comes to it; the loop names each miss it counted
    assert ctl.monitor.misses == sum(loop.misses.values()) == 6
    assert ctl.monitor.cycles == 28
