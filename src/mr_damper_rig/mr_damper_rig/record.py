"""
``mr-damper-record``: record the measurement topic into a rosbag2 (sqlite3 or MCAP).

For machines without ``ros2 bag``: subscribes to the measurement topic (reliable, keep-all, like
the identifier) and writes every message, still serialised, with the `rosbags` writer until
Ctrl-C (SIGINT) or SIGTERM, ``--duration`` seconds or ``--count`` messages; the bag is closed
properly in every case and the exit status is 0. Samples the middleware reports lost before
the recorder took them are counted and printed at the end.  The bag replays with
``rig_node --ros-args -p mode:=bag -p file:=DIR`` and opens in ``ros2 bag`` / rosbags tools.

Example::

    mr-damper-record --out run1_bag --storage mcap --duration 60
"""
import argparse
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from sensor_msgs.msg import JointState

from mr_damper_model.node_utils import DropCounter, install_stop_handlers, stop_requested

from .replay import MEASUREMENT_TOPIC, BagWriter


def _parser():
    p = argparse.ArgumentParser(prog='mr-damper-record', description=__doc__.split('\n')[1])
    p.add_argument('--out', required=True, help='bag directory to create (must not exist)')
    p.add_argument('--topic', default=MEASUREMENT_TOPIC, help='topic to record')
    p.add_argument('--storage', choices=('sqlite3', 'mcap'), default='sqlite3',
                   help='rosbag2 storage format')
    p.add_argument('--duration', type=float, default=0.0,
                   help='stop after this many seconds (0: until Ctrl-C)')
    p.add_argument('--count', type=int, default=0,
                   help='stop after this many messages (0: no limit)')
    return p


def main(argv=None):
    """Record until Ctrl-C / --duration / --count; return the exit status."""
    argv = sys.argv if argv is None else argv
    args = _parser().parse_args(remove_ros_args(argv)[1:])
    try:
        writer = BagWriter(args.out, topic=args.topic, storage=args.storage)
    except ValueError as exc:
        print(f'mr-damper-record: error: {exc}', file=sys.stderr)
        return 2
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    qos = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                     reliability=ReliabilityPolicy.RELIABLE)
    install_stop_handlers()   # SIGINT / SIGTERM: leave the loop, close the bag, exit 0
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('mr_damper_record')
    drops = DropCounter(node.get_logger())
    start = time.monotonic()
    with writer:
        def on_msg(raw):
            writer.write_raw(raw, node.get_clock().now().nanoseconds)

        node.create_subscription(JointState, args.topic, on_msg, qos, raw=True,
                                 event_callbacks=drops.lost_callbacks('message_lost'))
        node.get_logger().info(f'recording {args.topic} into {args.out} ({args.storage})')
        try:
            while rclpy.ok() and not stop_requested():
                rclpy.spin_once(node, timeout_sec=0.1)
                if args.duration > 0 and time.monotonic() - start >= args.duration:
                    break
                if args.count > 0 and writer.count >= args.count:
                    break
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            node.destroy_node()
            rclpy.try_shutdown()
    lost = drops.counts().get('message_lost', 0)
    print(f'mr-damper-record: {writer.count} messages written to {args.out}'
          f'{f", {lost} lost before they were taken" if lost else ""}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
