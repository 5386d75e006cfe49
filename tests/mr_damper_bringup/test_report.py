"""Tests of mr_damper_bringup.report (summary of a suite run from its MCAP) and its plots."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml

from mr_damper_bringup import report
from mr_damper_bringup.recorder import SuiteRecorder
from mr_damper_common.recording.columnlog import ColumnReader, ColumnWriter
from mr_damper_model.models.kwok_current import kwok_current_force
from quarter_car_sim.simulate import live_loop
from quarter_car_sim.plant.quarter_car import QuarterCar
from semi_active_control.supervision.failsafe import ModelSupervisor
from semi_active_control.car.quarter_car import QuarterCarParams

QC = {'plant': 'kwok-current', 'road': 'iso8608', 'road_class': 'C', 'speed_m_s': 20.0,
      'road_seed': 4, 'road_duration_s': 6.0, 'safe_current_a': 0.5, 'controller': 'skyhook'}


def _truth_msg():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    return params, dict(params, i_ref_a=2.0, current_min_a=0.0, current_max_a=2.0, valid=1.0,
                        rmse_n=1.0, nrmse_percent=0.1, window_end_s=1.0)


def _measurements(params, n=4000, rng=0):
    gen = np.random.default_rng(rng)
    t = np.arange(n) * 1e-3
    x = 0.03 * np.sin(2 * np.pi * 1.1 * t)
    v = 0.03 * 2 * np.pi * 1.1 * np.cos(2 * np.pi * 1.1 * t)
    i = np.repeat([0.0, 0.5, 1.0, 2.0], n // 4)
    f = kwok_current_force(dict(params, i_ref_a=2.0), x, v, i) + gen.normal(0, 1.0, n)
    return {'t': t, 'x': x, 'v': v, 'f': f, 'i': i, 'recv_epoch_s': 1000.0 + t + 0.002}


def test_fit_error_known_values():
    rmse, nrmse = report.fit_error([0.0, 10.0, 0.0, 10.0], [1.0, 9.0, 1.0, 9.0])
    assert rmse == pytest.approx(1.0) and nrmse == pytest.approx(10.0)
    assert all(math.isnan(v) for v in report.fit_error([], []))


def test_identification_summary_recovers_truth():
    params, msg = _truth_msg()
    meas = _measurements(params)
    bad = dict(msg, valid=0.0, c1=0.0)
    log = [(1.0, bad), (2.5, msg), (3.0, msg)]
    ident = report.identification_summary(meas, log, truth=msg)
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
    d = report.measurement_to_parameters(meas, log)
    np.testing.assert_allclose(d, [0.05], atol=1e-9)


def test_measurement_to_parameters_counts_a_republished_set_once():
    # a refused window keeps the set in use: the identifier publishes it again, with the
    # window it came from; only its first arrival is the delay of that window
    params, msg = _truth_msg()
    meas = _measurements(params)
    first = dict(msg, window_end_s=2.0, recv_epoch_s=1000.0 + 2.0 + 0.002 + 0.05)
    again = [dict(first, recv_epoch_s=first['recv_epoch_s'] + 0.2 * k) for k in (1, 2, 3)]
    later = dict(msg, window_end_s=3.0, recv_epoch_s=1000.0 + 3.0 + 0.002 + 0.07)
    log = [(0.0, first), *[(0.2 * k, a) for k, a in enumerate(again, 1)], (1.0, later)]
    d = report.measurement_to_parameters(meas, log)
    np.testing.assert_allclose(d, [0.05, 0.07], atol=1e-9)


def _live_log(path, controller_offers=False, seconds=4.0, status=None):
    """Run the node's loop in-process, in the node's way (t0 = -settle), and log it to path."""
    car_p = QuarterCarParams()
    from mr_damper_model.models.plant import make_plant
    from semi_active_control.laws import make_controller
    from quarter_car_sim.plant.road import make_road
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=4,
                     duration_s=QC['road_duration_s'])
    car = QuarterCar(car_p, make_plant('kwok-current'), road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=100.0, safe_current_a=0.5)
    ctrl = make_controller('skyhook', damper_only=True)
    loop = live_loop.ClosedLoop(car, ctrl, sup, 1e-3)
    trace = live_loop.TraceLog(path, 1e-3)
    _, msg = _truth_msg()
    n = int(round((seconds + live_loop.SETTLE_S) / 1e-3))
    for k in range(n):
        if controller_offers and k == 1500:
            sup.offer(msg, 0.0)
        state = loop.step(0.0)
        trace.append(state, loop.i_cmd, loop.f_demand, sup.mode == 'normal', 1e-3 * k, 1e-5)
    trace.close(**({'status': status} if status else {}))
    return ColumnReader(path)


def test_passive_reference_reproduces_a_passive_live_run(tmp_path):
    """Same road, seed, plant and timing: the offline passive run IS the fail-safe live run."""
    log = _live_log(tmp_path / 'log', controller_offers=False)
    ride = report.ride_summary(log, QC)
    assert 'never left fail-safe' in ride['note']
    for key in ('rms_body_accel_wk', 'rms_body_accel', 'rms_tyre_load_ratio',
                'rms_suspension_travel'):
        assert ride['skyhook'][key] == pytest.approx(ride['passive'][key], rel=2e-3), key
    assert ride['passive_0a']['rms_body_accel_wk'] != ride['passive']['rms_body_accel_wk']


@pytest.mark.slow
def test_live_skyhook_window_starts_at_first_normal_step(tmp_path):
    log = _live_log(tmp_path / 'log', controller_offers=True)
    ride = report.ride_summary(log, QC)
    assert ride['window_s'][0] == pytest.approx(1.0, abs=2e-3)     # step 1500 of t0 = -0.5
    assert ride['skyhook']['rms_body_accel_wk'] < ride['passive']['rms_body_accel_wk']
    assert ride['wk_improvement_percent'] > 0


def _write_run(path, meas, params_msgs, statuses, truth, cfg, *, drop=(), node_params=None,
               first_index=0, extra=()):
    """
    Write a synthetic ``suite.mcap`` the way the recorder node does (rclpy CDR bytes).

    ``params_msgs``: (receive time [s], dict); ``statuses``: (receive time [s], node, dict);
    ``drop``: measurement indices not recorded (gaps); ``node_params``: {node: parameters} as
    the recorder asks them from the nodes; ``first_index``: the stream index of the first sample
    (a later part of a recording goes on with the rig's index); ``extra``: more messages
    ``(receive time [s], key, rclpy message)``, written after the rest.
    """
    from rclpy.serialization import serialize_message

    from mr_damper_common import messages as mm
    from mr_damper_common.health import Health, OK
    from mr_damper_bringup.topics import NODE_PARAMETERS_TOPIC
    with SuiteRecorder(path, config_text=yaml.safe_dump(cfg), start_ns=999_000_000_000) as rec:
        for node, p in (node_params or {}).items():
            rec.write_text(NODE_PARAMETERS_TOPIC, yaml.safe_dump({node: {'ros__parameters': p}}),
                           999_000_000_002)
        rec.write('truth', serialize_message(mm.kwok_parameters_msg(truth)), 999_000_000_001)
        for k in range(meas['t'].size):
            if k in drop:
                continue
            # one sample per batch: a dropped sample is a jump of the stream index
            msg = mm.samples_to_msg(*([meas[c][k]] for c in 'txvfi'), sequence=first_index + k,
                                    first_index=first_index + k)
            rec.write('measurement', serialize_message(msg),
                      int(round(meas['recv_epoch_s'][k] * 1e9)))
        for t, d in params_msgs:
            rec.write('parameters', serialize_message(mm.kwok_parameters_msg(d)),
                      int(round(t * 1e9)))
        names = {'rig': 'mr_damper_rig', 'identifier': 'mr_damper_identifier',
                 'quarter_car': 'quarter_car_node', 'controller': 'semi_active_controller',
                 'recorder': 'mr_damper_record'}
        for t, node, d in statuses:
            diag = mm.diagnostic_array_msg([mm.diagnostic_status_msg(names[node], Health(
                OK, 'ok', d))], stamp_s=t)
            rec.write('diagnostics', serialize_message(diag), int(round(t * 1e9)))
        for t, key, msg in extra:
            rec.write(key, serialize_message(msg), int(round(t * 1e9)))
    return path


def _cfg():
    return {'/**': {'ros__parameters': {'plant': 'kwok-current'}},
            'mr_damper_rig': {'ros__parameters': {'mode': 'sim'}},
            'quarter_car_node': {'ros__parameters': dict(QC)}}


def test_read_recording_counts_gaps_and_decodes_every_kind(tmp_path):
    params, msg = _truth_msg()
    meas = _measurements(params, n=500)
    statuses = [(1000.2, 'rig', {'samples_published': 250}),
                (1001.0, 'identifier', {'samples_received': 497}),
                (1001.1, 'rig', {'samples_published': 500})]
    _write_run(tmp_path / 'suite.mcap', meas, [(1000.3, dict(msg, valid=False))], statuses,
               msg, _cfg(), drop=(100, 101, 300))
    rec = report.read_recording(tmp_path / 'suite.mcap', tmp_path)
    assert rec['config'] == _cfg()
    assert rec['measurements_received'] == 497 and rec['measurement_gaps'] == 3
    ok = {'level': 0, 'message': 'ok'}
    assert rec['status'] == {'rig': dict(ok, samples_published=500),
                             'identifier': dict(ok, samples_received=497)}
    assert rec['status_messages'] == {'rig': 2, 'identifier': 1}
    assert rec['truth']['c0'] == params['c0'] and rec['truth']['valid'] == 1.0
    assert rec['parameter_messages'] == 1
    assert rec['topic_messages']['measurement'] == 497 and rec['bad_messages'] == {}
    got = ColumnReader(tmp_path / 'measurement').read()
    keep = np.setdiff1d(np.arange(500), [100, 101, 300])
    for c in ('t', 'x', 'v', 'f', 'i', 'recv_epoch_s'):
        np.testing.assert_allclose(got[c], meas[c][keep], rtol=0, atol=1e-9)
    (line,) = (tmp_path / 'parameters.jsonl').read_text().splitlines()
    t, d = json.loads(line)
    assert t == pytest.approx(1.3) and d['valid'] == 0.0
    assert d['recv_epoch_s'] == pytest.approx(1000.3)


@pytest.mark.slow
def test_make_report_end_to_end(tmp_path):
    params, msg = _truth_msg()
    meas = _measurements(params)
    statuses = [(1004.5, 'rig', {'samples_published': 4000}),
                (1004.6, 'identifier', {'samples_received': 3990})]
    _write_run(tmp_path / 'suite.mcap', meas,
               [(1000.0, dict(msg)), (1000.2, dict(msg))], statuses, msg, _cfg())
    status = {'failsafe_s': 1.5, 'mode': 'normal', 'params_rejected': {'stale': 0}}
    _live_log(tmp_path / 'quarter_car_log', controller_offers=True, seconds=3.0, status=status)
    s = report.make_report(tmp_path, duration_s=5.0)
    assert json.loads((tmp_path / 'summary.json').read_text()) == s
    assert s['duration_s'] == 5.0 and s['failsafe_s'] == 1.5
    # receive time of the first valid parameters - the recorder's start (999 s)
    assert s['identification']['first_valid_s'] == pytest.approx(1.0)
    assert s['identification']['truth_model'] == 'kwok-current'
    assert s['identification']['updates'] == 2
    # 4000 samples in the recorded span, 3990 at the identifier
    assert s['messages_lost'] == 10
    assert s['recording']['messages']['measurement'] == 4000
    assert set(s['ride']) >= {'skyhook', 'passive', 'window_s'}
    for png in ('hysteresis.png', 'convergence.png', 'ride.png'):
        assert (tmp_path / png).stat().st_size > 5000
    assert not list(tmp_path.glob('.report_*'))        # the extracts are gone
    text = report.format_summary(s)
    assert 'parameter errors' in text and 'messages lost: 10' in text


@pytest.mark.slow
def test_settings_come_from_what_the_nodes_report(tmp_path):
    """The car's reported parameters (its defaults included) win over the YAML section."""
    params, msg = _truth_msg()
    meas = _measurements(params, n=1000)
    cfg = _cfg()
    del cfg['quarter_car_node']['ros__parameters']['safe_current_a']     # a node default
    car = dict(QC, safe_current_a=0.25, use_sim_time=False)
    _write_run(tmp_path / 'suite.mcap', meas, [(1000.0, dict(msg))], [], msg, cfg,
               node_params={'quarter_car_node': car})
    rec = report.read_recording(tmp_path / 'suite.mcap', tmp_path)
    assert rec['node_parameters'] == {'quarter_car_node': car}
    eff = report.effective_config(rec)
    assert eff['quarter_car_node']['ros__parameters']['safe_current_a'] == 0.25
    assert eff['mr_damper_rig'] == cfg['mr_damper_rig']
    _live_log(tmp_path / 'quarter_car_log', controller_offers=True, seconds=2.0)
    s = report.make_report(tmp_path, duration_s=3.0, plots=False)
    assert s['ride']['passive_current_a'] == 0.25
    assert s['recording']['node_parameters'] == ['quarter_car_node']


def test_make_report_without_a_recording_says_so(tmp_path):
    with pytest.raises(FileNotFoundError, match='suite.mcap'):
        report.make_report(tmp_path)


@pytest.mark.slow
def test_module_does_not_import_rclpy():
    code = ('import sys, mr_damper_bringup.report, mr_damper_bringup.plots; '
            'print("rclpy" in sys.modules)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == 'False'


def test_messages_lost_counts_the_identifier_not_the_recorder():
    rec = {'status': {'identifier': {'samples_received': 1040}}, 'measurement_gaps': 40,
           'measurements_received': 1000}
    lost, br = report.messages_summary(rec, {})
    assert lost == 0 and br['measurement_gaps_at_recorder'] == 40
    rec['status']['identifier']['samples_received'] = 1030
    assert report.messages_summary(rec, {})[0] == 10
    lost, br = report.messages_summary({'measurement_gaps': 3, 'status': {}}, {})
    assert lost == 3 and 'note' in br


def test_the_launchers_last_count_stands_where_the_recording_missed_the_identifiers_last():
    # the recorder, starved at the stop, has the identifier at 19,660 of 22,040 samples; the
    # launcher's monitor took its last status at 22,040 (the stream drained): nothing lost. A
    # lower count of the launcher's does not hide the recording's higher one, and a restarted
    # identifier's earlier lives still add up
    rec = {'status': {'identifier': {'samples_received': 19660}}, 'measurement_gaps': 0,
           'measurements_received': 22040}
    assert report.messages_summary(rec, None)[0] == 2380
    assert report.messages_summary(rec, None, 22040)[0] == 0
    assert report.messages_summary(rec, None, 100)[0] == 2380
    assert report.messages_summary(rec, None, None)[0] == 2380
    rec['identifier_lives'] = [{'last_count': 10000}, {'last_count': 9000}]
    # lives 10,000 + max(9,000 recorded, 19,660 status, 12,040 launcher) = 29,660 > span: 0
    assert report.messages_summary(rec, None, 12040)[0] == 0
    rec['status']['identifier']['samples_received'] = 9000
    assert report.messages_summary(rec, None, 11000)[0] == 22040 - 21000


def test_streamed_record_error_equals_the_whole_array_error(monkeypatch):
    params, msg = _truth_msg()
    meas = _measurements(params)
    force = kwok_current_force(msg, meas['x'], meas['v'], meas['i'])
    whole = report.fit_error(meas['f'], force)
    monkeypatch.setattr(report.recording, 'CHUNK_ROWS', 333)
    assert report.record_error(meas, msg) == pytest.approx(whole, rel=1e-12)


@pytest.mark.slow
def test_streamed_ride_metrics_equal_whole_run_metrics(tmp_path, monkeypatch):
    """Chunked passes (Wk filter state carried over) = the metrics of the whole arrays."""
    from quarter_car_sim.metrics.quarter_car import ride_metrics
    from semi_active_control.iso2631 import wk_filter
    log = _live_log(tmp_path / 'log', controller_offers=True)
    big = report.ride_summary(log, QC)
    monkeypatch.setattr(report.recording, 'CHUNK_ROWS', 377)
    small = report.ride_summary(log, QC)
    for key in ('skyhook', 'passive', 'passive_0a'):
        for m, v in big[key].items():
            assert small[key][m] == pytest.approx(v, rel=1e-9, nan_ok=True), (key, m)
    a = log.read()
    mask = a['t'] >= big['window_s'][0] - 5e-4
    sub = {k: a[k][mask] for k in ('t', 'a_s', 'travel', 'tyre_force', 'damper_force')}
    sub['current_cmd'] = a['i_cmd'][mask]
    ref = ride_metrics(sub, static_load=QuarterCarParams().static_tyre_load)
    ref['rms_body_accel_wk'] = float(np.sqrt(np.mean(wk_filter(a['a_s'], 1e3)[mask] ** 2)))
    for m in ('rms_body_accel_wk', 'rms_body_accel', 'rms_tyre_load_ratio', 'peak_body_accel',
              'rms_suspension_travel', 'mean_current_a', 'n_samples'):
        assert small['skyhook'][m] == pytest.approx(ref[m], rel=1e-9), m
    assert small['passive_trace']['t'].size == small['passive_trace']['a_s'].size > 1000


def test_streamed_delays_and_timing_equal_whole_array_figures(tmp_path, monkeypatch):
    params, msg = _truth_msg()
    meas = _measurements(params)
    log = [(0.0, dict(msg, window_end_s=e, recv_epoch_s=1000.0 + e + 0.05))
           for e in (-1.0, 0.5, 0.9995, 1.0, 2.2, 3.999, 7.0)]
    monkeypatch.setattr(report.recording, 'CHUNK_ROWS', 1000)
    d = report.measurement_to_parameters(meas, log)
    # windows before / after the record are ignored; the rest arrive 50 ms - 2 ms later
    np.testing.assert_allclose(d, [0.048] * 5, atol=1e-9)
    trace = _live_log(tmp_path / 'log', seconds=1.0)
    a = trace.read()
    a['wall'] = np.cumsum(np.where(np.arange(a['t'].size) % 97 == 0, 3e-3, 1e-3))
    fig = report.loop_figures(dict(a, dt=1e-3))
    per = live_loop.timing_stats(np.diff(a['wall']), float(np.median(np.diff(a['wall']))))
    for k in ('n', 'mean_ms', 'p50_ms', 'p99_ms', 'max_ms', 'jitter_max_ms', 'jitter_p99_ms'):
        assert fig['period'][k] == pytest.approx(per[k], rel=1e-9), k
    assert fig['latency']['n'] == a['t'].size and fig['timing_sample_stride'] == 1
    # every 97th period is 3 ms: real time on average is lost, the median step is not
    sim, wall = a['t'][-1] - a['t'][0], a['wall'][-1] - a['wall'][0]
    assert fig['real_time_factor_measured'] == pytest.approx(sim / wall, rel=1e-12)
    assert fig['real_time_factor_measured'] < 0.99
    assert fig['real_time_factor_median'] == pytest.approx(1.0, rel=1e-9)


@pytest.mark.slow
def test_report_passes_keep_memory_bounded(tmp_path):
    """1 M recorded samples (48 MB on disk): the identification figures take a few MB."""
    import tracemalloc
    params, msg = _truth_msg()
    n = 1_000_000
    with ColumnWriter(tmp_path / 'm', ('t', 'x', 'v', 'f', 'i', 'recv_epoch_s'),
                      chunk_rows=50000) as w:
        for k in range(0, n, 50000):
            m = _measurements(params, n=50000, rng=k)
            w.append_block(np.column_stack([m[c] + (k * 1e-3 if c in ('t', 'recv_epoch_s')
                                                    else 0.0)
                                            for c in ('t', 'x', 'v', 'f', 'i', 'recv_epoch_s')]))
    meas = ColumnReader(tmp_path / 'm')
    log = [(1.0, dict(msg, window_end_s=500.0, recv_epoch_s=1500.05))]
    tracemalloc.start()
    ident = report.identification_summary(meas, log, truth=msg, offline_budget_s=0)
    delays = report.measurement_to_parameters(meas, log)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert ident['truth_nrmse_percent'] < 0.1 and ident['nrmse_percent'] < 0.1
    np.testing.assert_allclose(delays, [0.048], atol=1e-6)
    assert peak < 16 * 2 ** 20


def test_restart_figures_from_car_modes_and_identifier_lives():
    """Fail-safe and silence per restart window; samples lost between identifier lives."""
    rec = {'end_epoch_s': 130.0, 'car_modes': [], 'identifier_lives': []}
    # car states every 10 ms: normal to 105 s, fail-safe 105..108, normal to 112, silent to
    # 114 (the car was down), fail-safe 114..115, normal to the end
    for t in np.arange(100.0, 130.0, 0.01):
        if 112.0 < t < 114.0:
            continue
        mode = int(105.0 <= t < 108.0 or 114.0 <= t < 115.0)
        report.recording._mode_runs(rec['car_modes'], float(t), mode)
    # identifier counts every 0.1 s at 1 kHz; killed at 103 s, restarted at 104 s, counting
    # from 0 on; the recorder missed its first counts (they arrive from 106 s on)
    for k in range(300):
        if 30 <= k < 60:
            continue
        t = 100.0 + 0.1 * k
        count = 100 * k if k < 30 else 100 * k - 4500
        report.recording._count_lives(rec['identifier_lives'], float(t), count, starts=(104.0,))
    assert len(rec['identifier_lives']) == 2
    # every sample recorded (1 kHz) but for 500 missing around 120 s (a recorder gap)
    recv = 100.0 + 1e-3 * np.arange(29901)
    meas = {'recv_epoch_s': np.delete(recv, np.arange(20000, 20500))}
    rec['gap_events'] = [(120.5, 500)]
    supervision = {'restarts': [
        {'node': 'mr_damper_identifier', 'death_s': 3.0, 'death_epoch_s': 103.0,
         'restart_s': 4.0, 'restart_epoch_s': 104.0},
        {'node': 'quarter_car_node', 'death_s': 12.0, 'death_epoch_s': 112.0,
         'restart_s': 12.5, 'restart_epoch_s': 112.5}]}
    ident, car = report.restart_figures(supervision, rec, meas)
    assert ident['window_s'] == pytest.approx(9.0)
    assert ident['failsafe_s'] == pytest.approx(3.0, abs=0.02)
    assert ident['no_car_state_s'] == pytest.approx(0.0, abs=0.02)
    # published from its last count (102.9 s) to the car's death (112 s): 9100; counted by the
    # new life by then: 7500; lost: the samples between 102.9 s and its start at 104.5 s
    assert ident['measurements_lost'] == pytest.approx(1600, abs=2)
    assert car['window_s'] == pytest.approx(18.0)
    assert car['no_car_state_s'] == pytest.approx(2.0, abs=0.02)
    assert car['failsafe_s'] == pytest.approx(1.0, abs=0.02)
    assert car['car_normal_at_end'] is True
    assert car['measurements_lost'] == pytest.approx(0, abs=2)   # the gap was counted
    # the restarts never claim more than the total loss; the rest is said apart
    br = {'measurements_lost_to_identifier': 2000}
    report.attribute_losses(br, [ident, car])
    at_restarts = ident['measurements_lost'] + car['measurements_lost']
    assert br == {'measurements_lost_to_identifier': 2000,
                  'measurements_lost_at_restarts': at_restarts,
                  'measurements_lost_not_at_restarts': 2000 - at_restarts}
    br = {'measurements_lost_to_identifier': 100}
    report.attribute_losses(br, [ident])
    assert ident['measurements_lost'] == 100 and br['measurements_lost_not_at_restarts'] == 0


def test_identifier_received_adds_up_its_lives():
    rec = {'status': {'identifier': {'samples_received': 900}},
           'measurements_received': 5000, 'measurement_gaps': 0,
           'identifier_lives': [{'last_count': 3000}, {'last_count': 850}]}
    lost, br = report.messages_summary(rec, {})
    assert br['measurements_received_by_identifier'] == 3900 and lost == 1100
    assert br['identifier_lives'] == 2


@pytest.mark.slow
def test_a_cut_recording_and_a_second_part_make_one_incomplete_report(tmp_path):
    """A killed recorder's part (no footer) and its successor's: read both, marked incomplete."""
    from mr_damper_bringup.recorder import recording_parts, work_file
    params, msg = _truth_msg()
    meas = _measurements(params, n=40000)
    first = {k: v[:30000] for k, v in meas.items()}
    second = {k: v[32000:] for k, v in meas.items()}
    _write_run(tmp_path / 'suite.mcap', first, [(1000.0, dict(msg))], [], msg, _cfg())
    _write_run(tmp_path / 'suite.1.mcap', second, [(1033.0, dict(msg))], [], msg, _cfg(),
               first_index=32000)
    # the first recorder was killed: its file stays in the work folder, without its end
    cut = work_file(tmp_path / 'suite.mcap')
    cut.parent.mkdir()
    raw = (tmp_path / 'suite.mcap').read_bytes()
    cut.write_bytes(raw[:int(0.8 * len(raw))])
    (tmp_path / 'suite.mcap').unlink()
    assert recording_parts(tmp_path / 'suite.mcap') == [(0, cut), (1, tmp_path / 'suite.1.mcap')]
    _live_log(tmp_path / 'quarter_car_log', controller_offers=True, seconds=2.0)
    s = report.make_report(tmp_path, duration_s=40.0, plots=False)
    rec = s['recording']
    assert rec['complete'] is False and [p['complete'] for p in rec['parts']] == [False, True]
    got = rec['parts'][0]['messages']
    assert 0 < got < 30000 + 3 and rec['parts'][1]['messages'] == 8000 + 3
    # every measurement of the complete chunks is there, the gap between the parts is counted
    n0 = s['messages']['measurements_received_by_recorder'] - 8000
    assert 0 < n0 < 30000
    assert s['messages']['measurement_gaps_at_recorder'] == 32000 - n0
    assert 'truncated' in rec['parts'][0]['error'] or 'EndOfFile' in rec['parts'][0]['error']
    assert 'recording INCOMPLETE' in report.format_summary(s)


def test_no_recording_gives_a_summary_from_the_statuses(tmp_path):
    _live_log(tmp_path / 'quarter_car_log', controller_offers=True, seconds=2.0)
    status = {'identifier': {'samples_received': 700}, 'rig': {'samples_published': 700},
              'quarter_car': {'mode': 'normal', 'failsafe_s': 1.0}}
    s = report.make_report(tmp_path, duration_s=3.0, fallback={'config': _cfg(),
                                                               'status': status})
    assert s['recording']['complete'] is False and s['recording']['parts'] == []
    assert 'statuses' in s['recording']['note']
    assert s['messages']['measurements_received_by_identifier'] == 700
    assert json.loads((tmp_path / 'summary.json').read_text()) == s
    assert not list(tmp_path.glob('*.png'))


def _batch(t, x, v, f, i, *, first_index, sequence=0):
    """Return a ``DamperSamples`` batch as the rig publishes it (no checks of the values)."""
    from mr_damper_common import messages as mm
    return mm.samples_to_msg(t, x, v, f, i, sequence=sequence, first_index=first_index,
                             sample_period_s=1e-3)


@pytest.mark.slow
def test_no_recorded_message_breaks_the_report(tmp_path):
    """
    Bad recorded messages are counted by reason and skipped; the summary is written.

    Each of these raised (``ModelError``, ``TypeError``) or wrote a false figure before: a NaN
    or infinite sample, a NaN parameter in a valid set, a batch whose arrays differ in length,
    samples stamped out of order, a batch whose ``first_index`` jumps by 2**64 - 1.
    """
    from mr_damper_interfaces.msg import DamperSamples
    params, msg = _truth_msg()
    meas = _measurements(params, n=3000)
    n = meas['t'].size
    bad_t = 1000.0 + 3.5          # receive times of the bad messages: after the good ones
    # the good samples among them are the model's force (the figures below are its noise)
    good = float(kwok_current_force(dict(params, i_ref_a=2.0), 0.0, 0.1, 0.5)[0])
    nan_sample = _batch([3.001, 3.002], [0.0, float('nan')], [0.1, 0.1], [good, good],
                        [0.5, 0.5], first_index=n)
    inf_sample = _batch([3.003], [0.0], [0.1], [float('inf')], [0.5], first_index=n + 2)
    short = _batch([3.004, 3.005], [0.0, 0.0], [0.1, 0.1], [1.0, 1.0], [0.5, 0.5],
                   first_index=n + 3)
    short.f_n = [1.0]                                    # arrays of different lengths
    late = _batch([1.0], [0.0], [0.1], [1.0], [0.5], first_index=n + 5)    # before the newest
    absurd = _batch([3.006], [0.0], [0.1], [good], [0.5], first_index=2 ** 64 - 1)
    empty = DamperSamples()
    nan_set = dict(msg, c0=float('nan'), window_end_s=3.0)
    extra = [(bad_t, 'measurement', m) for m in (nan_sample, inf_sample, short, late, absurd,
                                                 empty)]
    from mr_damper_common import messages as mm
    extra.append((bad_t + 0.1, 'parameters', mm.kwok_parameters_msg(nan_set)))
    _write_run(tmp_path / 'suite.mcap', meas, [(1000.5, dict(msg))], [], msg, _cfg(),
               extra=extra)
    s = report.make_report(tmp_path, duration_s=4.0, plots=True)
    assert json.loads((tmp_path / 'summary.json').read_text()) == s
    bad = s['recording']['bad_messages']
    assert bad['measurement'] == {'nonfinite_samples': 2, 'out_of_order_samples': 1,
                                  'layout': 1, 'undecodable': 1}
    assert bad['parameters'] == {'nonfinite_parameters': 1}
    # the good samples and the good set make the figures; the NaN set is no update
    ident = s['identification']
    assert ident['updates'] == 1 and ident['valid_updates'] == 1
    assert ident['rmse_n'] == pytest.approx(1.0, rel=0.1)
    assert s['messages']['measurements_received_by_recorder'] == n + 2   # 3.001 and 3.006
    # the absurd index jump is a restart of the stream, not 1.8e19 samples lost
    assert s['messages']['measurement_gaps_at_recorder'] == 0
    assert 'bad recorded messages' in report.format_summary(s)


def test_a_recording_with_empty_topics_makes_a_summary(tmp_path):
    """No measurement and no parameter message at all: figures are None, nothing raises."""
    _, msg = _truth_msg()
    _write_run(tmp_path / 'suite.mcap', {k: np.zeros(0) for k in 'txvfi'} |
               {'recv_epoch_s': np.zeros(0)}, [], [], msg, _cfg())
    s = report.make_report(tmp_path, duration_s=1.0, plots=True)
    assert s['identification']['updates'] == 0 and s['identification']['parameters'] is None
    assert s['recording']['bad_messages'] == {}
    assert json.loads((tmp_path / 'summary.json').read_text()) == s
