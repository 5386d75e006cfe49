"""
Benchmark: what the state estimator node pays per 1 kHz sensor reading (not collected by pytest).

    .venv/bin/python bench/bench_estimator_rate.py [--duration 10] [--repeats 7]

In-process (medians of ``--repeats``, the alternatives timed in turn in the same run):

- reading a serialised ``sensor_msgs/Imu`` / ``JointState``: rclpy's deserialisation (what a
  typed subscription does) against :mod:`semi_active_control.estimation.sensor_cdr` (what the
  node's raw readers do);
- a suppressed throttled warning: rclpy's ``throttle_duration_sec`` against the
  :class:`~mr_damper_common.node_utils.LogThrottle` gate;
- one filter period of
:class:`~semi_active_control.estimation.state_estimator_core.StateEstimatorCore` on the
  steady gain and time-varying (after a lost reading), and the periods it takes to return to
  the steady gain after one lost reading with ``steady_tol`` 1e-6 and the node's 1e-3.

Over DDS (two processes, a private domain on loopback): this process publishes a car's body
``Imu`` and suspension ``JointState`` at 1 kHz (paced against the monotonic clock, stamps
``k`` ms) and a valid identified parameter set; ``state_estimator_node`` (``clock:=readings``)
runs for ``--duration`` s. Printed from its ``/diagnostics``: readings sent, received and counted
lost by the node (``readings_lost``; received + lost = sent when nothing goes uncounted; each
suspension position reading received is one estimate published), filter steps, periods
predicted through; its CPU (percent of one core). Quote the load printed at the end.
"""
import argparse
import json
import os
from pathlib import Path
import random
import statistics
import subprocess
import sys
import time

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
sys.path.insert(0, str(REPO / 'tests'))


def _per_call_us(fn, n, repeats):
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        out.append((time.perf_counter() - t0) / n * 1e6)
    return statistics.median(out)


def _row(name, a_name, a, b_name, b):
    print(f'{name:<34} {a_name} {a:8.2f} us   {b_name} {b:8.2f} us   ratio {a / b:6.1f}x')


def bench_in_process(repeats):
    """Print the per-call costs of the alternatives."""
    import numpy as np
    import rclpy
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import Imu, JointState
    from kwok_messages import thesis_parameter_values
    from mr_damper_common.node_utils import LogThrottle
    from semi_active_control.estimation import sensor_cdr
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from semi_active_control.estimation.sensor_specs import default_specs, G0
    from semi_active_control.estimation.state_estimator_core import StateEstimatorCore

    imu = Imu()
    imu.header.frame_id = 'body'
    imu.linear_acceleration.z = G0
    raw_imu = serialize_message(imu)
    raw_js = serialize_message(JointState(name=['suspension'], position=[1e-3]))
    _row('read Imu', 'rclpy', _per_call_us(lambda: deserialize_message(raw_imu, Imu), 5000,
                                           repeats),
         'sensor_cdr', _per_call_us(lambda: sensor_cdr.imu_reading(raw_imu), 5000, repeats))
    _row('read JointState', 'rclpy',
         _per_call_us(lambda: deserialize_message(raw_js, JointState), 5000, repeats),
         'sensor_cdr', _per_call_us(lambda: sensor_cdr.joint_reading(raw_js), 5000, repeats))

    rclpy.init()
    try:
        node = rclpy.create_node('bench_estimator_rate_log')
        log = node.get_logger()
        log.warning('bench: the throttled lines below are suppressed', throttle_duration_sec=3600)
        gate = LogThrottle(3600.0)
        gate.due()

        def rclpy_throttled():
            log.warning('bench', throttle_duration_sec=3600.0)

        def gated():
            if gate.due():
                log.warning('bench')
        slow = _per_call_us(rclpy_throttled, 300, repeats)
        _row('suppressed throttled warning', 'rclpy', slow, 'gate',
             _per_call_us(gated, 300, repeats))
        node.destroy_node()
    finally:
        rclpy.try_shutdown()

    for tol in (1e-6, 1e-3):
        core = StateEstimatorCore(QuarterCarParams(), 1e-3, default_specs(), ModelSupervisor(
            timeout_s=3600.0), run_options={'steady_tol': tol})
        core.offer_parameters(thesis_parameter_values(), 0.0)
        rng = np.random.default_rng(1)
        k = [0]

        def period(lost=False):
            k[0] += 1
            if not lost:
                core.offer_reading('body_accel', G0 + 0.05 * rng.standard_normal())
                core.offer_reading('travel', 5e-5 * rng.standard_normal())
            return core.tick(k[0] * 1e-3, 0.0)
        while not core.estimator.steady:
            period()
        steady = _per_call_us(period, 1000, repeats)
        period(lost=True)
        back = 0
        while not core.estimator.steady:
            period()
            back += 1

        def tv_period():
            core.estimator._steady = False
            return period()
        print(f'filter period, steady_tol {tol:g}: back on the steady gain {back} periods '
              f'after one lost reading')
    _row('filter period', 'time-varying', _per_call_us(tv_period, 1000, repeats), 'steady',
         steady)


def bench_dds(duration_s):
    """Run the estimator node against a 1 kHz vehicle of this process; print the counts."""
    import psutil
    import rclpy
    from rclpy.node import Node
    from sensor_msgs.msg import Imu, JointState
    from kwok_messages import thesis_parameter_values
    from mr_damper_interfaces.msg import KwokParameters
    from mr_damper_common import messages
    from mr_damper_common.node_utils import LATCHED_QOS
    from mr_damper_common.node_utils import CONTROL_QOS
    import numpy as np

    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    env.setdefault('ROS_DOMAIN_ID', str(random.randint(20, 220)))
    os.environ.update(env)
    rclpy.init()
    node = Node('bench_vehicle')
    imu_pub = node.create_publisher(Imu, 'quarter_car/body_imu', CONTROL_QOS)
    pos_pub = node.create_publisher(JointState, 'quarter_car/suspension_position', CONTROL_QOS)
    par_pub = node.create_publisher(KwokParameters, 'mr_damper/kwok_parameters', LATCHED_QOS)
    par_pub.publish(messages.kwok_parameters_msg(thesis_parameter_values()))
    status = {}

    def on_diag(msg):
        for st in msg.status:
            if st.name.endswith('state_estimator'):
                status.update({kv.key: kv.value for kv in st.values})
    from diagnostic_msgs.msg import DiagnosticArray
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)
    proc = subprocess.Popen(
        [str(BIN / 'state_estimator_node'), '--ros-args', '-p', 'clock:=readings', '-p',
         'param_timeout_s:=3600.0', '-p', 'diagnostics_period_s:=0.2'], env=env)
    try:
        t0 = time.monotonic()
        while imu_pub.get_subscription_count() < 1 or pos_pub.get_subscription_count() < 1:
            if time.monotonic() - t0 > 30:
                raise RuntimeError('the estimator node did not connect within 30 s')
            rclpy.spin_once(node, timeout_sec=0.05)
        for _ in range(20):
            rclpy.spin_once(node, timeout_sec=0.05)
        ps = psutil.Process(proc.pid)
        cpu0 = sum(ps.cpu_times()[:2])
        imu = Imu()
        imu.header.frame_id = 'body'
        pos = JointState(name=['suspension'], position=[0.0])
        rng = np.random.default_rng(1)
        n = int(duration_s * 1000)
        start = time.monotonic()
        for k in range(n):
            wait = start + k * 1e-3 - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            messages.seconds_to_stamp(k * 1e-3, imu.header.stamp)
            imu.linear_acceleration.z = 9.80665 + 0.055 * rng.standard_normal()
            imu_pub.publish(imu)
            messages.seconds_to_stamp(k * 1e-3, pos.header.stamp)
            pos.position = [5e-5 * rng.standard_normal()]
            pos_pub.publish(pos)
            if k % 20 == 0:
                rclpy.spin_once(node, timeout_sec=0.0)
        wall = time.monotonic() - start
        cpu = sum(ps.cpu_times()[:2]) - cpu0
        t_end = time.monotonic() + 3.0
        while time.monotonic() < t_end:
            rclpy.spin_once(node, timeout_sec=0.05)
    finally:
        proc.send_signal(2)
        proc.wait(30)
        node.destroy_node()
        rclpy.try_shutdown()

    def val(key):
        return json.loads(status.get(key, 'null'))
    print(json.dumps({
        'sent_per_sensor': n, 'wall_s': round(wall, 2),
        'received': {s: val(f'readings_received.{s}') for s in ('body_accel', 'travel')},
        'lost_counted': {s: val(f'readings_lost.{s}') for s in ('body_accel', 'travel')},
        'filter_steps': val('steps'), 'predict_steps': val('predict_steps'),
        'estimator_cpu_percent': round(100.0 * cpu / wall, 1)}))


def main():
    """Entry point."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    p.add_argument('--duration', type=float, default=10.0)
    p.add_argument('--repeats', type=int, default=7)
    args = p.parse_args()
    print(f'load average at the start: {os.getloadavg()}')
    bench_in_process(args.repeats)
    bench_dds(args.duration)
    print(f'load average at the end: {os.getloadavg()}')


if __name__ == '__main__':
    main()
