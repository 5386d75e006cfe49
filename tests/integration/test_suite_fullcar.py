"""
``mr-damper-suite --config full-car``: four rig / identifier pairs and the 7-DOF full-car node.

Checks order and counts only: the suite runs until every corner of the car is on its own
identifier's model (then it is stopped with SIGINT, as Ctrl-C), every node exits 0, each of the
four identifiers produced valid sets and received every sample its rig published, the car
accepted parameters at every corner, the car's corner states and commands are recorded under
the corners' namespaces, and the summary has its ``full_car`` section.
"""
import json
import os
import re

import pytest

from conftest import VENV_BIN
from integration.ros_helpers import assert_reached_control, run_until_ready

pytestmark = [pytest.mark.integration, pytest.mark.slow]

CORNERS = ('fl', 'fr', 'rl', 'rr')


def test_full_car_suite_runs_four_corners_and_the_car(tmp_path):
    from rosbags.highlevel import AnyReader
    out = tmp_path / 'full_car'
    env = dict(os.environ)
    # no wall-clock duration: stop once the car drove 2 s (simulated) on four identified models
    cmd = [str(VENV_BIN / 'mr-damper-suite'), '--config', 'full-car', '--duration', '0',
           '--out', str(out), '--progress-s', '1', '--domain-id', env['ROS_DOMAIN_ID'],
           '--no-plots', '--set', 'full_car_node.param_timeout_s=5.0']
    t_normal = None

    def ready(line):
        nonlocal t_normal
        modes = dict(re.findall(r'(fl|fr|rl|rr): \d+ samples, [1-9]\d* valid, car (\w+)',
                                line))
        t_car = re.search(r'car t (-?[\d.]+) s', line)
        if t_car is None:
            return False
        if t_normal is None and all(modes.get(c) == 'normal' for c in CORNERS):
            t_normal = float(t_car.group(1))           # simulated time, not wall time
        # then let the car drive 2 s of simulated time on its four models
        return t_normal is not None and float(t_car.group(1)) >= t_normal + 2.0

    ok, returncode, seen, rest = run_until_ready(cmd, env, ready, out=out)
    assert ok, ''.join(seen[-20:])
    assert returncode == 0, ''.join(seen[-10:]) + rest[-3000:]
    summary = json.loads((out / 'summary.json').read_text())
    codes = summary['exit_codes']
    assert set(codes) == ({'full_car_node', 'mr_damper_record'}
                          | {f'{c}.{n}' for c in CORNERS
                             for n in ('mr_damper_rig', 'mr_damper_identifier')}), codes
    assert all(code == 0 for code in codes.values()), codes
    for c in CORNERS:
        d = summary['corners'][c]
        assert d['samples_recorded'] > 1000 and d['samples_lost'] == 0, (c, d)
        assert d['windows_valid'] > 0, (c, d)
    car = summary['full_car']
    assert car['controller'] == 'modal-skyhook' and car['steps'] > 0, car
    for c in CORNERS:
        d = car['corners'][c]
        assert d['params_accepted'] > 0 and d['samples_lost'] == 0, (c, d)
        assert d['first_normal_t_sim'] is not None, (c, d)
    assert_reached_control(summary, units=CORNERS)
    # ISO 2631-1 of the live body and of the passive car on the same road, same window
    assert car['live']['duration_s'] == pytest.approx(car['passive']['duration_s'], rel=1e-6)
    for key in ('live', 'passive'):
        assert car[key]['a_v'] >= car[key]['a_wz'] > 0, car[key]
    assert car['iso2631']['a_v'] > 0
    assert (out / 'full_car_body.npz').is_file()
    with AnyReader([out / 'suite.mcap']) as bag:
        counts = {}
        for conn in bag.connections:
            counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount
    for c in CORNERS:
        for topic in ('quarter_car/car_state', 'mr_damper/current_command',
                      'mr_damper/kwok_parameters', 'mr_damper/measurement'):
            assert counts.get(f'/{c}/{topic}', 0) > 0, (c, topic, counts)


def test_full_car_suite_with_the_external_controller(tmp_path):
    """``--external-controller``: the law in full_car_controller_node, the car the plant."""
    out = tmp_path / 'full_car_ext'
    env = dict(os.environ)
    cmd = [str(VENV_BIN / 'mr-damper-suite'), '--config', 'full-car', '--duration', '0',
           '--out', str(out), '--progress-s', '1', '--domain-id', env['ROS_DOMAIN_ID'],
           '--no-plots', '--external-controller', '--set', 'full_car_node.param_timeout_s=5.0']

    def ready(line):
        # stop once the controller has commanded every corner on its own model (a corner's
        # supervisor taking a set comes before its first command on it: wait for the command)
        return re.search(r'on models 4/4', line) is not None

    ok, returncode, seen, rest = run_until_ready(cmd, env, ready, out=out)
    assert ok, ''.join(seen[-20:])
    assert returncode == 0, ''.join(seen[-10:]) + rest[-3000:]
    summary = json.loads((out / 'summary.json').read_text())
    codes = summary['exit_codes']
    assert {'full_car_node', 'full_car_controller'} <= set(codes), codes
    assert all(code == 0 for code in codes.values()), codes
    car = summary['full_car']
    assert car['controller'] == 'modal-skyhook', car
    ext = car['external_controller']
    assert ext['sets'] > 0 and set(ext['car_command_timeouts']) == set(CORNERS), ext
    for c in CORNERS:
        d = car['corners'][c]
        assert d['params_accepted'] > 0 and d['first_normal_t_sim'] is not None, (c, d)
        assert summary['corners'][c]['samples_lost'] == 0, (c, summary['corners'][c])
    assert_reached_control(summary, units=CORNERS)
