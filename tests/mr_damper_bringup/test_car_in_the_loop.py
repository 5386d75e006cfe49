"""Tests of mr_damper_bringup.car_in_the_loop: the car's loop with a virtual rig for a damper."""
import numpy as np
import pytest

from mr_damper_model.models.plant import make_plant
from mr_damper_bringup import car_in_the_loop as cil
from mr_damper_rig.actuator import ServoActuator
from quarter_car_sim.runtime import hil
from quarter_car_sim.simulate import live_loop
from semi_active_control.laws import make_controller
from quarter_car_sim.plant.quarter_car import QuarterCar
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.quarter_car import QuarterCarParams
from quarter_car_sim.plant.road import make_road

DT = 1e-3


def _truth_msg():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    return dict(params, i_ref_a=model.options['i_ref_a'], current_min_a=0.0, current_max_a=2.0,
                valid=1.0)


def _run(plant, seconds=2.0):
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=3, duration_s=seconds)
    car = QuarterCar(params, plant, road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=1e9, safe_current_a=0.5)
    sup.offer(_truth_msg(), 0.0)
    metrics = live_loop.make_running_metrics(params)
    loop = live_loop.ClosedLoop(car, make_controller('skyhook', damper_only=True), sup, DT,
                                metrics=metrics)
    states = [loop.step(0.0) for _ in range(int(round((seconds + live_loop.SETTLE_S) / DT)))]
    return np.array([[s.z_s, s.travel, s.damper_force] for s in states]), metrics.as_dict()


def test_hil_with_perfect_rig_reproduces_model_in_the_loop():
    ref, ref_m = _run(make_plant('kwok-current'))
    plant = cil.make_hil_plant(actuator='ideal', compensation='none', delay_s=0.0,
                               feedback_delay_steps=0, force_noise_n=0.0, daq_bits=32)
    got, got_m = _run(plant)
    # only difference: the rig's first sample steps the plant with dt = 0 (coil lag of 1 ms)
    np.testing.assert_allclose(got[:, 1], ref[:, 1], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got[:, 2], ref[:, 2], rtol=0, atol=0.5)
    assert got_m['rms_body_accel_wk'] == pytest.approx(ref_m['rms_body_accel_wk'], rel=1e-3)
    assert plant.monitor.as_dict()['peak_m'] < 1e-9
    assert plant.monitor.n == got.shape[0]


def test_hil_force_feedback_is_one_sample_late():
    plant = cil.make_hil_plant(actuator='ideal', compensation='none', delay_s=0.0,
                               feedback_delay_steps=1, force_noise_n=0.0, daq_bits=32)
    plant.reset()
    f1 = plant.step(DT, 0.001, 0.1, 1.0)
    f2 = plant.step(DT, 0.002, 0.1, 1.0)
    assert f1 == 0.0
    assert f2 > 0.0                            # the first sample's force (extension resisted)
    with pytest.raises(hil.HilError, match='sample interval'):
        plant.step(2 * DT, 0.0, 0.0, 0.0)


@pytest.mark.slow
def test_compensated_hil_rides_closer_to_model_in_the_loop_than_uncompensated():
    seconds = 3.0
    _, ref = _run(make_plant('kwok-current'), seconds)
    out = {}
    for comp in ('none', 'poly'):
        plant = cil.make_hil_plant(actuator='second', compensation=comp, rng=2)
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
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=3,
                     duration_s=1.0)
    plant = cil.make_hil_plant(actuator='first', compensation='poly', rng=4)
    car = QuarterCar(params, plant, road, t0=0.0)
    loop = live_loop.ClosedLoop(car, make_controller('passive@1A', damper_only=True),
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


# ------------------------------------------------------------ remote rig (over ROS 2 topics)
@pytest.mark.slow
def test_remote_plant_over_a_zero_latency_link_reproduces_the_in_process_hil_plant():
    # same rig seed, same actuator and compensator: the remote plant's force is the previous
    # rig sample's, exactly HilPlant's one-sample-late feedback
    seconds = 2.0
    ref, _ = _run(cil.make_hil_plant(actuator='first', compensation='poly', rng=5), seconds)
    link = cil.make_simulated_link(actuator='first', compensation='poly', rng=5,
                                   delay_s=ServoActuator('first').equivalent_delay_s)
    got, _ = _run(link, seconds)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    counts = link.remote.counts
    assert counts['measurements'] == got.shape[0] and counts['no_measurement_steps'] == 1
    assert counts['gaps'] == counts['stale_steps'] == counts['out_of_order'] == 0


@pytest.mark.slow
def test_adaptive_horizon_over_a_latent_link_grows_by_the_latency_and_cuts_the_error():
    # 5 ms of message latency the initial horizon does not know of: the adapted horizon ends
    # about 5 ms above the one adapted without latency, and the tracking error falls below the
    # fixed horizon's
    seconds = 8.0
    out = {}
    for latency, gain in ((0, 2.0), (5, 0.0), (5, 2.0)):
        link = cil.make_simulated_link(actuator='first', latency_steps=latency,
                                       adapt_gain=gain, delay_s=0.014, rng=6)
        _run(link, seconds)
        out[latency, gain] = (link.remote.compensator.delay_s, link.monitor.as_dict())
    assert out[5, 0.0][0] == pytest.approx(0.014)
    grown = out[5, 2.0][0] - out[0, 2.0][0]
    assert 0.003 < grown < 0.0065
    assert out[5, 2.0][1]['rms_m'] < 0.7 * out[5, 0.0][1]['rms_m']
    # adapted: no remaining delay left (least squares, whole run)
    assert abs(out[5, 2.0][1]['delay_s']) < 0.25 * abs(out[5, 0.0][1]['delay_s'])


@pytest.mark.slow
def test_cam_rig_comparison_ranks_the_truth_with_the_cam_fit_and_a_wrong_model_below():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    truth = dict(params, i_ref_a=model.options['i_ref_a'])
    good = cil.cam_rig_comparison(truth, 'kwok-current', maxiter=20)
    # the truth is as good as a fit on the validation record (noise only), the fit is good
    assert good['hil_nrmse_percent'] <= good['cam_nrmse_percent'] + 0.05
    assert good['cam_nrmse_percent'] < 2.0 and good['ratio'] < 1.05
    wrong = dict(truth, **{k: 1.5 * v for k, v in params.items()})
    bad = cil.cam_rig_comparison(wrong, 'kwok-current', maxiter=20)
    assert bad['hil_nrmse_percent'] > 3 * good['hil_nrmse_percent']
    assert bad['cam_nrmse_percent'] == pytest.approx(good['cam_nrmse_percent'])    # seeded


def test_hil_summary_reports_the_tracking_and_probe_of_the_statuses():
    qc = {'hil': {'tracking': {'rms_m': 0.001, 'peak_m': 0.004, 'delay_s': 0.0005, 'n': 10},
                  'travel_rms_m': 0.01, 'horizon_s': 0.016, 'counts': {'measurements': 10}},
          'probe': {'covered': 21, 'bins': 21, 'covered_s': 40.0, 'windows': 40}}
    rig = {'displacement_commands': {'accepted': 10}, 'samples_published': 12}
    s = cil.hil_summary(qc, rig, None)
    assert s['tracking_rms_m'] == 0.001 and s['travel_rms_m'] == 0.01
    assert s['rig_commands'] == {'accepted': 10} and s['rig_samples'] == 12
    assert s['identification'] == {'note': 'no valid identified parameters'}
    text = cil.format_hil_summary(s)
    assert 'tracking RMS 1.00 mm' in text and '21/21 bins' in text
