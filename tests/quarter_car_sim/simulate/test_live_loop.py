"""Tests of quarter_car_sim.simulate.live_loop: the node's control loop without ROS."""
import subprocess
import sys

import numpy as np
import pytest

from mr_damper_common.recording.columnlog import ColumnReader
from mr_damper_model.models.plant import make_plant
from quarter_car_sim.simulate import live_loop
from semi_active_control.laws import make_controller, Passive, Skyhook
from quarter_car_sim.plant.quarter_car import QuarterCar
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import make_road


def _truth():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    msg = dict(params, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
               valid=1.0)
    return params, msg


def _loop(controller, *, safe=0.5, seconds=3.0):
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=3,
                     duration_s=seconds)
    car = QuarterCar(params, make_plant('kwok-current'), road, t0=-0.5)
    sup = ModelSupervisor(timeout_s=1.0, safe_current_a=safe)
    metrics = live_loop.make_running_metrics(params, 1e-3)
    return live_loop.ClosedLoop(car, controller, sup, 1e-3, metrics=metrics)


def test_failsafe_commands_safe_current_then_model_then_stale():
    loop = _loop(Skyhook(3000.0))
    truth, msg = _truth()
    for k in range(200):                              # no model yet
        loop.step(0.001 * k)
        assert loop.i_cmd == 0.5 and loop.sup.mode == 'failsafe'
    loop.sup.offer(msg, 0.2)
    currents = []
    for k in range(200, 1100):                        # model fresh until t = 1.2 s
        loop.step(0.001 * k)
        currents.append(loop.i_cmd)
    currents = np.array(currents)
    assert np.all((currents >= 0.0) & (currents <= 2.0))
    assert np.unique(np.round(currents, 3)).size > 50   # a controller, not a constant
    loop.step(1.25)                                   # stale
    assert loop.sup.mode == 'failsafe' and loop.sup.reason == 'stale' and loop.i_cmd == 0.5
    assert loop.steps == 1101
    assert loop.metrics.n == 1101


def test_inverse_delivers_the_demanded_force_with_the_true_model():
    """With the plant's own parameters the model force at the command equals the demand."""
    loop = _loop(Skyhook(3000.0))
    truth, msg = _truth()
    loop.sup.offer(msg, 0.0)
    from mr_damper_model.models.inverse import KwokCurrentInverse
    inv = KwokCurrentInverse(truth, tol_a=1e-4, sign_convention='body')
    checked = 0
    for k in range(2000):
        state = loop.car.state
        i = loop.command(state, 0.0)
        if not loop.last_saturated:                   # reachable demands
            f_model = inv.force(i, state.travel, state.v_rel)
            assert -f_model == pytest.approx(loop.f_demand, abs=0.5)
            checked += 1
        loop.advance()
    assert checked > 100


def test_inverse_kept_inside_identified_current_range():
    loop = _loop(Skyhook(3000.0))
    truth, msg = _truth()
    loop.sup.offer(dict(msg, current_min_a=0.0, current_max_a=1.25), 0.0)
    cur = np.array([loop.step(0.0) and loop.i_cmd for _ in range(3000)])
    assert cur.max() <= 1.25 + 1e-12 and cur.max() > 1.2   # saturates at the range, not 2 A


def test_passive_controller_ignores_the_model():
    loop = _loop(Passive(1.5))
    for k in range(100):
        loop.step(0.001 * k)
    assert loop.i_cmd == 1.5


def test_active_controller_refused():
    with pytest.raises(ValueError, match='force actuator'):
        make_controller('skyhook-ideal', damper_only=True)


def test_pacer_schedule_and_reanchor():
    now = [10.0]
    pacer = live_loop.Pacer(1e-3, 2.0, clock=lambda: now[0], max_burst=5)
    assert pacer.period() == pytest.approx(5e-4)
    pacer.wait()                      # step 0 due at once
    assert pacer.k == 1 and pacer.lateness == pytest.approx(0.0)
    now[0] += 0.0012                  # 1.2 ms later: steps 1 and 2 are due, step 1 late 0.7 ms
    pacer.wait()
    assert pacer.lateness == pytest.approx(0.0007)
    now[0] += 1.0                     # hopelessly behind: re-anchored, counted
    pacer.wait()
    assert pacer.late == 1
    assert pacer.next_deadline() == pytest.approx(now[0] + 5e-4)
    fast = live_loop.Pacer(1e-3, 0.0, clock=lambda: now[0])
    assert fast.period() == 0.0 and fast.wait() == now[0]


def test_timing_stats_known_values():
    st = live_loop.timing_stats([1e-3] * 98 + [3e-3, 5e-3], nominal=1e-3)
    assert st['n'] == 100 and st['p50_ms'] == pytest.approx(1.0)
    assert st['max_ms'] == pytest.approx(5.0) and st['jitter_max_ms'] == pytest.approx(4.0)
    assert st['mean_ms'] == pytest.approx((98 + 3 + 5) / 100)
    empty = live_loop.timing_stats([], nominal=1e-3)
    assert empty['n'] == 0 and np.isnan(empty['jitter_p99_ms'])


def test_trace_log_round_trip(tmp_path):
    loop = _loop(Passive(0.5))
    path = tmp_path / 'log'
    trace = live_loop.TraceLog(path, 1e-3, chunk_rows=16)
    for k in range(50):
        state = loop.step(0.001 * k)
        trace.append(state, loop.i_cmd, loop.f_demand, False, 0.001 * k, 1e-5, 0.0)
        if k == 39:
            # streamed as it runs: the first 32 steps (two chunks) are on disk already
            assert ColumnReader(path).rows == 32
    trace.close(status={'mode': 'failsafe', 'failsafe_s': float('nan')})
    r = ColumnReader(path)
    assert r.columns == live_loop.TRACE_COLUMNS
    assert r.meta['dt'] == 1e-3 and r.meta['status'] == {'mode': 'failsafe', 'failsafe_s': None}
    z = r.read()
    assert z['t'].size == 50
    np.testing.assert_allclose(np.diff(z['t']), 1e-3, atol=1e-12)
    assert np.all(z['i_cmd'] == 0.5) and np.all(z['mode'] == 0.0)


def test_loop_timing_counts_jitter():
    lt = live_loop.LoopTiming(1e-3)
    for k, w in enumerate([0.0, 0.001, 0.002, 0.0055, 0.0065]):
        lt.add(w, 1e-5, 2e-5, 0.0)
    st = lt.stats()
    assert st['steps'] == 5 and st['jitter_over_2ms'] == 1
    assert st['period']['max_ms'] == pytest.approx(3.5)


@pytest.mark.slow
def test_module_does_not_import_rclpy():
    code = 'import sys, quarter_car_sim.simulate.live_loop; print("rclpy" in sys.modules)'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == 'False'


def test_fixed_inverse_loop_applies_an_active_force_and_checks_its_settings():
    # without a supervisor an active law's force goes to the car directly (command NaN), as
    # QuarterCar.step_force does; an external command needs a supervisor; a supervised loop
    # takes its inverse from the supervisor only
    from semi_active_control.laws import SkyhookIdeal
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=3, duration_s=0.2)
    law = SkyhookIdeal()
    loop = live_loop.ClosedLoop(QuarterCar(params, None, road), law, dt=1e-3)
    ref = QuarterCar(params, None, road)
    for _ in range(100):
        f = law.demand(ref.state)
        a, b = loop.step(), ref.step_force(1e-3, f)
        fields = ('t', 'z_s', 'v_s', 'z_u', 'v_u', 'damper_force')
        assert [getattr(a, n) for n in fields] == [getattr(b, n) for n in fields]
        assert np.isnan(loop.i_cmd) and loop.f_demand == f
    with pytest.raises(ValueError, match='supervisor'):
        live_loop.ClosedLoop(QuarterCar(params, None, road), None, dt=1e-3)
    sup_loop = _loop(Skyhook(), seconds=0.2)
    with pytest.raises(ValueError, match='supervisor'):
        sup_loop.inverse = None
