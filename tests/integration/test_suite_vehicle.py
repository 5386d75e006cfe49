"""
``mr-damper-suite --config vehicle``: the vehicle computer against the car on a CAN bus.

Order and counts only: the suite runs until the lifecycle manager has brought the chain up and
the bridge has answered 500 sensor cycles (then it is stopped with SIGINT, as Ctrl-C); every
node exits 0; the summary's ``vehicle`` section has its keys, the cycles it counted, the
bridge's answers among them, the chain's transitions (two per node), and the body's a_v with
the offline references on the same window. Both layouts: ``loop`` (the default, one
``vehicle_computer``) and ``nodes`` (bridge, estimator and controller, each its own process).
"""
import json
import os
import re

import pytest

from conftest import VENV_BIN
from integration.ros_helpers import run_until_ready
from script_helpers import load_script

pytestmark = [pytest.mark.integration, pytest.mark.slow]

KEYS = ('control_cycles', 'answered_fraction', 'deadline_misses', 'driver_command_timeouts',
        'sensor_to_command_s', 'frames_lost', 'a_v', 'a_v_passive', 'a_v_lockstep')


def run_vehicle(out, answered, *flags):
    """
    Run ``--config vehicle`` until its chain is up and the bridge answered ``answered`` cycles.

    Then stopped with SIGINT (Ctrl-C); asserts it exited 0 and returns its summary.
    """
    env = dict(os.environ)
    cmd = [str(VENV_BIN / 'mr-damper-suite'), '--config', 'vehicle', *flags, '--duration', '0',
           '--out', str(out), '--progress-s', '1', '--domain-id', env['ROS_DOMAIN_ID'],
           '--no-plots', '--set', 'lifecycle_manager.heartbeat_timeout_s=10.0']

    def ready(line):
        m = re.search(r'chain (?:computer active|bridge active,estimator active,controller '
                      r'active) \| cycles \d+ answered (\d+)', line)
        return m is not None and int(m.group(1)) >= answered

    ok, returncode, seen, rest = run_until_ready(cmd, env, ready, guard_s=600.0)
    assert ok, ''.join(seen[-20:])
    assert returncode == 0, ''.join(seen[-10:]) + rest[-3000:]
    return json.loads((out / 'summary.json').read_text())


@pytest.mark.parametrize('layout, chain', [
    ('loop', ('vehicle_computer',)),
    ('nodes', ('vehicle_bridge', 'vehicle_estimator', 'vehicle_controller'))])
def test_vehicle_suite_chain_comes_up_and_reports(tmp_path, layout, chain):
    out = tmp_path / 'vehicle'
    summary = run_vehicle(out, 500, '--vehicle-layout', layout)
    codes = summary['exit_codes']
    assert set(codes) == {'mr_damper_record', 'full_car_node', 'lifecycle_manager', *chain}
    assert all(code == 0 for code in codes.values()), codes
    v = summary['vehicle']
    assert set(KEYS) <= set(v), sorted(v)
    assert v['control_cycles'] >= 500 and v['chain']['transitions'] >= 2 * len(chain), v
    # the chain came up, its start-up timed (the manager's clock: a figure, not asserted);
    # again only after a node it saw die (a heartbeat gap on a loaded machine)
    assert 1 <= v['chain']['ups'] <= 1 + v['chain']['deaths'], v['chain']
    assert v['chain']['first_up_s'] > 0, v['chain']
    assert 0.0 <= v['answered_fraction'] <= 1.0
    assert v['sensor_to_command_s']['n'] >= 500
    cpu = v['reader_cpu_per_cycle_s']      # the bus reader's CPU time, every cycle counted
    assert 0 < cpu['p50'] <= cpu['max'] and 0 < cpu['mean'] <= cpu['max'], cpu
    assert v['deadline_misses'] <= v['deadline']['cycles']
    assert isinstance(v['frames_lost']['total'], int)
    assert v['a_v'] > 0 and v['a_v_passive'] > 0 and v['a_v_lockstep'] > 0, v
    assert (out / 'full_car_body.npz').is_file()
    # the bench's reading of the recorded statuses: the controller's counts, never falling
    counts = load_script('bench/hypervisor_steal.py').deadline_counts(out / 'suite.mcap')
    assert len(counts) >= 2, counts
    assert all(a[0] < b[0] and a[1] <= b[1] and a[2] <= b[2] for a, b in zip(counts, counts[1:]))
    assert 0 < counts[-1][1] <= v['deadline']['cycles'] and counts[-1][2] <= v['deadline_misses']
    if layout == 'loop':         # the loop's execution times by stage, every cycle counted
        ex = v['execution_s']
        assert ex['estimate']['n'] >= ex['control']['n'] >= ex['send']['n'] >= 500, ex
        assert all(0 < ex[s]['p50_s'] <= ex[s]['max_s'] for s in ex), ex
        # every cycle's reception counted (the estimator's steps), the queued ones among them
        assert v['reception_s']['n'] == ex['estimate']['n'], v['reception_s']
        assert 0 <= v['cycles_queued'] <= ex['estimate']['n']
        # the loop's misses named by cause; the queued ones among the cycles queued
        assert set(v['loop_misses']) == {'bunched', 'queued', 'reached_late', 'slow'}
        assert v['loop_misses']['bunched'] + v['loop_misses']['queued'] <= v['cycles_queued']
    else:
        assert 'execution_s' not in v and 'reception_s' not in v


def test_vehicle_suite_runs_the_preview_law_on_the_cars_look_ahead_frames(tmp_path):
    """
    ``--config vehicle --preview``: the LQ preview law in the vehicle controller (issue 36).

    The car publishes its look-ahead sensor's frames stamped on the vehicle's clock (the bus's:
    the sensor cycles' stamps); the controller's preview input takes them at their cycle and the
    law previews, its cycles counted previewed or fallback.
    """
    summary = run_vehicle(tmp_path / 'vehicle_preview', 1000, '--preview')
    assert all(code == 0 for code in summary['exit_codes'].values()), summary['exit_codes']
    pv = summary['vehicle']['preview']
    law, inp, sensor = pv['law'], pv['input'], pv['sensor']
    assert sensor['delivered'] > 0 and inp['messages']['received'] > 0, pv
    assert law['previewed_steps'] > 0, pv
    assert law['steps'] == law['previewed_steps'] + law['fallback_steps'], pv
    assert pv['first_previewed_t'] <= pv['last_previewed_t'], pv
