"""
Identifier node in-process: dynamic parameters reach the core, the rest is refused with a reason.

Also: relative topic names under a namespace, the ``samples_received`` count, the diagnostics
values of received and rejected samples, and ROS time under ``use_sim_time``.
"""
import array
import time

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from std_msgs.msg import UInt64

from mr_damper_common.health import ERROR, OK, WARN
from mr_damper_model.nodes.identifier_node import IdentifierNode, PARAMETERS
from mr_damper_model.live import DYNAMIC_FIELDS
from mr_damper_common.messages import measurement_to_msg, samples_to_msg
from ros_context import ros_context


@pytest.fixture(scope='module')
def ros():
    """Return this module's rclpy context (its own; shut down after the module)."""
    with ros_context() as context:
        yield context


@pytest.fixture
def make_node(ros):
    nodes = []

    def make(*overrides, **kw):
        params = [Parameter('fit_in_process', value=False)] + list(overrides)
        node = IdentifierNode(parameter_overrides=params, context=ros, **kw)
        nodes.append(node)
        return node
    try:
        yield make
    finally:
        for node in nodes:
            node.shutdown()
            node.destroy_node()


def test_dynamic_parameters_reach_the_core(make_node):
    node = make_node()
    live = node.runtime.live
    res = node.set_parameters([Parameter('max_nrmse_percent', value=4.0),
                               Parameter('force_limit_n', value=800.0),
                               Parameter('no_sample_timeout_s', value=9.0)])
    assert all(r.successful for r in res), res
    assert live.config.max_nrmse_percent == 4.0 and live.config.force_limit_n == 800.0
    assert node.runtime.health_rules.no_sample_timeout_s == 9.0
    node._on_measurement(measurement_to_msg(0.0, 0.0, 0.0, 900.0, 1.0))
    assert live.counters['out_of_range']['force'] == 1      # the new limit applies


def test_read_only_out_of_range_and_inconsistent_changes_are_refused(make_node):
    node = make_node()
    before = node.runtime.live.config
    (res,) = node.set_parameters([Parameter('window_s', value=3.0)])
    assert not res.successful and 'read-only' in res.reason
    (res,) = node.set_parameters([Parameter('max_nrmse_percent', value=-1.0)])
    assert not res.successful and 'max_nrmse_percent out of range' in res.reason
    (res,) = node.set_parameters([Parameter('current_limit_min_a', value=3.0)])
    assert not res.successful and '`current_limit_min_a`' in res.reason
    assert node.runtime.live.config is before
    assert node.get_parameter('current_limit_min_a').value == before.current_limit_min_a


def test_every_live_threshold_is_declared_dynamic_and_the_rest_read_only():
    dynamic = {p.name for p in PARAMETERS if p.dynamic}
    assert set(DYNAMIC_FIELDS) <= dynamic
    assert dynamic - set(DYNAMIC_FIELDS) == {'save_period_s', 'no_sample_timeout_s'}
    for p in PARAMETERS:
        assert p.description and (isinstance(p.default, (bool, str)) or p.low is not None)


def test_relative_names_samples_received_and_diagnostics(make_node):
    node = make_node(Parameter('no_sample_timeout_s', value=0.0), namespace='fl')
    assert node._pub_received.topic_name == '/fl/mr_damper/samples_received'
    assert node._pub_params.topic_name == '/fl/mr_damper/kwok_parameters'
    assert node.diagnostics.name == 'fl/mr_damper_identifier'
    h = node.diagnostics.publish()
    assert (h.level, h.message) == (OK, 'waiting for samples')
    for k in range(5):
        node._on_measurement(measurement_to_msg(1.0 + k * 1e-3, 0.0, 0.01, 10.0, 0.5))
    bad = measurement_to_msg(2.0, 0.0, 0.0, 0.0, 0.0)
    bad.name = ['piston', 'coil']
    node._on_measurement(bad)
    v = node.diagnostics.publish().values
    assert v['samples_received'] == 6 and v['samples_accepted'] == 5
    assert v['rejected']['joint_names'] == 1 and v['stamp_age_ms']['n'] == 5
    # the count on mr_damper/samples_received
    got = []
    sub_node = rclpy.create_node('samples_received_probe', context=node.context)
    sub_node.create_subscription(UInt64, '/fl/mr_damper/samples_received',
                                 lambda m: got.append(m.data), 10)
    ex = SingleThreadedExecutor(context=node.context)
    ex.add_node(node)
    ex.add_node(sub_node)
    end = time.monotonic() + 15.0                    # hang guard (discovery)
    while (not got or got[-1] != 6) and time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    ex.remove_node(node)
    sub_node.destroy_node()
    assert got and got[-1] == 6


def test_measurement_batches_are_taken_whole_and_lost_samples_counted_exactly(make_node):
    node = make_node(Parameter('no_sample_timeout_s', value=0.0))
    node.diagnostics.publish()
    t = 1.0 + np.arange(100) * 1e-3
    z, f = np.zeros(100), np.linspace(-100.0, 100.0, 100)
    for k, first in enumerate((0, 20, 60, 80)):          # batch 40..59 never arrived
        part = slice(first, first + 20)
        node._on_samples(samples_to_msg(t[part], z[part], z[part] + 0.01, f[part],
                                        z[part] + 0.5, sequence=k, first_index=first))
    bad = samples_to_msg(t[:2] + 1.0, z[:2], z[:2], z[:2], z[:2], sequence=4, first_index=100)
    bad.i_a = array.array('d', [0.5])                      # unequal arrays: one rejection
    node._on_samples(bad)
    h = node.diagnostics.publish()
    v = h.values
    assert v['samples_accepted'] == 80 and v['rejected']['layout'] == 1
    assert v['stream'] == {'batches': 4, 'samples': 80, 'lost': 20, 'restarts': 0,
                           'jumps': 0, 'skipped_at_start': 0}
    assert h.level == WARN and '20 sample(s) lost' in h.message
    assert v['stamp_age_ms']['n'] == 4                    # one transport age per batch


def test_sim_time_fits_in_order_and_ages_are_ros_time(make_node):
    node = make_node(Parameter('use_sim_time', value=True),
                     Parameter('sim_backlog_windows', value=7))
    assert node.runtime.live.config.backlog_windows == 7
    assert node.get_clock().now().nanoseconds == 0          # no /clock yet: ROS time is 0
    node._on_measurement(measurement_to_msg(5.0, 0.0, 0.01, 10.0, 0.5))
    assert node.runtime.ages.summary()['p50'] == pytest.approx(-5000.0)
    real = make_node(Parameter('no_sample_timeout_s', value=1e-9))
    assert real.runtime.live.config.backlog_windows == 0
    assert real.diagnostics.publish().level == OK            # first report: the reference
    assert real.diagnostics.publish().level == ERROR         # then no sample for too long


@pytest.mark.parametrize('content', ['kwok-current-lag', 'not json'])
def test_a_parameter_file_it_cannot_resume_from_is_not_overwritten(
        make_node, tmp_path, content):
    from mr_damper_model.models.kwok_current_lag import KwokCurrentLag
    from mr_damper_model.io.params_file import save_params
    path = tmp_path / 'damper.json'
    if content == 'not json':
        path.write_text('{"model": ')
    else:                           # an offline fit of the default multi-current model
        m = KwokCurrentLag()
        lo, hi = m.default_bounds()
        save_params(path, {'model': m.name, 'parameters': m.to_dict((lo + hi) / 2)})
    before = path.read_bytes()
    node = make_node(Parameter('params_file', value=str(path)))
    assert node.runtime.saver is None and node.runtime.live.estimate is None
    assert node.diagnostics.publish().values['initial_source'] == 'file_error'
    assert node.runtime.flush_saves() == ''
    assert node.runtime.shutdown() == ''
    assert path.read_bytes() == before


def test_its_own_parameter_file_is_resumed_and_saved_to(make_node, tmp_path):
    from mr_damper_model.models import presets
    from mr_damper_model.io.params_file import save_params
    _, truth = presets.thesis_kwok_current()
    path = tmp_path / 'damper.json'
    save_params(path, {'model': 'kwok-current', 'parameters': truth,
                       'model_options': {'i_ref_a': 2.0}})
    node = make_node(Parameter('params_file', value=str(path)))
    assert node.runtime.saver is not None
    assert node.diagnostics.publish().values['initial_source'] == 'file'
    assert node.runtime.live.estimate.parameters == pytest.approx(truth)
