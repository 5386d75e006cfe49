"""
A node that takes its events while a depth-1 reader of it is flooded (issue 32, section 1).

The scenario of ros2/rmw_implementation#278 (the regression test of ros2/rmw_fastrtps#890), in
the suite's own terms. ``python flood_take.py take N`` subscribes through
``DropCounter.subscribe`` to numbered 200-kB ``mr_damper_interfaces/DamperSamples`` batches
(KEEP_LAST 1, best effort or reliable), starts ``python flood_take.py flood`` (in its process
group: a KEEP_LAST 1 writer publishing them as fast as it can) and runs a take loop on the
suite's executor (``node_utils.make_executor``, the EventsExecutor): each iteration takes what
is ready, then takes the subscription's QoS events ``TAKES`` times, as an event-driven executor
does when several events are pending. The writer's heartbeat comes every 2 ms
(``fast_heartbeat_profile.xml``), so a reliable reader learns of the batches it lost many times
a second, in the receive thread, under the reader's lock: the stack of the frozen controller
of issue 32. A subscription whose MESSAGE_LOST event is armed then freezes for good, at a
random moment: the take holds the event's mutex and waits for the reader's, while the receive
thread reporting the loss holds the reader's and waits for the event's.

Output: ``progress <iteration> <taken> <lost> <span>`` every 100 iterations (batches taken,
counted lost, and numbered from the first to the last one taken), and ``done`` with the same
fields once ``N`` iterations ran and losses were counted (the scenario happened), then the
writer is stopped (SIGTERM) and the exit status is 0.

``--arm-message-lost`` subscribes as the suite did before the fix (the event armed, its counts
from the middleware) to show the freeze on the old code: ``bench/bench_message_lost_hang.py``.
"""
import argparse
from dataclasses import dataclass, field
import os
from pathlib import Path
import queue
import signal
import subprocess
import sys
import threading
import time

TOPIC = 'flood_take/samples'
#: samples per batch: 5 arrays x 5000 x 8 B = 200 kB, more than the transport passes at the
#: writer's full speed, so the depth-1 reader loses batches
BATCH = 5000
#: event takes per iteration (several events pending: the EventsExecutor takes each)
TAKES = 10
#: the writer's Fast DDS profile (heartbeat period 2 ms)
PROFILE = Path(__file__).with_name('fast_heartbeat_profile.xml')


def _qos(reliable):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                      reliability=(ReliabilityPolicy.RELIABLE if reliable
                                   else ReliabilityPolicy.BEST_EFFORT))


def flood(reliable):
    """Publish numbered batches as fast as possible until SIGTERM / SIGINT (then exit 0)."""
    import numpy as np
    import rclpy
    from mr_damper_interfaces.msg import DamperSamples
    rclpy.init()         # rclpy's own SIGTERM handler: the context ends, publish() raises
    node = rclpy.create_node('flood_take_writer')
    try:
        pub = node.create_publisher(DamperSamples, TOPIC, _qos(reliable))
        msg = DamperSamples()
        msg.header.frame_id = 'flood'
        msg.t_offset_s = msg.x_m = msg.v_m_s = msg.f_n = msg.i_a = np.linspace(0.0, 1.0, BATCH)
        while rclpy.ok():
            pub.publish(msg)
            msg.sequence += 1
    except Exception:  # noqa: B902 - the context went down under publish(): stopping
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def take(iterations, reliable, arm_message_lost=False):
    """Run the take loop; return 0 once ``iterations`` ran and losses were counted."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from mr_damper_common.node_utils import DropCounter, make_executor
    from mr_damper_interfaces.msg import DamperSamples
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('flood_take_reader')
    drops = DropCounter(node.get_logger(), warn_period_s=3600.0)
    seen = {'taken': 0, 'first': None, 'last': None}

    def on_samples(msg):
        seen['taken'] += 1
        seen['first'] = msg.sequence if seen['first'] is None else seen['first']
        seen['last'] = msg.sequence
    if arm_message_lost:
        from rclpy.event_handler import SubscriptionEventCallbacks
        events = SubscriptionEventCallbacks(
            message_lost=lambda info: drops.count('lost', info.total_count_change))
        sub = node.create_subscription(DamperSamples, TOPIC, on_samples, _qos(reliable),
                                       event_callbacks=events)
    else:
        sub = drops.subscribe(node, DamperSamples, TOPIC, on_samples, _qos(reliable), 'lost')
    executor = make_executor()
    executor.add_node(node)
    env = dict(os.environ, FASTDDS_DEFAULT_PROFILES_FILE=str(PROFILE))
    writer = subprocess.Popen([sys.executable, __file__, 'flood'] + ['--reliable'] * reliable,
                              env=env)
    try:
        it = 0
        while True:
            executor.spin_once(timeout_sec=0.01)
            for handler in sub.event_handlers:
                for _ in range(TAKES):
                    handler.take_data()
            it += 1
            lost = drops.counts().get('lost', 0)
            span = 0 if seen['first'] is None else seen['last'] - seen['first'] + 1
            line = f'{it} {seen["taken"]} {lost} {span}'
            if it >= iterations and lost > 0:
                print('done', line, flush=True)
                return 0
            if it % 100 == 0:
                print('progress', line, flush=True)
    finally:
        writer.send_signal(signal.SIGTERM)
        try:
            writer.wait(timeout=30)
        except subprocess.TimeoutExpired:
            writer.kill()
            writer.wait()


@dataclass
class TakeRun:
    """What one ``take`` process did (:func:`run_take`)."""

    hung: bool = False
    returncode: int = None
    lines: list = field(default_factory=list)

    def counts(self, kind):
        """Return ``[(iteration, taken, lost, span), ...]`` of the ``kind`` lines."""
        return [tuple(int(v) for v in line.split()[1:]) for line in self.lines
                if line.startswith(kind + ' ')]


def run_take(iterations, *options, guard_s=180.0, on_hang=None):
    """
    Run ``flood_take.py take`` in a process group of its own; kill the group whatever happens.

    ``guard_s`` is a hang guard, not a time bound: a run that has not ended by then is
    ``hung`` (``on_hang(pid)`` is called first, e.g. to save its stacks).
    """
    proc = subprocess.Popen([sys.executable, __file__, 'take', str(int(iterations)), *options],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    lines = queue.Queue()

    def pump():
        for line in iter(proc.stdout.readline, ''):
            lines.put(line)
        lines.put(None)
    threading.Thread(target=pump, daemon=True).start()
    run = TakeRun()
    deadline = time.monotonic() + guard_s
    try:
        while True:
            try:
                line = lines.get(timeout=max(deadline - time.monotonic(), 0.0))
            except queue.Empty:
                run.hung = True
                if on_hang is not None:
                    on_hang(proc.pid)
                break
            if line is None:
                break
            run.lines.append(line.strip())
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)    # the writer too, and anything it left
        except ProcessLookupError:
            pass
        run.returncode = proc.wait()
    return run


def main(argv=None):
    """Command line: ``flood [--reliable]`` or ``take N [--reliable] [--arm-message-lost]``."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('role', choices=('flood', 'take'))
    parser.add_argument('iterations', type=int, nargs='?', default=1000)
    parser.add_argument('--reliable', action='store_true')
    parser.add_argument('--arm-message-lost', action='store_true')
    args = parser.parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if args.role == 'flood':
        flood(args.reliable)
        return 0
    return take(args.iterations, args.reliable, args.arm_message_lost)


if __name__ == '__main__':
    sys.exit(main())
