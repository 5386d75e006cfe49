"""
The vehicle computer's chain over real topics and the loopback CAN bus.

Real node processes (console scripts): ``vehicle_bridge_node``, ``vehicle_estimator_node``,
``vehicle_controller_node`` and (first test) ``lifecycle_manager``; this test process plays the
car's side of the bus: a :class:`mr_damper_can.driver_sim.SimulatedEcu` on ``udp_loopback`` (a
port of this test's own) sends the sensor frames (synthetic sines) every 2 ms and its drivers'
status every 10 ms, and records every command it takes. Assertions are on the order and the
counts of events (the waits are hang guards only, never a time budget).

1. Lifecycle and one corner's model: a transition out of order (activate an unconfigured node)
   is refused; the manager brings the chain up in order (configure bridge, estimator,
   controller, then activate them in that order); with the ``rr`` record marked invalid (a
   damper that failed its end-of-line check) ``rr`` is commanded its safe current with the
   fail-safe bit in every frame while the other three corners follow the law; deactivating the
   controller puts all four drivers on the safe current at once: the first command frame after
   the deactivation's command is safe on every corner, the controller's last, and no law
   frame follows it on the bus.
2. Faults without a manager (the transitions driven by the test): a killed estimator leads,
   through the controller's sensor timeout, to the safe current on every corner (the
   controller's reason ``sensor_timeout``); a silent controller (stopped with SIGSTOP) leads to
   the drivers' own command timeout (counted by each driver), and when it goes on the drivers
   take its commands again.
"""
import signal

import pytest

from integration.ros_helpers import Listener, NodeProcess
from integration.vehicle_helpers import (all_safe, bus_channel, Car, chain_up, change_state,
                                         command_frames, CORNERS, drivers_time_out_while_stopped,
                                         GUARD_S, model_files, normal_but_rr, safe_of_no_cycle,
                                         SAFE_A)

pytestmark = [pytest.mark.integration, pytest.mark.slow]

NODES = ('vehicle_bridge', 'vehicle_estimator', 'vehicle_controller')


def _chain(tmp_path, channel, files, sensor_timeout_s):
    """Start the three nodes; no timing watchdog (a loaded machine must pass the same tests)."""
    bus = {'channel': channel}
    common = {'diagnostics_period_s': 0.2, 'heartbeat_period_s': 0.1}
    return [NodeProcess('vehicle_bridge_node',
                        params=dict(bus, **common, safe_current_a=SAFE_A)),
            NodeProcess('vehicle_estimator_node', params=dict(common, dropout_s=10.0)),
            NodeProcess('vehicle_controller_node', params=dict(
                common, model_files=files, safe_current_a=SAFE_A,
                sensor_timeout_s=sensor_timeout_s, max_consecutive_misses=100000))]


def test_lifecycle_in_order_one_invalid_corner_and_deactivation(tmp_path):
    from lifecycle_msgs.msg import TransitionEvent
    from mr_damper_interfaces.msg import FullCarCommand
    channel = bus_channel(0)
    car = Car(channel)
    procs = _chain(tmp_path, channel, model_files(tmp_path, invalid=('rr',)), 30.0)
    try:
        with Listener('vehicle_chain_test') as lis:
            diag = lis.diagnostics()
            from rclpy.qos import QoSProfile, ReliabilityPolicy
            events = {n: lis.subscribe(f'{n}/transition_event', TransitionEvent, QoSProfile(
                depth=100, reliability=ReliabilityPolicy.RELIABLE)) for n in NODES}
            commands = lis.subscribe('vehicle/command', FullCarCommand, QoSProfile(
                depth=10, reliability=ReliabilityPolicy.RELIABLE))
            # a transition out of order is refused: the controller is unconfigured
            assert change_state(lis, 'vehicle_controller', 'activate') is False
            manager = NodeProcess('lifecycle_manager', params={'diagnostics_period_s': 0.2,
                                                               'heartbeat_timeout_s': 5.0})
            procs.append(manager)

            assert lis.wait_for(chain_up(diag, car), GUARD_S, procs=procs), manager.output()
            # in order: configure each, then activate each, in the chain's order
            done = sorted((t, n, e.goal_state.label) for n in NODES for t, e in events[n]
                          if e.goal_state.label in ('inactive', 'active'))
            # (the first six: a loaded machine may stall a node past its heartbeat, and the
            # chain then goes down and up again by the same rules)
            assert [(n, g) for _, n, g in done][:6] == [(n, 'inactive') for n in NODES] + \
                [(n, 'active') for n in NODES]
            # the other three follow the law: normal, and their currents move (waited for as
            # an event: the law may ask 0 A for a stretch of road, as a CI run saw for 54
            # frames, when every demand is below the damper's force at 0 A)
            assert lis.wait_for(lambda: len({f['fl'][0] for f in command_frames(car.taken())
                                             if normal_but_rr(f)}) > 1, GUARD_S, procs=procs)
            # the invalid record's corner is safe, flagged, in every frame
            frames = command_frames(car.taken())
            assert all(f['rr'] == (SAFE_A, 1) for f in frames)
            assert len([f for f in frames if normal_but_rr(f)]) >= 40
            assert lis.wait_for(lambda: diag.values('vehicle_controller').get(
                'corners', {}).get('rr', {}).get('reason') == 'invalid_flag', GUARD_S)
            manager.stop()
            # deactivate the controller: the drivers are on the safe current at once
            n_before = len(car.taken())
            assert change_state(lis, 'vehicle_controller', 'deactivate') is True
            # (one command: the controller is then silent, the bridge forwards nothing more)
            assert lis.wait_for(lambda: any(
                safe_of_no_cycle(f) for f in command_frames(car.taken()[n_before:])),
                GUARD_S, procs=procs[:3])
            after = command_frames(car.taken()[n_before:])
            # law frames in flight before the deactivation took effect, then its safe frame
            # (of no cycle: a frame the bridge made safe on its way, a driver's status late
            # on a starved machine, answers its cycle and may be followed by law frames)
            first = [safe_of_no_cycle(f) for f in after].index(True)
            assert all(all_safe(f) for f in after[first:]), after[first - 3:]
            # and the controller's last command was the deactivation's: no law command after
            assert lis.wait_for(lambda: commands and commands[-1][1].mode.tolist() == [
                FullCarCommand.MODE_INACTIVE] * 4, GUARD_S)
            seqs = [m.sequence for _, m in commands]
            assert seqs == sorted(seqs) and list(commands[-1][1].reason) == ['inactive'] * 4
            assert lis.wait_for(lambda: diag.values('vehicle_controller').get(
                'lifecycle') == 'inactive', GUARD_S)
            ctrl = diag.values('vehicle_controller')
            assert ctrl['all_safe']['inactive'] == 1
    finally:
        for p in procs:
            p.stop()
        car.close()
    assert [p.proc.returncode for p in procs] == [0] * len(procs), procs[0].output()


def test_killed_estimator_then_silent_controller(tmp_path):
    channel = bus_channel(50)
    car = Car(channel, driver_safe_a=0.3)      # the drivers' own safe current
    procs = _chain(tmp_path, channel, model_files(tmp_path), 0.05)
    bridge, estimator, controller = procs
    try:
        with Listener('vehicle_faults_test') as lis:
            diag = lis.diagnostics()
            for node in NODES:
                assert change_state(lis, node, 'configure') is True, node
            for node in NODES:
                assert change_state(lis, node, 'activate') is True, node
            assert lis.wait_for(lambda: any(all(f[c][1] == 0 for c in CORNERS)
                                            for f in command_frames(car.taken())[-5:]),
                                GUARD_S, procs=procs)
            # the estimator is killed: the controller's sensor timeout, every corner safe
            entries0 = diag.values('vehicle_controller').get('deadline', {}).get(
                'entries', {}).get('sensor_timeout', 0)
            estimator.proc.send_signal(signal.SIGKILL)
            estimator.proc.wait(30)
            n_kill = len(car.taken())

            def timed_out():
                d = diag.values('vehicle_controller').get('deadline', {})
                taken = car.taken()
                return d.get('entries', {}).get('sensor_timeout', 0) > entries0 and \
                    len(taken) > n_kill + 4 * 20 and \
                    any(safe_of_no_cycle(f) for f in command_frames(taken[n_kill:]))
            assert lis.wait_for(timed_out, GUARD_S, procs=(bridge, controller))
            after = command_frames(car.taken()[n_kill:])
            # the sensor timeout's first safe frame (of no cycle), then no law frame: a state
            # that reaches the controller late (sent before the kill) is skipped, not answered
            k = [safe_of_no_cycle(f) for f in after].index(True)
            assert all(all_safe(f) for f in after[k:]), after[k - 3:]
            assert diag.values('vehicle_controller')['all_safe']['sensor_timeout'] >= 1
            # the controller falls silent: nothing is sent in its name, the drivers time out
            n_stop = drivers_time_out_while_stopped(lis, car, controller.proc, 0.3)
            # it goes on: its (safe, sensor-timeout) commands reach the drivers again
            assert lis.wait_for(lambda: len(car.taken()) > n_stop + 4 * 5, GUARD_S,
                                procs=(bridge, controller))
            bridge_st = diag.values('vehicle_bridge')
            assert bridge_st['cycles']['safe_frames'] > 0        # while it was inactive
    finally:
        for p in procs:
            p.stop()
        car.close()
    assert bridge.proc.returncode == 0 and controller.proc.returncode == 0
