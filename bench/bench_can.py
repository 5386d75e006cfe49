"""
Benchmark: ROS command -> CAN frame -> damper driver, against the direct ROS path, at 1 kHz.

This process publishes ``std_msgs/Float64`` coil current commands on
``mr_damper/current_command`` paced at ``--rate`` for ``--duration`` seconds (an absolute
schedule). Two other processes read the same topic:

- ``can_bridge_node`` (``udp_loopback`` bus, one corner): each command becomes a
  ``DAMPER_CMD_FL`` frame; the simulated driver (:class:`mr_damper_can.driver_sim.SimulatedEcu`,
  run in *this* process on the same bus) stamps each valid command frame on arrival;
- a plain rclpy subscriber (this script with ``--direct OUT``) that stamps each command on
  arrival: the direct ROS path, what a driver on ROS would see.

All stamps are ``time.monotonic`` (one clock for every process of the host). Consecutive
commands have distinct values, so command k is matched to the k-th frame / message, and a lost
one is counted (the bridge's keep-alive re-sends are off: ``resend_period_s`` 10 s). Printed:
latency p50 / p99 / max of both paths, the CAN path's extra over the direct one (same
messages), lost counts, the CPU of the bridge and of the direct subscriber (one core = 100 %),
and the load average at the start and the end. With ``--log run.blf`` (or ``.asc``, ``.log``
for candump) the bridge writes every frame of the run with python-can's writer for that format.

Usage::

    .venv/bin/python bench/bench_can.py [--duration 10] [--rate 1000] [--log run.blf]
"""
import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

VENV_BIN = Path(sys.executable).parent


def _value(k):
    """Return the k-th command [A]: consecutive values differ, all on the 10-mA grid."""
    return round(0.01 * (k % 255 + 1), 2)


def direct_subscriber(out):
    """Run the direct ROS subscriber until SIGINT; save the arrival stamps to ``out``."""
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64
    from mr_damper_common.node_utils import install_stop_handlers, spin_node, stop_requested
    install_stop_handlers()
    rclpy.init()
    node = rclpy.create_node('bench_can_direct')
    stamps = []
    node.create_subscription(Float64, 'mr_damper/current_command',
                             lambda m: stamps.append((time.monotonic(), m.data)),
                             QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    spin_node(node, stop_requested)
    np.save(out, np.array(stamps, dtype=float).reshape(-1, 2))
    node.destroy_node()
    rclpy.try_shutdown()


def _cpu_s(pid):
    import psutil
    t = psutil.Process(pid).cpu_times()
    return t.user + t.system


def _stats(lat_s):
    lat = np.asarray(lat_s) * 1e3
    if lat.size == 0:
        return 'no samples'
    return (f'p50 {np.percentile(lat, 50):.3f} ms, p99 {np.percentile(lat, 99):.3f} ms, '
            f'max {lat.max():.1f} ms (n = {lat.size})')


def _match(pub_t, pub_v, got):
    """Match arrivals ``[(t, value)]`` to the publications in order; return latencies, lost."""
    lat, k = [], 0
    for t, v in got:
        while k < len(pub_v) and abs(pub_v[k] - v) > 0.004:
            k += 1                       # publications k.. never arrived
        if k == len(pub_v):
            break
        lat.append(t - pub_t[k])
        k += 1
    return lat, len(pub_v) - len(lat)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--duration', type=float, default=10.0, help='streaming time [s]')
    parser.add_argument('--rate', type=float, default=1000.0, help='command rate [Hz]')
    parser.add_argument('--log', default='', help='frame log of the run (.blf, .asc, .log)')
    parser.add_argument('--domain-id', type=int, default=None)
    parser.add_argument('--direct', default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if args.direct:
        direct_subscriber(args.direct)
        return 0
    domain = args.domain_id if args.domain_id is not None else 100 + os.getpid() % 100
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    channel = f'239.74.163.2:{44500 + domain}'
    load0 = os.getloadavg()
    print(f'load average at start: {load0[0]:.2f} (1 min), {os.cpu_count()} cores')

    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64
    from mr_damper_can.bus import make_bus
    from mr_damper_can.driver_sim import SimulatedEcu

    tmp = Path(tempfile.mkdtemp(prefix='bench_can_'))
    log = str(Path(args.log).resolve()) if args.log else ''
    bridge = subprocess.Popen(
        [str(VENV_BIN / 'can_bridge_node'), '--ros-args', '-p', 'interface:=udp_loopback',
         '-p', f'channel:={channel}', '-p', 'corners:=fl', '-p', 'publish_sensors:=false',
         '-p', 'resend_period_s:=10.0', '-p', 'command_timeout_s:=3600.0',
         '-p', 'rx_timeout_s:=3600.0'] + (['-p', f'log_file:={log}'] if log else []),
        stdout=open(tmp / 'bridge.log', 'w'), stderr=subprocess.STDOUT)
    direct_out = tmp / 'direct.npy'
    direct = subprocess.Popen([sys.executable, __file__, '--direct', str(direct_out)],
                              stdout=open(tmp / 'direct.log', 'w'), stderr=subprocess.STDOUT)
    bus = make_bus('udp_loopback', channel)
    arrivals = []
    lock = threading.Lock()

    def on_command(corner, value, counter, failsafe, t):
        if not failsafe:
            with lock:
                arrivals.append((t, value))

    ecu = SimulatedEcu(bus, ('fl',), sensors=False, command_timeout_s=3600.0,
                       on_command=on_command)
    ecu.start()
    rclpy.init()
    node = rclpy.create_node('bench_can')
    pub = node.create_publisher(Float64, 'mr_damper/current_command',
                                QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1000,
                                           reliability=ReliabilityPolicy.RELIABLE))
    try:
        end = time.monotonic() + 60.0
        while (pub.get_subscription_count() < 2 and time.monotonic() < end
               and bridge.poll() is None and direct.poll() is None):
            time.sleep(0.05)
        if pub.get_subscription_count() < 2:
            raise RuntimeError(f'bridge or direct subscriber not matched within 60 s (logs in '
                               f'{tmp})')
        time.sleep(1.0)                  # both start-ups done
        n = int(args.duration * args.rate)
        pub_t, pub_v = np.empty(n), np.array([_value(k) for k in range(n)])
        cpu0 = {p.pid: _cpu_s(p.pid) for p in (bridge, direct)}
        wall0 = time.monotonic()
        msg = Float64()
        for k in range(n):
            due = wall0 + k / args.rate
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            msg.data = pub_v[k]
            pub_t[k] = time.monotonic()
            pub.publish(msg)
        time.sleep(1.0)                  # the last ones arrive
        wall = time.monotonic() - wall0
        cpu = {p.pid: (_cpu_s(p.pid) - cpu0[p.pid]) / wall * 100.0 for p in (bridge, direct)}
    finally:
        for proc in (bridge, direct):
            proc.send_signal(signal.SIGINT)
        for proc in (bridge, direct):
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
        ecu.stop()
        bus.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    with lock:
        can_got = list(arrivals)
    direct_got = [tuple(r) for r in np.load(direct_out)] if direct_out.exists() else []
    lat_can, lost_can = _match(pub_t, pub_v, can_got)
    lat_ros, lost_ros = _match(pub_t, pub_v, direct_got)
    st = ecu.status()['corners']['fl']
    load1 = os.getloadavg()
    print(f'{n} commands at {args.rate:g} Hz for {args.duration:g} s')
    print(f'ROS -> bridge -> CAN frame -> driver: {_stats(lat_can)}; lost {lost_can}; '
          f'driver counter jumps {st["counter_jumps"]}, bad checksums {st["bad_checksum"]}')
    print(f'ROS -> direct subscriber:            {_stats(lat_ros)}; lost {lost_ros}')
    if lat_can and lat_ros and not lost_can and not lost_ros:
        extra = (np.asarray(lat_can) - np.asarray(lat_ros)) * 1e3
        print(f'CAN path minus direct path, same commands: p50 {np.percentile(extra, 50):.3f} '
              f'ms, p99 {np.percentile(extra, 99):.3f} ms')
    print(f'CPU (one core = 100 %): bridge {cpu[bridge.pid]:.1f} %, direct subscriber '
          f'{cpu[direct.pid]:.1f} %')
    print(f'exit codes: bridge {bridge.returncode}, direct {direct.returncode}')
    if log:
        print(f'frame log: {log} ({Path(log).stat().st_size} bytes)')
    print(f'load average at end: {load1[0]:.2f} (1 min)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
