"""
The quarter-car node's runtime without ROS: external commands, lock-step, probe, rig as plant.

Every step is run by hand (or by the control thread's loop in the test's own thread, as fast as
possible) on a hand-moved node clock; the assertions are counts and values, never durations.
The control period is 2**-10 s so that car time is exact and the probe schedule has no
rounding at its window edges.
"""
import math

import numpy as np
import pytest

from fake_clock import FakeClock
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.car_runtime import CarOutputs, CarRuntime
from quarter_car_sim.controller_core import CommandInput, make_node_law
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.hil import make_remote_plant
from quarter_car_sim.live_loop import ClosedLoop, TraceLog
from quarter_car_sim.params import QuarterCarParams
from quarter_car_sim.probing import CurrentProbe
from quarter_car_sim.road import make_road
from quarter_car_sim.sensors import VehicleSensors

DT = 2.0 ** -10
SAFE_A = 0.5


class Recorder(CarOutputs):
    """What the node would publish and log; ``answer(state)`` plays the external controller."""

    def __init__(self):
        self.commands, self.car_states, self.states = [], [], []
        self.displacements, self.warnings = [], []
        self.answer = None
        self.rig = None

    def publish_command(self, current_a):
        self.commands.append(current_a)

    def publish_car_state(self, state, current_a, normal, reason):
        self.car_states.append((state.t, current_a, normal, reason))
        if self.answer is not None:
            self.answer(state)

    def publish_state(self, state):
        self.states.append(state)

    def publish_displacement(self, command_m):
        self.displacements.append(command_m)
        if self.rig is not None:
            self.rig(len(self.displacements) - 1, command_m)

    def warn(self, text):
        self.warnings.append(text)


def _runtime(out, clock, *, plant=None, law='skyhook', **kw):
    params = QuarterCarParams()
    road = make_road('sine', duration_s=2.0, dt=DT)
    # no coil lag: the coil current of a step is its command
    car = QuarterCar(params, plant or make_plant('kwok-current', coil_tau_s=0.0), road, t0=0.0)
    sup = ModelSupervisor(timeout_s=1.0, safe_current_a=SAFE_A, i_min_a=0.0, i_max_a=2.0)
    law = make_node_law(law, params, 1.0 / DT, {}) if law else None
    return CarRuntime(ClosedLoop(car, law, sup, DT), clock, out, real_time_factor=0.0, **kw)


def _external(out, clock, **kw):
    cmd_in = CommandInput(timeout_s=0.05, safe_current_a=SAFE_A, i_min_a=0.0, i_max_a=2.0)
    return _runtime(out, clock, law=None, command_input=cmd_in, **kw)


def test_lockstep_step_without_a_command_counts_a_timeout_and_applies_the_safe_current():
    clock, out = FakeClock(100.0), Recorder()
    rt = _external(out, clock, lockstep=True, lockstep_timeout_s=0.001)
    new = rt.step()
    # state 0 went out with the safe current in force; no command came within the wait
    assert out.car_states == [(0.0, SAFE_A, False, 'no_command_yet')]
    assert rt.lockstep_timeouts == 1 and out.commands == []       # the car publishes none
    assert rt.current_a == SAFE_A and new.coil_current == SAFE_A and new.t == DT
    assert out.warnings == ['no command within 0.001 s of state t = 0.000 s (1 in all)']
    st = rt.status()
    assert (st['mode'], st['reason'], st['controller']) == ('failsafe', 'no_command_yet',
                                                            'external')
    assert (st['lockstep'], st['lockstep_timeouts'], st['command_timeouts']) == (True, 1, 0)
    assert st['steps'] == 1 and math.isnan(st['first_normal_t_sim'])

    # a controller that answers every state: its command drives that very step
    out.answer = lambda state: rt.offer_command(1.25)
    for _ in range(3):
        new = rt.step()
        clock.t += DT
    assert rt.lockstep_timeouts == 1
    assert rt.current_a == 1.25 and new.coil_current == 1.25
    # each state carries the mode before its own answer
    assert [s[1:] for s in out.car_states[1:]] == [(SAFE_A, False, 'no_command_yet'),
                                                   (1.25, True, 'ok'), (1.25, True, 'ok')]
    assert rt.first_normal_t == DT
    st = rt.status()
    assert (st['mode'], st['reason'], st['commands']['accepted']) == ('normal', 'ok', 3)

    # the controller falls silent for longer than command_timeout_s: the safe current again
    out.answer = None
    clock.t += 0.1
    new = rt.step()
    assert rt.lockstep_timeouts == 2 and new.coil_current == SAFE_A
    assert ('no current command for 0.05 s: safe current 0.5 A (1 time(s))'
            in out.warnings)
    st = rt.status()
    assert (st['mode'], st['reason'], st['command_timeouts'], st['failsafe_entries']) == (
        'failsafe', 'command_timeout', 1, 1)


def test_external_commands_are_checked_and_counted_without_lockstep():
    clock, out = FakeClock(100.0), Recorder()
    rt = _external(out, clock)
    outcomes = [rt.offer_command(i) for i in (5.0, -1.0, math.nan, 0.75)]
    assert outcomes == ['clamped_high', 'clamped_low', 'refused_non_finite', 'accepted']
    rt.step()
    assert rt.current_a == 0.75 and rt.lockstep_timeouts == 0 and out.warnings == []
    assert rt.status()['commands'] == {'accepted': 1, 'clamped_low': 1, 'clamped_high': 1,
                                       'refused_non_finite': 1}


def test_probe_overrides_the_fail_safe_current_with_the_farthest_starving_bin(tmp_path):
    clock, out = FakeClock(100.0), Recorder()
    # bins 0, 0.5, ..., 2 A; a 32-step window every 128 steps
    probe = CurrentProbe(0.0, 2.0, bin_a=0.5, period_s=0.125, hold_s=0.03125,
                         min_samples=10 ** 6, max_duty=0.25)
    trace = TraceLog(tmp_path / 'log', DT)
    rt = _runtime(out, clock, probe=probe, state_every=1, trace=trace)
    assert rt.control.run(max_steps=640) is None       # in this thread, as fast as possible
    # no parameters: the law is in fail-safe (0.5 A) outside the windows; in them, first the
    # emptiest bin (no sample yet; ties: the lowest), then the bin farthest from the fullest
    # one (the safe current's), held while it starves (no bin ever covered here)
    expected = np.full(640, SAFE_A)
    for w, level in enumerate((0.0, 2.0, 2.0, 2.0, 2.0)):
        expected[128 * w:128 * w + 32] = level
    np.testing.assert_array_equal(out.commands, expected)
    np.testing.assert_array_equal([s.coil_current for s in out.states], expected)
    assert all(not normal and reason == 'no_parameters_yet'
               for _, _, normal, reason in out.car_states)
    st = rt.status()
    assert st['probe']['windows'] == 5 and st['probe']['counts'] == [32, 480, 0, 0, 128]
    assert (st['steps'], st['loop']['steps'], st['mode']) == (640, 640, 'failsafe')
    assert rt.close_log() == 640
    np.testing.assert_array_equal(trace.arrays()['i_cmd'], expected)


def test_rig_as_plant_waits_for_each_answer_and_counts_the_missing_ones():
    clock, out = FakeClock(100.0), Recorder()
    remote = make_remote_plant(DT, compensation='none', stale_after_s=0.05)
    rt = _runtime(out, clock, plant=remote, remote=remote, hil_wait_s=0.001)
    skipped = {5, 11}

    def rig(k, command_m):
        # the rig answers command k with its measured force 100 + k N, stamped k * DT
        if k not in skipped:
            rt.receive_measurements(([k * DT], [command_m], [0.0], [100.0 + k], [0.8]))
    out.rig = rig
    states = [rt.step() for _ in range(20)]
    counts = rt.status()['hil']['counts']
    assert counts['wait_timeouts'] == 2 and counts['gaps'] == 2
    assert counts['measurements'] == 18 and counts['no_measurement_steps'] == 1
    assert counts['stale_steps'] == 0
    # the car publishes its travel as the command and feels the latest answer (sign: on body)
    assert out.displacements == [s.travel for s in states]
    assert states[0].damper_force == 0.0
    for k in range(1, 20):
        last = k - 1 if k - 1 not in skipped else k - 2
        assert states[k].damper_force == -(100.0 + last) and states[k].coil_current == 0.8


def test_rig_as_plant_holds_step_0_until_the_rig_takes_commands():
    clock, out = FakeClock(100.0), Recorder()
    remote = make_remote_plant(DT, compensation='none')
    rt = _runtime(out, clock, plant=remote, remote=remote, hil_wait_s=0.001)
    polls = []

    def connected():
        # the rig opens its command input at the 3rd poll (its measurement readers matched)
        polls.append(len(out.displacements))
        return len(polls) >= 3
    out.rig_connected = connected
    sent = []

    def rig(k, command_m):
        # the rig's reader matches late: it answers the car's third neutral command first
        sent.append(command_m)
        if len(sent) >= 3:
            rt.receive_measurements(([len(sent) * DT], [command_m], [0.0], [50.0], [0.5]))
    out.rig = rig
    assert rt.control.run(max_steps=2) is None
    assert polls == [0, 0, 0]          # no command at all before the link was matched
    # three neutral commands until the first answer, then one per step, no wait timed out
    assert sent[:3] == [0.0, 0.0, 0.0] and len(sent) == 5
    counts = rt.status()['hil']['counts']
    assert counts['wait_timeouts'] == 0 and counts['no_measurement_steps'] == 0


def test_construction_refuses_a_law_and_a_command_input_together_and_sensors_without_one():
    clock, out = FakeClock(), Recorder()
    cmd_in = CommandInput(timeout_s=0.05, safe_current_a=SAFE_A)
    with pytest.raises(ValueError, match='not both'):
        _runtime(out, clock, command_input=cmd_in)
    with pytest.raises(ValueError, match='not both'):
        _runtime(out, clock, law=None)
    with pytest.raises(ValueError, match='needs controller:=external'):
        _runtime(out, clock, sensors=VehicleSensors(DT, 1))


def test_reconfigure_reaches_the_law_the_supervisor_and_the_health_rules():
    from quarter_car_sim.health import CarHealth
    clock, out = FakeClock(), Recorder()
    params = QuarterCarParams()
    rt = _runtime(out, clock, health_rules=CarHealth(),
                  make_law=lambda options: make_node_law('skyhook', params, 1.0 / DT, options))
    assert rt.reconfigure({'controller_options': '{"c_sky": 4500.0}', 'safe_current_a': 0.8,
                           'lateness_warn_ms': 9.0}) == ''
    assert rt.loop.controller.c_sky == 4500.0 and rt.sup.safe_current_a == 0.8
    assert rt.health_rules.lateness_warn_ms == 9.0
    assert 'controller:=external' in rt.reconfigure({'command_timeout_s': 0.5})
    rt.step()
    assert rt.current_a == 0.8                        # the new safe current (no parameters)
