"""
Tests of node_utils.diagnostics: drop counter, log throttle, ``/diagnostics`` publisher.

The drop counter's subscriptions count lost messages from their sequence numbers and never arm
the middleware's MESSAGE_LOST event.
"""
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from mr_damper_common import node_utils
import node_utils_helpers
from node_utils_helpers import RecordingLogger as _Logger, spin_once as _spin_once

ros = node_utils_helpers.ros      # this module's rclpy context (fixture)


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
