"""Tests of node_utils.qos: the QoS of each stream, the writer that survives a stalled reader."""
import pytest
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from mr_damper_common import node_utils
import node_utils_helpers
from node_utils_helpers import spin_once as _spin_once

ros = node_utils_helpers.ros      # this module's rclpy context (fixture)


def test_measurement_stream_is_reliable_keep_all_and_other_topics_keep_last():
    r = node_utils.MEASUREMENT_QOS
    assert r.history == HistoryPolicy.KEEP_ALL and r.reliability == ReliabilityPolicy.RELIABLE
    for q in (node_utils.LATCHED_QOS, node_utils.STATUS_QOS):
        assert q.history == HistoryPolicy.KEEP_LAST and q.depth <= 10


@pytest.mark.slow
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
