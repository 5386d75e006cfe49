"""
The rig node as a process: /clock for nodes on sim time, and flow control against a consumer.

Real ``rig_node`` processes, LOCALHOST discovery, the private domain of tests/conftest.py.
Order of events and counts only; the waits are hang guards.

- ``publish_clock`` on a CSV replay at ``rate_factor`` 4: a node started with
  ``use_sim_time`` sees ``/clock`` advance strictly, one message per tick that published
  samples, each the stamp of the newest sample of that tick, up to the last sample's stamp; its
  ROS time at the end is that stamp exactly, and while it runs it is always a clock the rig
  published;
- ``rate_factor`` 0: the rig keeps exactly ``flow_window`` samples ahead of the count the
  consumer publishes on ``mr_damper/samples_received``; a count that goes down (a restarted
  consumer) is counted in ``flow_restarts`` and paced against; the replay ends (exit 0) with
  every sample received and ``done`` on ``/diagnostics``.
"""
import threading

import numpy as np
import pytest

from integration.ros_helpers import NodeProcess

pytestmark = [pytest.mark.integration]

GUARD_S = 60.0
RATE_HZ = 200.0


def _write_csv(path, n, t0_s=10.0):
    """Write a 200 Hz record of ``n`` samples from ``t0_s`` [s]; return its stamps."""
    t = t0_s + np.arange(n) / RATE_HZ
    x = 0.01 * np.sin(2 * np.pi * 2.0 * t)
    v = 0.02 * np.pi * 2.0 * np.cos(2 * np.pi * 2.0 * t)
    f = 300.0 * np.tanh(v / 0.05)
    i = np.full(n, 0.5)
    np.savetxt(path, np.column_stack([t, x, v, f, i]), delimiter=',', header='t,x,v,f,i',
               comments='', fmt='%.9f')
    return np.round(t, 9)


class SimTimeNode:
    """A node with ``use_sim_time`` (spun in a thread): measurements with its ROS time, /clock."""

    def __init__(self, topic, context):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.parameter import Parameter
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from mr_damper_interfaces.msg import DamperSamples
        self.node = rclpy.create_node('sim_time_listener', context=context, parameter_overrides=[
            Parameter('use_sim_time', value=True)])
        self.clocks = []
        self.received = []    # (stamp ns, ROS time ns at receipt)
        keep_all = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_ALL,
                              reliability=ReliabilityPolicy.RELIABLE)
        self.clock_sub = self.node.create_subscription(
            Clock, '/clock', lambda m: self.clocks.append(
                m.clock.sec * 1_000_000_000 + m.clock.nanosec), keep_all)
        self._meas = (DamperSamples, topic, keep_all)
        self._executor = SingleThreadedExecutor(context=context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def subscribe_measurements(self):
        msg_type, topic, qos = self._meas
        self.node.create_subscription(msg_type, topic, self._on_measurement, qos)

    def _on_measurement(self, msg):
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        now = self.node.get_clock().now().nanoseconds
        for offset in msg.t_offset_s:       # every sample of the batch, received now
            self.received.append((stamp + round(offset * 1e9), now))

    def now_ns(self):
        return self.node.get_clock().now().nanoseconds

    def _spin(self):
        while not self._stop.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def close(self):
        self._stop.set()
        self._thread.join(timeout=5)
        self._executor.shutdown()
        self.node.destroy_node()


def test_replay_clock_drives_a_sim_time_node_at_rate_factor_4(listener, tmp_path):
    n = 600                                      # 3 s of record, 0.75 s at rate_factor 4
    stamps_ns = (_write_csv(tmp_path / 'rec.csv', n) * 1e9).round().astype(np.int64)
    diag = listener.diagnostics()
    sim = SimTimeNode('/clk/mr_damper/measurement', listener.context)
    try:
        params = {'mode': 'csv', 'file': str(tmp_path / 'rec.csv'), 'rate_factor': 4.0,
                  'publish_clock': True, 'tick_s': 0.005, 'wait_for_subscribers': 1,
                  'diagnostics_period_s': 0.2}
        with NodeProcess('rig_node', params, namespace='clk') as rig:
            # /clock matched first: the rig starts once the measurement reader matched
            assert listener.wait_for(lambda: sim.clock_sub.get_publisher_count() > 0,
                                     GUARD_S, procs=[rig]), rig.output()
            assert sim.now_ns() == 0                  # no clock yet: sim time stands at 0
            sim.subscribe_measurements()
            assert rig.wait(GUARD_S) == 0, rig.output()
            assert listener.wait_for(lambda: len(sim.received) == n, GUARD_S)
            assert listener.wait_for(
                lambda: diag.values('clk/mr_damper_rig').get('done'), GUARD_S)
        values = diag.values('clk/mr_damper_rig')
        clocks = np.array(sim.clocks)
        # strictly increasing, each the stamp of a published sample, up to the last one
        assert np.all(np.diff(clocks) > 0)
        assert np.isin(clocks, stamps_ns).all()
        assert clocks[-1] == stamps_ns[-1]
        # one clock per tick that published samples (fewer than the samples: several per tick
        # at 800 samples/s and 200 ticks/s)
        assert len(clocks) == values['clock']['published'] < n
        assert values['samples_published'] == n and values['clock']['last_s'] == pytest.approx(
            stamps_ns[-1] * 1e-9, abs=1e-9)
        # the sim-time node's ROS time is the recording's: at the end the last stamp exactly
        assert listener.wait_for(lambda: sim.now_ns() == stamps_ns[-1], GUARD_S)
        # while it ran: the node's ROS time at each sample was a clock the rig published (or 0
        # before the first). How close it was to the sample's stamp is not asserted: /clock
        # and the measurements are two topics, not ordered against each other, so a receiver
        # that falls behind on one sees the other run ahead (82-96 % of the samples were
        # within one tick at load 8 on 2 cores; a statistic of the machine, not a property)
        got = np.array([s for s, _ in sim.received])
        assert got.shape == stamps_ns.shape       # every sample, in order (ns stamp + offset)
        assert np.abs(got - stamps_ns).max() <= 1
        ros = np.array([r for _, r in sim.received])
        assert np.isin(ros, np.append(clocks, 0)).all()
        assert np.all(np.diff(ros) >= 0)           # ROS time never goes back
    finally:
        sim.close()


def test_flow_control_keeps_the_window_and_follows_a_restarted_consumer(listener, tmp_path):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import UInt64
    from mr_damper_interfaces.msg import DamperSamples
    n, window = 700, 50
    _write_csv(tmp_path / 'rec.csv', n)
    diag = listener.diagnostics()
    batches = listener.subscribe('/flow/mr_damper/measurement', DamperSamples, QoSProfile(
        depth=1000, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))

    def received():
        return sum(len(m.x_m) for _, m in list(batches))
    counts = listener.publisher('/flow/mr_damper/samples_received', UInt64)
    name = 'flow/mr_damper_rig'
    params = {'mode': 'csv', 'file': str(tmp_path / 'rec.csv'), 'rate_factor': 0.0,
              'flow_window': window, 'wait_for_subscribers': 1, 'diagnostics_period_s': 0.1}
    with NodeProcess('rig_node', params, namespace='flow') as rig:
        assert listener.wait_for(lambda: counts.get_subscription_count() > 0 and diag.count(name),
                                 GUARD_S, procs=[rig]), rig.output()
        assert not batches                           # waits for the consumer's first count
        counts.publish(UInt64(data=0))
        # after each count the rig sends exactly up to one window beyond what the consumer
        # has: before a restart, base 0; a restarted consumer counts from 0 again and the rig
        # paces against its new count plus what it had published (the same target)
        offset, expected = 0, window
        for step in range(8):
            assert listener.wait_for(lambda: received() >= expected, GUARD_S, procs=[rig])
            got = received()
            assert got == expected                # one window ahead, not more
            if step == 4:                         # the consumer restarts: its count is 0
                offset = got
            counts.publish(UInt64(data=got - offset))
            expected = min(got + window, n)
        assert listener.wait_for(lambda: diag.values(name).get('flow_restarts') == 1, GUARD_S,
                                 procs=[rig]), diag.values(name)
        while received() < n:                      # the rest, count by count
            got = received()
            counts.publish(UInt64(data=got - offset))
            assert listener.wait_for(lambda: received() > got, GUARD_S, procs=[rig])
        assert rig.wait(GUARD_S) == 0, rig.output()
    values = diag.values(name)
    assert values['done'] and values['samples_published'] == n == received()
    assert values['flow_restarts'] == 1 and values['flow']['window'] == window
    stamps = np.concatenate([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
                             + np.asarray(m.t_offset_s) for _, m in batches])
    assert np.all(np.diff(stamps) > 0)            # in order, none twice
    firsts = [m.first_index for _, m in batches]  # the stream index: contiguous
    assert firsts == list(np.cumsum([0] + [len(m.x_m) for _, m in batches][:-1]))
