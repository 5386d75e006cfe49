"""Helpers of the node_utils tests: an rclpy context per module, a logger, one spin of a node."""
import pytest
from rclpy.executors import SingleThreadedExecutor

from ros_context import ros_context


@pytest.fixture(scope='module')
def ros():
    """Return this module's rclpy context (its own; shut down after the module)."""
    with ros_context() as context:
        yield context


class RecordingLogger:
    """Stands in for an rclpy logger: keeps the warning lines."""

    def __init__(self):
        self.lines = []

    def warning(self, text, throttle_duration_sec=None):
        self.lines.append(text)


def spin_once(node, timeout_sec):
    """Spin ``node`` once on an executor of its own context."""
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        executor.remove_node(node)
        executor.shutdown()
