"""
Benchmark: the stand-alone controller node, state -> command latency and ride against built-in.

1. Streaming at 1 kHz: this process publishes ``QuarterCarState`` messages (states of a
   simulated ride, so the skyhook law and the inverse do real work) paced at ``--rate`` for
   ``--stream-s`` seconds to ``semi_active_controller_node`` (its own process; the valid thesis
   parameter set latched by this process) and takes its commands back. States and commands
   are KEEP_LAST 10 (only the newest matters), so a starved process loses some: they are
   counted. Without a loss command ``k`` answers state ``k`` (reliable, in order) and the
   latency (receipt of command ``k`` - publication of state ``k``) is printed too.
2. Lock-step in real time: the quarter car node (``controller:=external lockstep:=true``,
   1 kHz, real time) driven by the controller node for ``--duration`` seconds. Each step the
   car publishes its state and waits for the command answering it: the per-step latency
   state published -> its command in hand (the car's log column ``compute_s``) is the
   state -> command latency across DDS at 1 kHz with nothing lost (p50, p99; target
   p99 <= 2 ms). The same run gives the ride: Wk RMS body acceleration and RMS dynamic tyre
   load ratio on the road (t >= 0) against the built-in loop (``live_loop.ClosedLoop``) on the
   same road, seed and model, step for step. The core alone in-process (the built-in
   controller, no DDS) is timed on the same states for comparison.
3. Asynchronous in real time (the default ``lockstep:=false``): the same, but each step applies
   the newest command received, so the answer to state k acts one step late (or more on a
   stall); its ride figures against the built-in loop show what that delay costs.

Machine load (``os.getloadavg``) is printed at the start and at the end.

Usage::

    .venv/bin/python bench/bench_controller.py [--duration 20] [--stream-s 10] [--domain-id 75]
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

SAFE_A = 0.5
SEED = 1


def _params():
    from mr_damper_model.identification import presets
    model, params = presets.thesis_kwok_current()
    values = {k: float(v) for k, v in params.items()}
    values.update(i_ref_a=float(model.options.get('i_ref_a', 2.0)), current_min_a=0.0,
                  current_max_a=2.0, valid=1.0)
    return values


def _ride_states(n):
    """States of ``n`` steps of a built-in skyhook ride (inputs of the latency run)."""
    loop = _built_in_loop()
    return [loop.step(0.0) for _ in range(n)]


def _built_in_loop():
    from mr_damper_model.models.plant import make_plant
    from quarter_car_sim.simulate import live_loop
    from semi_active_control.laws import make_controller
    from quarter_car_sim.plant.quarter_car import QuarterCar
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.plant.road import make_road
    params = QuarterCarParams()
    road = make_road('iso8608', road_class='C', speed_m_s=20.0, rng=SEED,
                     duration_s=300.0, dt=1e-3)
    car = QuarterCar(params, make_plant('kwok-current'), road, t0=-live_loop.SETTLE_S)
    sup = ModelSupervisor(timeout_s=3600.0, safe_current_a=SAFE_A)
    law = make_controller('skyhook', params=params, damper_only=True)
    loop = live_loop.ClosedLoop(car, law, sup, 1e-3)
    sup.offer(_params(), 0.0)
    return loop


def _start(exe, params, log, namespace='bench_controller'):
    cmd = [str(Path(sys.executable).parent / exe), '--ros-args', '-r', f'__ns:=/{namespace}']
    for k, v in params.items():
        v = ('true' if v else 'false') if isinstance(v, bool) else v
        cmd += ['-p', f'{k}:={v}']
    return subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ))


def _stop(proc):
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
    return proc.returncode


def _wait(pred, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.02)
    return pred()


def live_settle():
    """Return the car's settling time [s] before the road starts."""
    from quarter_car_sim.simulate.live_loop import SETTLE_S
    return SETTLE_S


def _stats_ms(a):
    a = 1e3 * np.asarray(a, dtype=float)
    return (f'p50 {np.percentile(a, 50):.3f} ms, p99 {np.percentile(a, 99):.3f} ms, '
            f'max {a.max():.3f} ms (n {a.size})')


def latency_run(node, ctrl_status, rate_hz, duration_s, prefix):
    """Publish paced states, return (send times, receive times, in-process core times)."""
    from mr_damper_interfaces.msg import QuarterCarState
    from std_msgs.msg import Float64
    from semi_active_control.runtime.controller_core import ControllerCore
    from semi_active_control.laws import Skyhook
    from semi_active_control.supervision.failsafe import ModelSupervisor
    from mr_damper_common.messages import corner_state_to_msg
    from mr_damper_common.node_utils import CONTROL_QOS
    n = int(rate_hz * duration_s)
    states = _ride_states(n)
    recv = []
    node.create_subscription(Float64, f'{prefix}/mr_damper/current_command',
                             lambda m: recv.append(time.perf_counter()), CONTROL_QOS)
    pub = node.create_publisher(QuarterCarState, f'{prefix}/quarter_car/car_state', CONTROL_QOS)
    if not _wait(lambda: pub.get_subscription_count() > 0 and ctrl_status()
                 and ctrl_status().get('mode') == 'normal', 30.0):
        raise RuntimeError(f'controller not ready: {ctrl_status()}')
    time.sleep(0.5)                      # the command path matched too
    sent = np.empty(n)
    msg = None
    period = 1.0 / rate_hz
    t0 = time.perf_counter()
    for k, s in enumerate(states):
        due = t0 + k * period
        while True:
            now = time.perf_counter()
            if now >= due:
                break
            if due - now > 2e-4:
                time.sleep(due - now - 1.5e-4)
        msg = corner_state_to_msg(s, 0.0, True, 'ok', msg)
        sent[k] = time.perf_counter()
        pub.publish(msg)
    _wait(lambda: len(recv) >= n, 5.0)
    # the built-in controller on the same states: the core called in-process
    core = ControllerCore(Skyhook(), ModelSupervisor(timeout_s=3600.0, safe_current_a=SAFE_A))
    core.offer_parameters(_params(), 0.0)
    local = np.empty(n)
    for k, s in enumerate(states):
        a = time.perf_counter()
        core.command(s, 0.0)
        local[k] = time.perf_counter() - a
    return sent, np.array(recv), local


def external_car(prefix, log, priority=0, lockstep=True):
    """Start the external car at 1 kHz in real time; return (process, log path)."""
    tmp = Path(tempfile.mkdtemp(prefix='bench_controller_'))
    car_log = tmp / 'car_log'
    car = _start('quarter_car_node', {
        'plant': 'kwok-current', 'controller': 'external', 'lockstep': lockstep,
        'lockstep_timeout_s': 1.0, 'command_timeout_s': 1.0 if lockstep else 0.05,
        'real_time_factor': 1.0,
        'road_seed': SEED, 'road_duration_s': 300.0, 'safe_current_a': SAFE_A,
        'log_file': str(car_log), 'diagnostics_period_s': 0.1, 'realtime_priority': priority},
        log)
    return car, car_log


def external_run(procs, ctrl_params, prefix, log, args, status, local, lockstep):
    """Run the external car with a fresh controller; print latency and ride against built-in."""
    # a fresh controller (its states start again at t = 0) and the car
    _stop(procs['ctrl'])
    status.pop('ctrl', None)
    procs['ctrl'] = _start('semi_active_controller_node', ctrl_params, log)
    if not _wait(lambda: status.get('ctrl', {}).get('mode') == 'normal', 30.0):
        raise RuntimeError(f'controller not ready: {status.get("ctrl")}')
    status.pop('car', None)
    car, car_log = external_car(prefix, log, args.realtime_priority, lockstep)
    procs['car'] = car
    ok = _wait(lambda: status.get('car', {}).get('t_sim', -1.0) >= args.duration
               - live_settle(), 60.0 + 3.0 * args.duration)
    _stop(car)
    if not ok:
        raise RuntimeError(f'the car did not run {args.duration} s: {status.get("car")}')
    from mr_damper_common.recording.columnlog import ColumnReader
    z = ColumnReader(car_log).read()
    meta = ColumnReader(car_log).meta['status']
    title = '2. lock-step' if lockstep else '3. asynchronous (newest command each step)'
    print(f'{title}, real time: {z["t"].size} steps at 1 kHz, lock-step timeouts '
          f'{meta["lockstep_timeouts"]}, command timeouts {meta["command_timeouts"]}, all '
          f'steps normal {bool(np.all(z["mode"] == 1.0))}; period jitter p99 '
          f'{meta["loop"]["period"]["jitter_p99_ms"]:.3f} ms')
    if lockstep:
        print(f'   state published -> its command in the car: {_stats_ms(z["compute_s"])} '
              '(target p99 <= 2 ms)')
        print(f'   built-in controller (core in-process, no DDS): {_stats_ms(local)}')
    else:
        print(f'   commands received {meta["commands_received"]} for {meta["steps"]} steps '
              '(the answer to state k arrives during step k: it acts from step k + 1)')
    loop = _built_in_loop()
    states = [loop.step(0.0) for _ in range(int(z['t'].size))]
    ref = {c: np.array([getattr(s, c) for s in states])
           for c in ('t', 'a_s', 'travel', 'tyre_force', 'damper_force')}
    wk_e, tl_e = ride_figures(z)
    wk_b, tl_b = ride_figures(ref)
    print(f'   ride over {z["t"][-1]:.2f} s of road (ISO 8608 C, 20 m/s, seed {SEED}, '
          'kwok-current plant, skyhook, thesis model):')
    print(f'     external            : Wk RMS {wk_e:.5f} m/s^2, RMS tyre load ratio '
          f'{tl_e:.5f}')
    print(f'     built-in            : Wk RMS {wk_b:.5f} m/s^2, RMS tyre load ratio '
          f'{tl_b:.5f}')
    print(f'     external / built-in : Wk {wk_e / wk_b:.6f}, tyre load {tl_e / tl_b:.6f}')


def ride_figures(columns):
    """Return (Wk RMS body acceleration [m/s^2], RMS dynamic tyre load ratio) for t >= 0."""
    from semi_active_control.car.quarter_car import QuarterCarParams
    from quarter_car_sim.metrics.quarter_car import ride_metrics
    keep = columns['t'] >= 0.0
    m = ride_metrics({c: np.asarray(columns[c])[keep] for c in
                      ('t', 'a_s', 'travel', 'tyre_force', 'damper_force')},
                     static_load=QuarterCarParams().static_tyre_load)
    return m['rms_body_accel_wk'], m['rms_tyre_load_ratio']


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--duration', type=float, default=20.0,
                    help='lock-step real-time run [s] (20)')
    ap.add_argument('--stream-s', type=float, default=10.0, help='streaming run [s] (10)')
    ap.add_argument('--rate', type=float, default=1000.0, help='streaming rate [Hz] (1000)')
    ap.add_argument('--realtime-priority', type=int, default=0,
                    help='SCHED_FIFO priority of the car\'s control thread and the controller '
                         'node (0 = normal scheduling; needs root)')
    ap.add_argument('--domain-id', type=int, default=75)
    args = ap.parse_args(argv)
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    os.environ['ROS_DOMAIN_ID'] = str(args.domain_id)
    os.environ.setdefault('ROS_LOG_DIR', tempfile.mkdtemp(prefix='ros_log_'))
    sys.setswitchinterval(0.0005)
    import rclpy
    from mr_damper_interfaces.msg import KwokParameters
    from diagnostic_msgs.msg import DiagnosticArray
    from mr_damper_common.messages import health_from_diagnostic, kwok_parameters_msg
    from mr_damper_common.node_utils import LATCHED_QOS, make_executor, set_realtime_priority
    print(f'bench_controller: load at start {os.getloadavg()}, {os.cpu_count()} CPUs, '
          f'realtime priority {args.realtime_priority}')
    prefix = '/bench_controller'
    rclpy.init()
    node = rclpy.create_node('bench_controller')
    status = {}
    names = {f'{prefix[1:]}/semi_active_controller': 'ctrl',
             f'{prefix[1:]}/quarter_car_node': 'car'}

    def on_diagnostics(msg):
        for st in msg.status:
            if st.name in names:
                status[names[st.name]] = health_from_diagnostic(st).values
    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    ppub = node.create_publisher(KwokParameters, f'{prefix}/mr_damper/kwok_parameters',
                                 LATCHED_QOS)
    ppub.publish(kwok_parameters_msg(_params()))
    executor = make_executor(True)
    executor.add_node(node)
    # this process's publisher and receiver compete with the nodes: same priority as theirs
    set_realtime_priority(args.realtime_priority, node.get_logger())
    running = threading.Event()
    running.set()

    def spin():
        while running.is_set():
            executor.spin_once(timeout_sec=0.05)
    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    log = open(Path(tempfile.gettempdir()) / 'bench_controller_nodes.log', 'w')
    ctrl_params = {
        'param_timeout_s': 3600.0, 'safe_current_a': SAFE_A, 'diagnostics_period_s': 0.1,
        'realtime_priority': args.realtime_priority}
    procs = {'ctrl': _start('semi_active_controller_node', ctrl_params, log), 'car': None}
    code = 0
    try:
        sent, recv, local = latency_run(node, lambda: status.get('ctrl'), args.rate,
                                        args.stream_s, prefix)
        time.sleep(0.3)
        st = status.get('ctrl', {})
        print(f'1. streaming: {sent.size} states at {args.rate:g} Hz, {recv.size} commands back '
              f'(lost {sent.size - recv.size}: {sent.size - st.get("commands", 0)} states '
              f'before the controller, {st.get("commands", 0) - recv.size} commands after it)')
        if recv.size == sent.size:
            print(f'   state -> command across DDS: {_stats_ms(recv - sent)}')
        else:
            print('   (with losses command k need not answer state k: no latency from this run)')
        for lockstep in (True, False):
            external_run(procs, ctrl_params, prefix, log, args, status, local, lockstep)
    except RuntimeError as exc:
        print(f'bench_controller: {exc}', file=sys.stderr)
        code = 1
    finally:
        for proc in procs.values():
            if proc is not None:
                _stop(proc)
        running.clear()
        thread.join(5)
        node.destroy_node()
        rclpy.try_shutdown()
        log.close()
    print(f'bench_controller: load at end {os.getloadavg()}')
    return code


if __name__ == '__main__':
    sys.exit(main())
