"""
The closed loop over ROS 2: quarter-car node, rig, identifier and the suite launcher.

Real nodes in separate processes (console scripts of the venv), LOCALHOST discovery and the
private domain of tests/conftest.py. Four runs, about 3 min together on 2 shared cores at load 13:

- the quarter-car node alone, fed by a test publisher: no model -> fail-safe at the safe current;
  a valid set -> normal; invalid, non-finite, out-of-range, narrow-range and zero ``i_ref_a``
  sets are refused and counted by reason, each dropping to fail-safe; commands stay in the coil
  range;
- the whole suite through ``mr-damper-suite`` (twice real time, stopped once the car drove 10 s
  of car time on its model): the car leaves fail-safe after the first valid parameters (the
  summary's ``control`` section), its currents stay in the coil range, the live skyhook beats
  the passive damper on Wk-weighted RMS body acceleration on the same road and seed, exit
  status 0;
- the suite's processes with the identifier killed mid-run: the car goes fail-safe (stale) after
  the timeout and keeps running; the identifier restarted, the loop recovers;
- a node that dies at every start ends the launcher's run with exit status 1.
"""
import json
import math
import os
import signal
import time

import numpy as np
import pytest

from conftest import VENV_BIN
from integration.ros_helpers import (assert_reached_control, end_suite_nodes, fault_test_suite,
                                     NodeProcess, run_suite_until_controlled)
from kwok_messages import thesis_parameter_values
from mr_damper_bringup.config import IDENT, QC, RIG
from mr_damper_bringup.processes import CLEAN_EXIT
from mr_damper_common.recording.columnlog import ColumnReader
from process_helpers import run

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SAFE_A = 0.5


def test_quarter_car_refuses_bad_parameters(listener, tmp_path):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common.messages import kwok_parameters_msg
    from std_msgs.msg import Float64
    topic = '/h5test/mr_damper/kwok_parameters'
    params = {'safe_current_a': SAFE_A, 'param_timeout_s': 30.0, 'diagnostics_period_s': 0.05,
              'road_duration_s': 60.0}
    diag = listener.diagnostics()
    name = 'h5test/quarter_car_node'
    commands = listener.subscribe('/h5test/mr_damper/current_command', Float64, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    pub = listener.publisher(topic, KwokParameters, QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    with NodeProcess('quarter_car_node', params=params, namespace='h5test') as qc:
        assert listener.wait_for(lambda: diag.count(name) and pub.get_subscription_count() > 0,
                                 20, procs=[qc]), qc.output()
        st = diag.values(name)
        assert st['mode'] == 'failsafe' and st['reason'] == 'no_parameters_yet'
        assert st['current_a'] == SAFE_A
        assert 'fail-safe: no identified parameters yet' in diag.latest(name).message

        def send(values, expect_mode, counter=None, count=None):
            n = diag.count(name)
            pub.publish(values if isinstance(values, KwokParameters)
                        else kwok_parameters_msg(values))

            def seen():
                if diag.count(name) <= n + 1:
                    return False
                s = diag.values(name)
                ok = s['mode'] == expect_mode
                if counter:
                    ok = ok and s['params_rejected'][counter] == count
                return ok
            assert listener.wait_for(seen, 10, procs=[qc]), (values, diag.values(name))
            return diag.values(name)

        good = thesis_parameter_values()
        st = send(good, 'normal')
        assert st['params_accepted'] == 1 and st['reason'] == 'ok'
        bad_sets = [
            ('invalid_flag', dict(good, valid=0.0)),
            ('non_finite', dict(good, beta0=math.nan)),
            ('out_of_bounds', dict(good, c1=-100.0)),
            ('narrow_current_range', dict(good, current_min_a=0.0, current_max_a=0.0)),
            ('bad_current_range', dict(good, current_max_a=7.0)),
        ]
        for reason, values in bad_sets:
            st = send(values, 'failsafe', reason, 1)
            assert st['reason'] == reason
            assert f'parameters refused ({reason})' in diag.latest(name).message
            send(good, 'normal')
        no_i_ref = KwokParameters()              # i_ref_a 0: decode refuses, by its reason
        st = send(no_i_ref, 'failsafe', 'bad_i_ref', 1)
        st = send(good, 'normal')
        assert st['params_accepted'] == 2 + len(bad_sets)
        assert sum(st['params_rejected'].values()) == len(bad_sets) + 1
        assert st['failsafe_entries'] == len(bad_sets) + 1
        assert qc.alive()
    cmds = np.array([m.data for _, m in commands])
    assert cmds.size > 1000
    assert np.all((cmds >= 0.0) & (cmds <= 2.0))
    assert np.any(cmds == SAFE_A) and np.any(cmds != SAFE_A)


def test_full_suite_short_run(tmp_path):
    """mr-damper-suite end to end, twice real time: fail-safe left, limits kept, skyhook wins."""
    out = tmp_path / 'suite'
    # no wall-clock duration: stopped once the car drove 10 s of car time on its model
    summary, stdout = run_suite_until_controlled(
        out, '--rate-factor', '2.0',
        # at twice real time on a busy machine a fit can stall > 1 s: this test is about
        # leaving fail-safe and the ride, the timeout itself is tested below
        '--set', 'quarter_car_node.param_timeout_s=2.0',
        controlled=lambda line: 'quarter car normal' in line, car_s=10.0, plots=True,
        # hang guard only: at load 10 (a CPU burner beside a CI run) the stop and the report
        # with its plots outlasted 300 s
        guard_s=900.0)
    assert 'MR damper suite summary' in stdout
    for key in ('duration_s', 'identification', 'ride', 'failsafe_s', 'messages_lost'):
        assert key in summary
    assert_reached_control(summary)
    assert summary['control']['samples_lost'] == 0
    # the ride's window starts at the law's first step on a model, or at t = 0 when that came
    # while the car was still settling (t < 0: a model before the road, on a loaded machine)
    assert summary['ride']['window_s'][0] == max(0.0, summary['control']['first_normal_t_sim'])
    ident = summary['identification']
    # counts and order only (a starved machine makes fewer updates, never wrong ones)
    assert ident['updates'] >= ident['valid_updates'] > 0
    assert ident['first_valid_s'] is not None
    assert ident['nrmse_percent'] < 10.0
    log = ColumnReader(out / 'quarter_car_log').read()
    mode = log['mode']
    # starts in fail-safe at the safe current, then normal once a model is accepted
    assert mode[0] == 0.0 and log['i_cmd'][0] == SAFE_A
    first = int(np.argmax(mode > 0.5))
    assert first > 0 and mode[first:].any()
    assert np.all((log['i_cmd'] >= 0.0) & (log['i_cmd'] <= 2.0))
    assert np.all(log['i_cmd'][:first] == SAFE_A)
    # whenever the car is in fail-safe (also later, parameters gone stale on a starved machine)
    # it commands the safe current, never a guess
    assert np.all(log['i_cmd'][mode < 0.5] == SAFE_A)
    ride = summary['ride']
    assert ride['window_s'][1] > ride['window_s'][0]                # sim time with a model
    # 10 s of car time on the model at least (the stop's condition); the comfort figure itself
    # is the benches'; on 10 s or more skyhook beats passive
    assert ride['window_s'][1] - ride['window_s'][0] >= 10.0, ride['window_s']
    assert ride['skyhook']['rms_body_accel_wk'] < ride['passive']['rms_body_accel_wk']
    assert summary['messages_lost'] == 0
    # one recording of every topic; the recorder took every sample the identifier took
    assert (out / 'suite.mcap').is_file() and not (out / 'suite.recording').exists()
    recorded = summary['recording']['messages']
    for key in ('measurement', 'parameters', 'truth_spencer', 'current_command',
                'samples_received', 'car_joint_state', 'car_state', 'diagnostics'):
        assert recorded.get(key, 0) > 0, (key, recorded)
    # every node's /diagnostics status is in the recording
    statuses = summary['recording']['statuses']
    assert all(statuses.get(n, 0) > 0 for n in ('rig', 'identifier', 'quarter_car', 'recorder')), \
        statuses
    assert summary['recording']['bad_messages'] == {}     # nothing the report left out
    # the settings of the report: what each node ran with, asked from its parameter services
    assert set(summary['recording']['node_parameters']) >= {'mr_damper_rig',
                                                            'mr_damper_identifier',
                                                            'quarter_car_node'}
    msgs = summary['messages']
    assert msgs['measurement_gaps_at_recorder'] == 0
    assert (msgs['measurements_received_by_recorder']
            == msgs['measurements_received_by_identifier'])
    # the node's fail-safe time is the wall time of its fail-safe steps
    dw = np.diff(log['wall'])
    assert summary['failsafe_s'] == pytest.approx(dw[mode[:-1] < 0.5].sum(), abs=0.3)
    assert summary['failsafe_s'] >= log['wall'][first] - log['wall'][0] - 0.3
    for png in ('hysteresis.png', 'convergence.png', 'ride.png'):
        assert (out / png).stat().st_size > 10000


def test_identifier_killed_then_restarted(listener, tmp_path):
    suite = fault_test_suite(tmp_path)
    diag = listener.diagnostics()

    def car():
        return diag.values('quarter_car_node')
    try:
        suite.start_all()

        def mode(expected):
            def check():
                return car().get('mode') == expected
            return check
        assert listener.wait_for(mode('normal'), 40), \
            (car(), suite.log_tail(IDENT), suite.log_tail(RIG))
        time.sleep(1.0)
        suite.kill(IDENT, signal.SIGKILL)
        # order of events, not durations: stale after the timeout, the car keeps stepping
        assert listener.wait_for(mode('failsafe'), 60), car()
        st = car()
        # (a set the car's starved executor takes after the timeout is refused as received
        # stale: no set of the dead identifier brings its model back)
        assert st['reason'] in ('stale', 'stale_on_arrival'), st
        steps = st['steps']
        assert listener.wait_for(lambda: car()['steps'] > steps + 500, 60)
        st = car()
        assert suite.alive(QC) and st['mode'] == 'failsafe'
        assert st['current_a'] == SAFE_A
        suite.start(IDENT)                      # restarts from its saved parameter file
        # hang guard only: until the middleware drops the killed reader (its participant's
        # lease, about 20 s) the rig's reliable writer keeps filling on it and is replaced every
        # few seconds, so the new identifier's windows have gaps; it needs fresh sets over the
        # whole current range after that (seen in CI: still narrow-range 30 s after the kill)
        assert listener.wait_for(mode('normal'), 120), \
            (car(), suite.log_tail(IDENT))
        assert suite.poll() == {}
    finally:
        codes = suite.stop()
    assert codes[QC] in CLEAN_EXIT, suite.log_tail(QC)


def test_launcher_exits_non_zero_when_a_node_dies(tmp_path):
    """A node that dies at every start (the car on an unknown road class) ends the run: exit 1."""
    out = tmp_path / 'dead'
    # --duration 0: run until stopped, so only noticing the death ends the run (the timeout
    # below is a hang guard)
    cmd = [str(VENV_BIN / 'mr-damper-suite'), '--duration', '0',
           '--out', str(out), '--no-plots', '--set', 'quarter_car_node.road_class=Z',
           '--domain-id', os.environ['ROS_DOMAIN_ID'], '--max-restarts', '2',
           '--restart-backoff-s', '0.1']
    try:
        proc = run(cmd, 120)
    finally:
        left = end_suite_nodes(out)
    assert not left, f'nodes outlived the launcher: {left}'
    assert proc.returncode == 1, proc.stdout + proc.stderr
    # restarted twice (the whole stderr on a failure: ci58 once counted 2, cause not seen)
    assert proc.stderr.count('quarter_car_node died (exit 2)') == 3, proc.stderr
    assert proc.stderr.count('restarted quarter_car_node') == 2
    assert 'quarter_car_node died 3 times within 60 s' in proc.stderr
    assert 'road' in proc.stderr.lower()              # its one-line error is shown
    sup = json.loads((out / 'restarts.json').read_text())
    assert [r['exit_code'] for r in sup['restarts']] == [2, 2]
    assert sup['gave_up']['node'] == 'quarter_car_node' and sup['gave_up']['exit_code'] == 2
