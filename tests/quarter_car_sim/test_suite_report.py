"""Tests of quarter_car_sim.suite_report (summary of a suite run) and suite_plots, without ROS."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml

from quarter_car_sim import live_loop, suite_report
from quarter_car_sim.dynamics import QuarterCar
from quarter_car_sim.failsafe import ModelSupervisor
from quarter_car_sim.params import QuarterCarParams

QC = {'plant': 'kwok-current', 'road': 'iso8608', 'road_class': 'C', 'speed_m_s': 20.0,
      'road_seed': 4, 'road_duration_s': 6.0, 'safe_current_a': 0.5, 'controller': 'skyhook'}


def _truth_msg():
    from mr_damper_model import presets
    model, params = presets.thesis_kwok_current()
    return params, dict(params, i_ref_a=2.0, current_min_a=0.0, current_max_a=2.0, valid=1.0,
                        rmse_n=1.0, nrmse_percent=0.1, window_end_s=1.0)


def _measurements(params, n=4000, rng=0):
    gen = np.random.default_rng(rng)
    t = np.arange(n) * 1e-3
    x = 0.03 * np.sin(2 * np.pi * 1.1 * t)
    v = 0.03 * 2 * np.pi * 1.1 * np.cos(2 * np.pi * 1.1 * t)
    i = np.repeat([0.0, 0.5, 1.0, 2.0], n // 4)
    f = suite_report.model_force(dict(params, i_ref_a=2.0), x, v, i) + gen.normal(0, 1.0, n)
    return {'t': t, 'x': x, 'v': v, 'f': f, 'i': i, 'recv_epoch_s': 1000.0 + t + 0.002}


def test_model_force_is_the_kwok_current_model():
    from mr_damper_model.models import get_model
    params, _ = _truth_msg()
    model = get_model('kwok-current', i_ref_a=2.0)
    x = np.linspace(-0.03, 0.03, 50)
    v = np.linspace(0.2, -0.2, 50)
    i = np.linspace(0.0, 2.0, 50)
    np.testing.assert_allclose(suite_report.model_force(params, x, v, i),
                               model.force(model.from_dict(params), x, v, i), rtol=1e-12)


def test_fit_error_known_values():
    rmse, nrmse = suite_report.fit_error([0.0, 10.0, 0.0, 10.0], [1.0, 9.0, 1.0, 9.0])
    assert rmse == pytest.approx(1.0) and nrmse == pytest.approx(10.0)
    assert all(math.isnan(v) for v in suite_report.fit_error([], []))


def test_identification_summary_recovers_truth():
    params, msg = _truth_msg()
    meas = _measurements(params)
    bad = dict(msg, valid=0.0, c1=0.0)
    log = [(1.0, bad), (2.5, msg), (3.0, msg)]
    ident = suite_report.identification_summary(meas, log, truth=msg)
    assert ident['updates'] == 3 and ident['valid_updates'] == 2
    assert ident['first_valid_s'] == 2.5
    assert all(abs(e) < 1e-9 for e in ident['parameter_error_percent'].values())
    # noise std 1 N on a ~1700 N force range: RMSE of the true model is the noise
    assert ident['rmse_n'] == pytest.approx(1.0, rel=0.05)
    assert ident['truth_rmse_n'] == pytest.approx(ident['rmse_n'])
    # the invalid early model (no current dependence) is much worse on the whole record
    assert ident['history'][0]['record_nrmse_percent'] > 10 * ident['nrmse_percent']


def test_measurement_to_parameters_delay():
    params, msg = _truth_msg()
    meas = _measurements(params)
    log = [(0.0, dict(msg, window_end_s=2.0, recv_epoch_s=1000.0 + 2.0 + 0.002 + 0.05))]
    d = suite_report.measurement_to_parameters(meas, log)
    np.testing.assert_allclose(d, [0.05], atol=1e-9)


def _live_log(controller_offers=False, seconds=4.0):
    """Run the node's loop in-process, in the node's way (t0 = -settle), and log it."""
    car_p = QuarterCarParams()
    road = live_loop.make_road('iso8608', road_class='C', speed_m_s=20.0, seed=4,
                               duration_s=QC['road_duration_s'])
    car = QuarterCar(car_p, live_loop.make_plant('kwok-current'), road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=100.0, safe_current_a=0.5)
    ctrl = live_loop.make_controller('skyhook')
    loop = live_loop.ClosedLoop(car, ctrl, sup, 1e-3)
    trace = live_loop.TraceLog()
    _, msg = _truth_msg()
    n = int(round((seconds + live_loop.SETTLE_S) / 1e-3))
    for k in range(n):
        if controller_offers and k == 1500:
            sup.offer(msg, 0.0)
        state = loop.step(0.0)
        trace.append(state, loop.i_cmd, loop.f_demand, sup.mode == 'normal', 1e-3 * k, 1e-5)
    log = trace.arrays()
    log['dt'] = 1e-3
    return log


def test_passive_reference_reproduces_a_passive_live_run():
    """Same road, seed, plant and timing: the offline passive run IS the fail-safe live run."""
    log = _live_log(controller_offers=False)
    ride = suite_report.ride_summary(log, QC)
    assert 'never left fail-safe' in ride['note']
    for key in ('rms_body_accel_wk', 'rms_body_accel', 'rms_tyre_load_ratio',
                'rms_suspension_travel'):
        assert ride['skyhook'][key] == pytest.approx(ride['passive'][key], rel=2e-3), key
    assert ride['passive_0a']['rms_body_accel_wk'] != ride['passive']['rms_body_accel_wk']


def test_live_skyhook_window_starts_at_first_normal_step():
    log = _live_log(controller_offers=True)
    ride = suite_report.ride_summary(log, QC)
    assert ride['window_s'][0] == pytest.approx(1.0, abs=2e-3)     # step 1500 of t0 = -0.5
    assert ride['skyhook']['rms_body_accel_wk'] < ride['passive']['rms_body_accel_wk']
    assert ride['wk_improvement_percent'] > 0


def test_make_report_end_to_end(tmp_path):
    params, msg = _truth_msg()
    meas = _measurements(params)
    np.savez(tmp_path / 'measurement.npz', **meas)
    rec = {'params': [[1.0, dict(msg, recv_epoch_s=1001.5)], [1.2, dict(msg)]],
           'truth': msg, 'truth_spencer': None,
           'status': {'rig': {'samples_published': 4000},
                      'identifier': {'samples_received': 3990}},
           'measurement_gaps': 0, 'measurements_received': 4000}
    (tmp_path / 'recording.json').write_text(json.dumps(rec))
    log = _live_log(controller_offers=True, seconds=3.0)
    status = {'failsafe_s': 1.5, 'mode': 'normal', 'params_rejected': {'stale': 0}}
    np.savez(tmp_path / 'quarter_car_log.npz', **log, status=json.dumps(status))
    cfg = {'/**': {'ros__parameters': {'plant': 'kwok-current'}},
           'mr_damper_rig': {'ros__parameters': {'mode': 'sim'}},
           'quarter_car_node': {'ros__parameters': QC}}
    (tmp_path / 'suite_params.yaml').write_text(yaml.safe_dump(cfg))
    s = suite_report.make_report(tmp_path, duration_s=5.0)
    assert json.loads((tmp_path / 'summary.json').read_text()) == s
    assert s['duration_s'] == 5.0 and s['failsafe_s'] == 1.5
    assert s['identification']['first_valid_s'] == 1.0
    assert s['identification']['truth_model'] == 'kwok-current'
    # 4000 samples in the recorded span, 3990 at the identifier
    assert s['messages_lost'] == 10
    assert set(s['ride']) >= {'skyhook', 'passive', 'window_s'}
    for png in ('hysteresis.png', 'convergence.png', 'ride.png'):
        assert (tmp_path / png).stat().st_size > 5000
    text = suite_report.format_summary(s)
    assert 'parameter errors' in text and 'messages lost: 10' in text


def test_module_does_not_import_rclpy():
    code = ('import sys, quarter_car_sim.suite_report, quarter_car_sim.suite_plots; '
            'print("rclpy" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == 'False'


def test_messages_lost_counts_the_identifier_not_the_recorder():
    rec = {'status': {'identifier': {'samples_received': 1040}}, 'measurement_gaps': 40,
           'measurements_received': 1000}
    lost, br = suite_report.messages_summary(rec, {})
    assert lost == 0 and br['measurement_gaps_at_recorder'] == 40
    rec['status']['identifier']['samples_received'] = 1030
    assert suite_report.messages_summary(rec, {})[0] == 10
    lost, br = suite_report.messages_summary({'measurement_gaps': 3, 'status': {}}, {})
    assert lost == 3 and 'note' in br
