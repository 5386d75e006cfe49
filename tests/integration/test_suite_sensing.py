"""
The suite on estimated states: ``mr-damper-suite --sensing vehicle`` (docs/sensing.md).

- the configuration alone (no nodes): the estimator starts before the controller and the car,
  takes the car's rate, fail-safe current, timeout and car parameters and is clocked by the
  readings; the car publishes its sensors; the recorder takes the sensor topics and the true
  state;
- the whole run (real node processes, the car in lock-step with estimator and controller, until
  the car drove 9 s) with a body accelerometer dropout injected mid-run (1 s of car time): exit
  0, every node exited 0, the estimator took every reading and published, the dropout shows as
  a counted fail-safe named ``dropout_body_accel`` while the lost readings arrive, the controller
  refused those states (its safe current), and the estimate is valid again afterwards. Order of
  events and counts only, no wall-clock thresholds.
"""
import json

import pytest

from mr_damper_bringup.config import (CTRL, EST, external_controller, IDENT, node_params, QC,
                                      recorder_arguments, resolve_config, RIG, suite_nodes)
from mr_damper_bringup.launcher import parse_args
from mr_damper_bringup.processes import Suite
from mr_damper_bringup.topics import SENSING_TOPICS, topic_table

DROPOUT = (6.0, 1.0)        # start, length [s of car time]


def test_sensing_vehicle_config_wires_car_estimator_controller(tmp_path):
    cfg = resolve_config(parse_args(['--sensing', 'vehicle', '--out', str(tmp_path),
                                     '--set', 'quarter_car_node.safe_current_a=0.25',
                                     '--set', 'quarter_car_node.m_s=320.0']), tmp_path)
    assert list(suite_nodes(cfg)) == [RIG, IDENT, EST, CTRL, QC]
    assert external_controller(cfg)
    car, est = node_params(cfg, QC), node_params(cfg, EST)
    assert car['sensing'] == 'vehicle' and car['controller'] == 'external'
    assert car['lockstep'] is True          # the default: an estimate for every car step
    real = resolve_config(parse_args(['--sensing', 'vehicle', '--out', str(tmp_path), '--set',
                                      'quarter_car_node.lockstep=false']), tmp_path)
    assert node_params(real, QC)['lockstep'] is False
    assert est['clock'] == 'readings'
    for name in ('rate_hz', 'safe_current_a', 'param_timeout_s', 'm_s', 'road_class'):
        assert est[name] == car[name], name
    assert est['safe_current_a'] == 0.25 and est['m_s'] == 320.0
    assert node_params(cfg, CTRL)['controller'] == 'skyhook'
    assert recorder_arguments(cfg) == ['--sensing']
    assert set(topic_table(sensing=True)) >= set(SENSING_TOPICS)
    assert not set(topic_table()) & set(SENSING_TOPICS)
    # the estimator is stopped with the others (after the controller, before the rig)
    assert EST in Suite.stop.__defaults__[0]
    ideal = resolve_config(parse_args(['--out', str(tmp_path)]), tmp_path)
    assert EST not in suite_nodes(ideal) and recorder_arguments(ideal) == []


@pytest.mark.integration
@pytest.mark.slow
def test_suite_on_estimated_states_counts_a_sensor_dropout(tmp_path):
    """mr-damper-suite --sensing vehicle end to end (lock-step), a dropout injected mid-run."""
    import os
    import re
    from conftest import VENV_BIN
    from integration.ros_helpers import assert_reached_control, run_until_ready
    out = tmp_path / 'suite'
    env = dict(os.environ)
    cmd = [str(VENV_BIN / 'mr-damper-suite'), '--sensing', 'vehicle', '--duration', '0',
           '--out', str(out), '--progress-s', '1', '--no-plots', '--domain-id',
           env['ROS_DOMAIN_ID'],
           '--set', f'quarter_car_node.sensor_dropout_start_s={DROPOUT[0]}',
           '--set', f'quarter_car_node.sensor_dropout_s={DROPOUT[1]}']
    end_s = DROPOUT[0] + DROPOUT[1] + 2.0

    def ready(line):
        # car time, not wall time: stop 2 s of car time after the dropout window
        t_car = re.search(r't_sim (-?[\d.]+) s', line)
        return t_car is not None and float(t_car.group(1)) >= end_s

    ok, returncode, seen, rest = run_until_ready(cmd, env, ready, out=out)
    assert ok, ''.join(seen[-20:])
    assert returncode == 0, ''.join(seen[-10:]) + rest[-3000:]
    stdout = ''.join(seen) + rest
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['exit_codes'] and set(summary['exit_codes'].values()) == {0}, summary
    assert set(summary['exit_codes']) >= {RIG, IDENT, EST, CTRL, QC}
    recorded = summary['recording']['messages']
    for key in ('body_imu', 'suspension_position', 'true_state', 'car_state',
                'current_command'):
        assert recorded.get(key, 0) > 0, (key, recorded)
    assert summary['recording']['bad_messages'] == {}     # nothing the report left out
    s = summary['sensing']
    assert 'sensing vehicle: estimator' in stdout
    # the estimator published (one estimate per reading it took) and the controller answered
    assert s['estimator']['steps'] > 0 and s['estimates'] > 0 and s['valid_estimates'] > 0
    assert s['controller']['commands'] > s['controller']['commands_normal'] > 0
    assert_reached_control(summary)
    # lock-step: every reading taken (none lost, none predicted through), a filter step and an
    # estimate for each (the estimator's last status, one snapshot)
    est = s['estimator']
    assert est['stale_ticks'] == 0 and est['rebases'] == 0, est
    assert est['readings_lost'] == {'body_accel': 0, 'travel': 0}, est
    assert est['predict_steps'] == 0, est
    assert est['readings_received']['travel'] == est['steps'], est

    # the injected dropout: every body accelerometer sample of the window lost (1 kHz)
    sensors = s['car_sensors']
    assert sensors['dropout_window_s'] == list(DROPOUT)
    assert sensors['sensors']['body_accel']['lost'] >= 999
    first_nan, last_nan, n_nan = s['dropout_seen']
    assert n_nan > 0 and first_nan <= last_nan
    # order of events: the estimate turns invalid, named, while the lost readings arrive, and
    # is valid again after the window
    runs = s['estimate_runs']
    hit = [k for k, (reason, n, t0, t1) in enumerate(runs)
           if reason == 'dropout_body_accel' and first_nan <= t0 <= last_nan]
    assert hit, (runs, s['dropout_seen'])
    assert any(reason == 'ok' for reason, *_ in runs[hit[0] + 1:]), runs
    # counted: the estimator's entry by reason, the controller's safe-current answers
    assert s['estimator']['invalid_entries'].get('dropout_body_accel', 0) >= 1
    assert s['controller']['state_rejected']['non_finite'] >= 1
    assert s['dropout_failsafe'] is True
    # the estimate against the car's true state (paired by stamps): travel, which the position
    # sensor reads to 0.05 mm, within 1 mm RMS
    err = s['estimation_error']
    assert err['aligned_by'] == 'stamps' and err['pairs'] > 0
    assert err['rms_error']['travel'] < 1e-3
