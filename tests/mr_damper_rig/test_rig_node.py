"""
In-process tests of the rig node: dynamic parameters reach the core, the rest are refused.

The node is built in the test process (its own rclpy context) and its callbacks are called
directly: ``set_parameters`` on a dynamic parameter changes the pacer, the current limiter or
the displacement guard; a read-only one, an out-of-range one and one that does not apply to the
node's mode are refused with a reason and change nothing. Its tick publishes the samples due
with ``/clock`` and the status values carry the counters.
"""
import math

import numpy as np
import pytest

from conftest import QUIROZ_DIR
from ros_context import ros_context

QUIROZ = QUIROZ_DIR / 'quiroz_sine_5mm3Hz_0p5A.csv.gz'


@pytest.fixture
def make_node():
    from rclpy.parameter import Parameter
    from mr_damper_rig.rig_node import RigNode
    made = []
    with ros_context(made) as ctx:
        def make(**params):
            node = RigNode(context=ctx, parameter_overrides=[
                Parameter(k, value=v) for k, v in params.items()])
            made.append(node)
            return node
        yield make


def _set(node, name, value):
    from rclpy.parameter import Parameter
    return node.set_parameters([Parameter(name, value=value)])[0]


def test_rate_factor_changes_the_pacer_and_refusals_give_a_reason(make_node):
    node = make_node(mode='csv', file=str(QUIROZ), rate_factor=2.0)
    assert _set(node, 'rate_factor', 4.0).successful
    assert node.pacer.rate_factor == 4.0 and node.get_parameter('rate_factor').value == 4.0
    result = _set(node, 'rate_factor', 0.0)          # flow control is a start-up choice
    assert not result.successful and 'to or from 0' in result.reason
    result = _set(node, 'rate_factor', 5000.0)       # outside 0 .. 1000
    assert not result.successful and node.pacer.rate_factor == 4.0
    result = _set(node, 'mode', 'sim')               # read-only
    assert not result.successful and 'read-only' in result.reason.lower()
    assert node.mode == 'csv'
    result = _set(node, 'flow_window', 10)           # no flow control at rate_factor 4
    assert not result.successful and 'rate_factor 0' in result.reason
    result = _set(node, 'stroke_m', 0.01)            # no commanded excitation
    assert not result.successful and 'commanded' in result.reason


def test_current_limits_and_guard_settings_reach_the_core(make_node):
    node = make_node(mode='sim', excitation='commanded', current_source='command',
                     plant='kwok-current')
    assert _set(node, 'current_max_a', 1.5).successful
    assert node.limiter.i_max_a == 1.5
    result = _set(node, 'current_min_a', 1.8)        # above the maximum: refused by the core
    assert not result.successful and 'i_min_a' in result.reason
    assert node.limiter.i_min_a == 0.0
    assert _set(node, 'command_timeout_s', 0.2).successful
    assert node.follower.guard.timeout_s == 0.2 and node.pacer.timeout_s == 0.2
    assert _set(node, 'stroke_m', 0.02).successful
    from std_msgs.msg import Float64
    node._on_displacement(Float64(data=0.05))        # clamped to the new stroke
    assert node.follower.guard.counts['clamped_high'] == 1
    values = node.status_values()
    assert values['samples_published'] == 1 and values['tracking_error']['n'] == 1
    node._on_command(Float64(data=3.0))
    assert node.status_values()['commands']['clamped_high'] == 1
    assert node.rig._command == 1.5                  # the coil follows the clamped command


def test_current_limits_refused_without_current_commands(make_node):
    node = make_node(mode='sim')
    result = _set(node, 'current_max_a', 1.5)
    assert not result.successful and 'current_source:=command' in result.reason


def test_tick_publishes_the_due_samples_and_the_clock_of_the_newest(make_node):
    from mr_damper_model.io.data import read_csv
    data = read_csv(QUIROZ)
    node = make_node(mode='csv', file=str(QUIROZ), rate_factor=1.0, publish_clock=True,
                     samples_per_message=20)
    clock = [1000.0]
    node.pacer._clock = lambda: clock[0]             # a fake wall clock for the pacer
    node.pacer.created_s = clock[0]
    node._tick()                 # starts: the first sample is due, no whole batch yet
    assert node.pacer.published == 0 and node.stream.pending == 1
    assert node.clock_published == 0 and math.isnan(node.clock_last_s)
    clock[0] += 0.5
    node._tick()
    due = int(np.searchsorted(data.t - data.t[0], 0.5, side='right'))
    n = due // 20 * 20                               # the whole batches of the samples due
    assert node.pacer.published == n and node.stream.pending == due - n
    assert node.stream.sequence == n // 20
    assert node.clock_published == 1 and node.clock_last_s == pytest.approx(data.t[n - 1])
    values = node.status_values()
    assert values['clock'] == {'published': 1, 'last_s': node.clock_last_s}
    assert values['samples_published'] == n and values['started'] and not values['done']
    assert values['messages_published'] == n // 20
    health = node.health()
    assert health.level == 0 and health.values['mode'] == 'csv'


def test_publish_clock_needs_a_replay_and_wall_time(make_node):
    with pytest.raises(ValueError, match='publish_clock needs a replay'):
        make_node(mode='sim', publish_clock=True)
    with pytest.raises(ValueError, match='use_sim_time'):
        make_node(mode='csv', file=str(QUIROZ), publish_clock=True, use_sim_time=True)
    assert math.isnan(make_node(mode='csv', file=str(QUIROZ)).clock_last_s)


def test_default_parameter_file_matches_the_declared_parameters():
    import yaml
    from conftest import REPO
    from mr_damper_rig.rig_node import PARAMETERS
    cfg = yaml.safe_load((REPO / 'src/mr_damper_rig/config/rig.yaml').read_text())
    values = cfg['mr_damper_rig']['ros__parameters']
    defaults = {p.name: p.default for p in PARAMETERS}
    assert set(values) == set(defaults)
    for name, value in values.items():
        assert value == defaults[name] and type(value) is type(defaults[name]), name
