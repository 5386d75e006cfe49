"""
Tests of node_utils: QoS choices, drop counter, spin loop, SIGINT / SIGTERM in run_node.

The spin loop's stop and error handling, and run_node's signal handling in a real process
(exit 0 after finish and destroy, in that order). The drop counter's subscriptions count lost
messages from their sequence numbers and never arm the middleware's MESSAGE_LOST event.
"""
import os
import signal
import subprocess
import sys
import textwrap

import pytest
import rclpy
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from mr_damper_common import node_utils
from process_helpers import popen, stop_group
from ros_context import ros_context


class _Logger:
    def __init__(self):
        self.lines = []

    def warning(self, text, throttle_duration_sec=None):
        self.lines.append(text)


@pytest.fixture(scope='module')
def ros():
    """Return this module's rclpy context (its own; shut down after the module)."""
    with ros_context() as context:
        yield context


def _spin_once(node, timeout_sec):
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        executor.remove_node(node)
        executor.shutdown()


def test_measurement_stream_is_reliable_keep_all_and_other_topics_keep_last():
    r = node_utils.MEASUREMENT_QOS
    assert r.history == HistoryPolicy.KEEP_ALL and r.reliability == ReliabilityPolicy.RELIABLE
    for q in (node_utils.LATCHED_QOS, node_utils.STATUS_QOS):
        assert q.history == HistoryPolicy.KEEP_LAST and q.depth <= 10


def test_drop_counter_counts_by_reason_and_warns():
    log = _Logger()
    drops = node_utils.DropCounter(log)
    drops.count('message_lost', 3)
    drops.count('message_lost', 2)
    drops.count('publish_failed')
    drops.count('nothing', 0)
    assert drops.counts() == {'message_lost': 5, 'publish_failed': 1}
    # one warning per reason per period (the counts are never throttled)
    assert len(log.lines) == 2 and '3 in all' in log.lines[0] and 'publish_failed' in log.lines[1]


def _wait_for(condition, spin, what):
    for _ in range(3000):   # a hang guard, not a time bound
        if condition():
            return
        spin()
    raise AssertionError(f'hang guard: {what}')


def test_subscribe_counts_sequence_gaps_per_stream_and_never_arms_message_lost(ros):
    from rclpy.event_handler import QoSSubscriptionEventType
    from mr_damper_interfaces.msg import DamperSamples
    node = rclpy.create_node('gaps_test', context=ros)
    executor = SingleThreadedExecutor(context=ros)
    executor.add_node(node)
    try:
        drops = node_utils.DropCounter(_Logger())
        got, text = [], []
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        sub = drops.subscribe(node, DamperSamples, 'gaps_topic', got.append, qos,
                              'samples_lost')
        plain = drops.subscribe(node, String, 'gaps_text', text.append, qos)
        with pytest.raises(ValueError, match='no sequence'):    # no count it cannot keep
            drops.subscribe(node, String, 'gaps_text', text.append, qos, 'text_lost')
        for s in (sub, plain):
            types = {h.event_type for h in s.event_handlers}
            assert QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST not in types, types
        pub = node.create_publisher(DamperSamples, 'gaps_topic', qos)
        text_pub = node.create_publisher(String, 'gaps_text', qos)
        _wait_for(lambda: pub.get_subscription_count() == text_pub.get_subscription_count() == 1,
                  lambda: executor.spin_once(timeout_sec=0.01), 'discovery')
        # two publishers (frames) interleaved; 'fl' skips 3, 4 and 7, 'fr' restarts at 0
        sent = [('fl', 0), ('fr', 10), ('fl', 1), ('fl', 2), ('fr', 11), ('fl', 5), ('fl', 6),
                ('fr', 0), ('fl', 8), ('fr', 1)]
        for frame, k in sent:
            msg = DamperSamples(sequence=k)
            msg.header.frame_id = frame
            pub.publish(msg)
            text_pub.publish(String(data=str(k)))
        _wait_for(lambda: len(got) == len(text) == len(sent),
                  lambda: executor.spin_once(timeout_sec=0.01), 'delivery')
        assert [(m.header.frame_id, m.sequence) for m in got] == sent
        assert drops.counts() == {'samples_lost': 3}     # types without a sequence: nothing
    finally:
        executor.shutdown()
        node.destroy_node()


def test_no_subscription_in_src_arms_the_message_lost_event():
    """Fast DDS 3.2.3 can deadlock a node taking MESSAGE_LOST (ros2/rmw_fastrtps#890)."""
    import re
    from conftest import REPO
    armed = re.compile(r'message_lost\s*=|RCL_SUBSCRIPTION_MESSAGE_LOST|lost_callbacks')
    found = [f'{path.relative_to(REPO)}:{n}: {line.strip()}'
             for path in sorted((REPO / 'src').rglob('*.py'))
             for n, line in enumerate(path.read_text().splitlines(), 1) if armed.search(line)]
    assert not found, found


def test_publish_failure_is_counted_not_raised(ros):
    node = rclpy.create_node('node_utils_test', context=ros)
    drops = node_utils.DropCounter(_Logger())
    pub = node.create_publisher(String, '/node_utils_test/status', node_utils.STATUS_QOS)
    assert drops.publish(pub, String(data='x')) is True
    pub.destroy()                                       # the handle is gone: publish raises

    class Refusing:
        topic_name = '/refusing'

        def publish(self, msg):
            raise _rclpy.RCLError('Failed to publish: cannot publish data')
    assert drops.publish(pub, String(data='y')) is False
    assert drops.publish(Refusing(), String(data='z')) is False
    assert drops.counts() == {'publish_failed': 2}
    node.destroy_node()


def test_publish_next_numbers_each_message_from_0_also_past_a_failed_publish():
    """The readers of a numbered stream count the failed one lost: its number is used."""
    from mr_damper_interfaces.msg import QuarterCarState
    drops = node_utils.DropCounter(_Logger())
    sent = []

    class Flaky:
        topic_name = '/numbered'

        def publish(self, msg):
            if msg.sequence == 1:
                raise _rclpy.RCLError('Failed to publish: cannot publish data')
            sent.append(msg.sequence)
    msg = QuarterCarState()
    assert [drops.publish_next(Flaky(), msg) for _ in range(3)] == [True, False, True]
    assert sent == [0, 2] and msg.sequence == 3 and drops.counts() == {'publish_failed': 1}


class _Executor:
    """spin_once counts calls, raises ``error`` at call ``fail_at``, stops at ``stop_at``."""

    def __init__(self, stop_at=None, fail_at=None, error=RuntimeError('Unable to convert')):
        self.calls = 0
        self.stop_at, self.fail_at, self.error = stop_at, fail_at, error

    def spin_once(self, timeout_sec):
        self.calls += 1
        if self.calls == self.stop_at:
            node_utils.request_stop()
        if self.calls == self.fail_at:
            raise self.error


@pytest.fixture
def stop_flag():
    """Clear the stop flag; rclpy's default context up (the spin loop asks ``rclpy.ok()``)."""
    node_utils._STOP.clear()
    try:
        with ros_context(default=True):
            yield
    finally:
        node_utils._STOP.clear()


def test_spin_returns_on_stop_request_and_on_done(stop_flag):
    ex = _Executor(stop_at=3)
    node_utils.spin(ex)
    assert ex.calls == 3 and node_utils.stop_requested()
    node_utils._STOP.clear()
    ex = _Executor()
    node_utils.spin(ex, done=lambda: ex.calls >= 5)
    assert ex.calls == 5


def test_spin_error_after_stop_ends_quietly_before_stop_raises(stop_flag):
    ex = _Executor(stop_at=2, fail_at=2)
    node_utils.spin(ex)                                  # the shutdown race: no error
    assert ex.calls == 2
    node_utils._STOP.clear()
    with pytest.raises(RuntimeError, match='Unable to convert'):
        node_utils.spin(_Executor(fail_at=2))


_NODE_SCRIPT = textwrap.dedent('''
    import sys, time
    from rclpy.node import Node
    from mr_damper_common.node_utils import run_node

    class Busy(Node):
        def __init__(self):
            super().__init__('node_utils_signal_test')
            self.ticks = 0
            self.create_timer(0.001, self.tick)

        def tick(self):
            self.ticks += 1
            t = time.perf_counter()
            while time.perf_counter() - t < 0.0008:   # keep the main thread busy
                pass
            if self.ticks == 50:
                print('ready', flush=True)

    def finish(node):
        print(f'finish after {node.ticks} ticks', flush=True)

    sys.exit(run_node(Busy, 'busy', finish=finish))
''')


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_run_node_exits_0_on_signal_after_finish(sig):
    proc = popen([sys.executable, '-c', _NODE_SCRIPT], stdout=subprocess.PIPE,
                 stderr=subprocess.STDOUT, text=True, env=dict(os.environ))
    try:
        assert proc.stdout.readline().strip() == 'ready'
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=30)          # hang guard only
    finally:
        if proc.poll() is None:
            stop_group(proc, signal.SIGKILL)
    assert proc.returncode == 0, out
    assert out.startswith('finish after') and 'Traceback' not in out, out


def test_resettable_publisher_replaces_a_writer_a_reader_stopped_acknowledging(ros):
    # a KEEP_ALL reader whose callbacks never run (never spun) stops taking samples once its
    # history is full; the reliable writer then keeps everything unacknowledged until its own
    # resource limit (5,000) and publish() fails: the writer is replaced, nothing raises
    node = rclpy.create_node('resettable_pub', context=ros)
    stalled = rclpy.create_node('stalled_reader', context=ros)
    qos = QoSProfile(depth=10, history=HistoryPolicy.KEEP_ALL,
                     reliability=ReliabilityPolicy.RELIABLE)
    stalled.create_subscription(String, 'stall_topic', lambda m: None, qos)
    pub = node_utils.ResettablePublisher(node, String, 'stall_topic', node_utils.MEASUREMENT_QOS,
                                         rematch_timeout_s=30.0)
    for _ in range(3000):   # discovery: a hang guard, not a time bound
        if pub.get_subscription_count() == 1:
            break
        _spin_once(node, timeout_sec=0.01)
    assert pub.get_subscription_count() == 1
    old = pub.publisher
    sent = 0
    while pub.publish(String(data='x')):
        sent += 1
        assert sent < 20000, 'the stalled reader never filled the writer'
    assert pub.resets == 1 and pub.publisher is not old
    assert sent >= 10        # the reader's and writer's histories held these
    # the new writer waits for as many readers as the old one had, less the stalled one
    assert pub.ready()
    node.destroy_node()
    stalled.destroy_node()


_SPECS = (
    node_utils.Param('gain', 2.0, 'Controller gain [N s/m]', 0.0, 10.0, dynamic=True),
    node_utils.Param('safe_current_a', 0.5, 'Safe current [A]', 0.0, 2.0, dynamic=True),
    node_utils.Param('window', 3, 'Window count [-]', 1, 100),
    node_utils.Param('mode', 'sim', 'Source of the samples'),
)


def test_parameters_have_descriptions_ranges_and_refuse_what_cannot_change(ros):
    from rclpy.parameter import Parameter
    node = rclpy.create_node('param_spec_test', context=ros)
    applied = []

    def on_set(changes):
        if changes.get('gain', 0.0) > 5.0 and 'safe_current_a' not in changes:
            return 'gain above 5 needs a safe current in the same request'
        applied.append(changes)
        return ''

    values = node_utils.declare_parameters(node, _SPECS, on_set)
    assert values == {'gain': 2.0, 'safe_current_a': 0.5, 'window': 3, 'mode': 'sim'}
    desc = node.describe_parameter('gain')
    assert desc.description == 'Controller gain [N s/m]' and not desc.read_only
    assert (desc.floating_point_range[0].from_value,
            desc.floating_point_range[0].to_value) == (0.0, 10.0)
    assert node.describe_parameter('window').integer_range[0].to_value == 100
    assert node.describe_parameter('mode').read_only
    # a dynamic parameter in range is applied through the callback
    result = node.set_parameters([Parameter('gain', value=4.0)])[0]
    assert result.successful and applied == [{'gain': 4.0}]
    assert node.get_parameter('gain').value == 4.0
    # out of range: rclpy refuses before the callback
    result = node.set_parameters([Parameter('gain', value=11.0)])[0]
    assert not result.successful and 'out of range' in result.reason
    # the node's own check refuses with its reason; nothing changes
    result = node.set_parameters([Parameter('gain', value=6.0)])[0]
    assert not result.successful and 'safe current' in result.reason
    assert node.get_parameter('gain').value == 4.0 and len(applied) == 1
    # start-up-only parameters are refused, not accepted and ignored
    result = node.set_parameters([Parameter('mode', value='csv')])[0]
    assert not result.successful and 'read-only' in result.reason
    assert node.get_parameter('mode').value == 'sim'
    node.destroy_node()


def test_a_value_out_of_range_at_start_up_is_a_parameter_error(ros):
    from rclpy.exceptions import ParameterException
    from rclpy.parameter import Parameter
    node = rclpy.create_node('param_range_test', context=ros, parameter_overrides=[
        Parameter('window', value=0)])
    with pytest.raises(ParameterException):
        node_utils.declare_parameters(node, _SPECS[2:])
    node.destroy_node()


def test_dynamic_parameters_need_an_on_set_callback(ros):
    node = rclpy.create_node('param_no_callback', context=ros)
    with pytest.raises(ValueError, match='on_set'):
        node_utils.declare_parameters(node, _SPECS[:1])
    node.destroy_node()


def test_diagnostics_publisher_sends_named_levels_and_survives_a_status_error(ros):
    from diagnostic_msgs.msg import DiagnosticArray
    from mr_damper_common.health import Health, STALE, WARN
    from mr_damper_common.messages import health_from_diagnostic
    node = rclpy.create_node('diag_test', namespace='fl', context=ros)
    listener = rclpy.create_node('diag_listener', context=ros)
    got = []
    listener.create_subscription(DiagnosticArray, '/diagnostics', got.append,
                                 node_utils.DIAGNOSTICS_QOS)
    calls = []

    def health():
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError('boom')
        return Health(WARN, 'fail-safe: stale', {'param_age_s': 1.5})

    drops = node_utils.DropCounter(_Logger())
    diag = node_utils.DiagnosticsPublisher(node, health, period_s=3600.0, hardware_id='fl',
                                           drops=drops)
    assert diag.name == 'fl/diag_test'
    for _ in range(3000):   # discovery: a hang guard, not a time bound
        if listener.count_publishers('/diagnostics') >= 1 and \
                node.count_subscribers('/diagnostics') >= 1:
            break
        _spin_once(listener, timeout_sec=0.01)
    assert diag.publish().level == WARN
    assert diag.publish().level == STALE         # the error became a STALE status
    for _ in range(3000):
        if len(got) == 2:
            break
        _spin_once(listener, timeout_sec=0.01)
    statuses = [s for msg in got for s in msg.status]
    assert [s.name for s in statuses] == ['fl/diag_test'] * 2
    first, second = (health_from_diagnostic(s) for s in statuses)
    assert first.level == WARN and first.values == {'param_age_s': 1.5}
    assert statuses[0].hardware_id == 'fl'
    assert second.level == STALE and 'RuntimeError: boom' in second.message
    assert diag.published == 2 and drops.counts() == {}
    node.destroy_node()
    listener.destroy_node()


def test_log_throttle_gates_per_key():
    """At most one line per key per period; a zero period lets every line through."""
    from mr_damper_common.node_utils import LogThrottle
    gate = LogThrottle(3600.0)
    assert [gate.due('a'), gate.due('a'), gate.due('b'), gate.due('a')] == [True, False, True,
                                                                            False]
    assert all(LogThrottle(0.0).due() for _ in range(3))


def test_fast_lane_takes_its_topic_in_its_own_thread_with_the_parents_namespace(ros):
    import threading
    import time
    parent = rclpy.create_node('lane_parent', namespace='/corner_fl', context=ros)
    lane = node_utils.FastLane(parent, 'link')
    assert (lane.node.get_name(), lane.node.get_namespace()) == ('lane_parent_link',
                                                                 '/corner_fl')
    # no parameter services on the lane: only the parent answers `ros2 param`
    services = [name for name, _ in lane.node.get_service_names_and_types_by_node(
        'lane_parent_link', '/corner_fl')]
    assert not any(name.endswith('/get_parameters') for name in services), services
    parent_services = parent.get_service_names_and_types_by_node('lane_parent', '/corner_fl')
    assert '/corner_fl/lane_parent/get_parameters' in [name for name, _ in parent_services]
    got, threads = [], set()

    def on_msg(msg):
        got.append(msg.data)
        threads.add(threading.current_thread().name)
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    lane.node.create_subscription(String, 'link_topic', on_msg, qos)   # relative: namespaced
    lane.start()
    pub = parent.create_publisher(String, '/corner_fl/link_topic', qos)
    for _ in range(3000):   # discovery: a hang guard, not a time bound
        if pub.get_subscription_count() == 1:
            break
        time.sleep(0.01)
    for k in range(50):
        pub.publish(String(data=str(k)))
    for _ in range(3000):   # the parent is never spun: the lane's thread takes them
        if len(got) == 50:
            break
        time.sleep(0.01)
    assert got == [str(k) for k in range(50)] and threads == {'lane_parent_link'}
    lane.close()
    assert lane._thread is None
    parent.destroy_node()
