"""Tests of quarter_car_sim.hil: delay compensation, tracking metrics and the HIL loop."""
import math

import numpy as np
import pytest

from mr_damper_rig.actuator import ServoActuator
from quarter_car_sim import hil, live_loop
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.params import QuarterCarParams

DT = 1e-3


def _track(act, comp, seconds=2.0, freq_hz=2.0, amp_m=0.01):
    t = DT * np.arange(int(seconds / DT))
    xd = amp_m * np.sin(2 * math.pi * freq_hz * t)
    xm = np.array([act.step(x if comp is None else comp(x))[0] for x in xd])
    half = t.size // 2                                 # after the start-up transient
    return hil.tracking_error(xd[half:], xm[half:], DT)


def test_tracking_error_recovers_a_known_pure_delay():
    t = DT * np.arange(3000)
    xd = 0.01 * np.sin(2 * math.pi * 1.5 * t)
    xm = 0.01 * np.sin(2 * math.pi * 1.5 * (t - 0.008))
    e = hil.tracking_error(xd, xm, DT)
    assert e['delay_s'] == pytest.approx(0.008, rel=0.02)
    # sine of amplitude A delayed by tau: error amplitude 2 A sin(pi f tau)
    amp = 2 * 0.01 * math.sin(math.pi * 1.5 * 0.008)
    assert e['peak_m'] == pytest.approx(amp, rel=1e-3)
    assert e['rms_m'] == pytest.approx(amp / math.sqrt(2), rel=1e-2)


@pytest.mark.parametrize('kind', ['first', 'second'])
def test_polynomial_compensation_cuts_tracking_error_on_a_sine(kind):
    act = ServoActuator(kind, DT, delay_s=0.002)
    plain = _track(act, None)
    act.reset()
    comp = hil.DelayCompensator(DT, act.equivalent_delay_s, order=2)
    compensated = _track(act, comp)
    assert plain['delay_s'] == pytest.approx(act.equivalent_delay_s, rel=0.15)
    assert compensated['rms_m'] < plain['rms_m'] / 4
    assert compensated['peak_m'] < plain['peak_m'] / 4
    assert abs(compensated['delay_s']) < 0.2 * plain['delay_s']


def test_adaptive_horizon_converges_to_the_true_delay():
    act = ServoActuator('ideal', DT, delay_s=0.010)
    comp = hil.DelayCompensator(DT, 0.0, order=2, adapt_gain=2.0)
    mon = hil.TrackingMonitor(DT)
    t = DT * np.arange(8000)
    xd = 0.01 * np.sin(2 * math.pi * 1.0 * t)
    vd = 0.01 * 2 * math.pi * np.cos(2 * math.pi * 1.0 * t)
    for k in range(t.size):
        xm = act.step(comp(xd[k]))[0]
        mon.update(xd[k], vd[k], xm)
        if (k + 1) % 100 == 0:
            comp.adapt(mon.recent_delay_s, 0.1)
    assert comp.delay_s == pytest.approx(0.010, abs=0.001)


def test_compensator_refuses_bad_settings():
    with pytest.raises(hil.HilError, match='order'):
        hil.DelayCompensator(DT, 0.01, order=5)
    with pytest.raises(hil.HilError, match='delay_s'):
        hil.DelayCompensator(DT, -0.01)


def _truth_msg():
    from mr_damper_model import presets
    model, params = presets.thesis_kwok_current()
    return dict(params, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
                valid=1.0)


def _run(plant, seconds=2.0):
    params = QuarterCarParams()
    road = live_loop.make_road('iso8608', road_class='C', speed_m_s=20.0, seed=3,
                               duration_s=seconds)
    car = QuarterCar(params, plant, road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=1e9, safe_current_a=0.5)
    sup.offer(_truth_msg(), 0.0)
    metrics = live_loop.make_running_metrics(params)
    loop = live_loop.ClosedLoop(car, live_loop.make_controller('skyhook'), sup, DT,
                                metrics=metrics)
    states = [loop.step(0.0) for _ in range(int(round((seconds + live_loop.SETTLE_S) / DT)))]
    return np.array([[s.z_s, s.travel, s.damper_force] for s in states]), metrics.as_dict()


def test_hil_with_perfect_rig_reproduces_model_in_the_loop():
    ref, ref_m = _run(live_loop.make_plant('kwok-current'))
    plant = hil.make_hil_plant(actuator='ideal', compensation='none', delay_s=0.0,
                               feedback_delay_steps=0, force_noise_n=0.0, daq_bits=32)
    got, got_m = _run(plant)
    # only difference: the rig's first sample steps the plant with dt = 0 (coil lag of 1 ms)
    np.testing.assert_allclose(got[:, 1], ref[:, 1], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got[:, 2], ref[:, 2], rtol=0, atol=0.5)
    assert got_m['rms_body_accel_wk'] == pytest.approx(ref_m['rms_body_accel_wk'], rel=1e-3)
    assert plant.monitor.as_dict()['peak_m'] < 1e-9
    assert plant.monitor.n == got.shape[0]


def test_hil_force_feedback_is_one_sample_late():
    plant = hil.make_hil_plant(actuator='ideal', compensation='none', delay_s=0.0,
                               feedback_delay_steps=1, force_noise_n=0.0, daq_bits=32)
    plant.reset()
    f1 = plant.step(DT, 0.001, 0.1, 1.0)
    f2 = plant.step(DT, 0.002, 0.1, 1.0)
    assert f1 == 0.0
    assert f2 > 0.0                            # the first sample's force (extension resisted)
    with pytest.raises(hil.HilError, match='sample interval'):
        plant.step(2 * DT, 0.0, 0.0, 0.0)


def test_compensated_hil_rides_closer_to_model_in_the_loop_than_uncompensated():
    seconds = 3.0
    _, ref = _run(live_loop.make_plant('kwok-current'), seconds)
    out = {}
    for comp in ('none', 'poly'):
        plant = hil.make_hil_plant(actuator='second', compensation=comp, rng=2)
        _, ride = _run(plant, seconds)
        out[comp] = (abs(ride['rms_body_accel_wk'] / ref['rms_body_accel_wk'] - 1),
                     plant.monitor.as_dict())
    # the uncompensated rig lags ~10 ms (2 zeta / wn + 2 ms transport delay) ...
    assert out['none'][1]['delay_s'] == pytest.approx(0.009, abs=0.002)
    # ... compensation cuts the tracking error and brings the ride back to the reference
    assert out['poly'][1]['rms_m'] < out['none'][1]['rms_m'] / 4
    assert out['poly'][0] < out['none'][0] / 3


def test_run_loop_records_what_the_monitor_saw():
    params = QuarterCarParams()
    road = live_loop.make_road('iso8608', road_class='C', speed_m_s=20.0, seed=3,
                               duration_s=1.0)
    plant = hil.make_hil_plant(actuator='first', compensation='poly', rng=4)
    car = QuarterCar(params, plant, road, t0=0.0)
    loop = live_loop.ClosedLoop(car, live_loop.make_controller('passive@1A'),
                                ModelSupervisor(timeout_s=1.0, safe_current_a=0.5), DT)
    out = hil.run_loop(loop, 1.0)
    assert out['t'].size == 1000 and np.all(out['i_cmd'] == 1.0)
    e = hil.tracking_error(out['travel'], out['measured'], DT)
    mon = plant.monitor.as_dict()
    assert mon['n'] == 1000
    assert e['rms_m'] == pytest.approx(mon['rms_m'], rel=1e-12)
    assert e['peak_m'] == pytest.approx(mon['peak_m'], rel=1e-12)
    assert np.all(np.isfinite(out['command']))
    assert not np.array_equal(out['command'], out['travel'])     # compensated command
