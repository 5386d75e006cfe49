"""
The vehicle computer in one loop (``vehicle_computer_node``) over real topics and the CAN bus.

A real node process (console script) and ``lifecycle_manager``; this test process plays the
car's side of the loopback bus (:class:`integration.vehicle_helpers.Car`). Assertions are on
the order and the counts of events (the waits are hang guards only, never a time budget):

- a transition out of order (activate an unconfigured node) is refused; the manager brings it
  up (``node_names: [vehicle_computer]``);
- with the ``rr`` record marked invalid, ``rr`` is commanded its safe current with the
  fail-safe bit in every frame while the other three corners follow the law; the node's one
  status holds the bridge's, the estimator's and the controller's;
- deactivation: the drivers are on the safe current at once, the first safe frame after it is
  followed only by safe frames, and the last command published is the deactivation's;
- activated again, then stopped (SIGSTOP): nothing is sent in its name, the drivers fall back
  on their own command timeout; when it goes on, its commands reach them again.
"""
import pytest

from integration.ros_helpers import Listener, NodeProcess
from integration.vehicle_helpers import (all_safe, bus_channel, Car, chain_up, change_state,
                                         command_frames, drivers_time_out_while_stopped, GUARD_S,
                                         model_files, normal_but_rr, SAFE_A)

pytestmark = [pytest.mark.integration, pytest.mark.slow]

NODE = 'vehicle_computer'


def test_loop_lifecycle_one_invalid_corner_deactivation_and_a_silent_computer(tmp_path):
    from mr_damper_interfaces.msg import FullCarCommand
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    channel = bus_channel(100)
    car = Car(channel, driver_safe_a=0.3)          # the drivers' own safe current
    computer = NodeProcess('vehicle_computer_node', params={
        'channel': channel, 'diagnostics_period_s': 0.2, 'heartbeat_period_s': 0.1,
        'model_files': model_files(tmp_path, invalid=('rr',)), 'safe_current_a': SAFE_A,
        'sensor_timeout_s': 30.0, 'max_consecutive_misses': 100000, 'dropout_s': 10.0})
    procs = [computer]
    try:
        with Listener('vehicle_computer_test') as lis:
            diag = lis.diagnostics()
            commands = lis.subscribe('vehicle/command', FullCarCommand, QoSProfile(
                depth=10, reliability=ReliabilityPolicy.RELIABLE))
            assert change_state(lis, NODE, 'activate') is False     # unconfigured: refused
            manager = NodeProcess('lifecycle_manager', params={
                'node_names': [NODE], 'diagnostics_period_s': 0.2, 'heartbeat_timeout_s': 5.0})
            procs.append(manager)

            assert lis.wait_for(chain_up(diag, car), GUARD_S, procs=procs), computer.output()
            # the three good corners follow the law: their currents move (an event: the law
            # may ask 0 A for a stretch of road)
            assert lis.wait_for(lambda: len({f['fl'][0] for f in command_frames(car.taken())
                                             if normal_but_rr(f)}) > 1, GUARD_S, procs=procs)
            frames = command_frames(car.taken())
            assert all(f['rr'] == (SAFE_A, 1) for f in frames)

            def counted():
                # a status published after the answered cycles (the one at hand may be older)
                st = diag.values(NODE) or {}
                return ((st.get('bridge') or {}).get('cycles', {}).get('answered', 0) > 0
                        and (st.get('estimator') or {}).get('steps', 0) > 0)

            assert lis.wait_for(counted, GUARD_S, procs=procs)
            st = diag.values(NODE)
            assert st['controller']['corners']['rr']['reason'] == 'invalid_flag'
            manager.stop()
            # deactivation: the safe current at once, then only safe frames
            n_before = len(car.taken())
            assert change_state(lis, NODE, 'deactivate') is True
            assert lis.wait_for(lambda: any(
                all_safe(f) for f in command_frames(car.taken()[n_before:])), GUARD_S,
                procs=procs[:1])
            n_deact = len(car.taken())
            # the bridge's safe frames while inactive (every safe_period_s): wait for 5 more
            assert lis.wait_for(lambda: len(car.taken()) >= n_deact + 4 * 5, GUARD_S,
                                procs=procs[:1])
            after = command_frames(car.taken()[n_before:])
            safe = [all_safe(f) for f in after]
            assert all(safe[safe.index(True):])
            assert lis.wait_for(lambda: commands and commands[-1][1].mode.tolist() == [
                FullCarCommand.MODE_INACTIVE] * 4, GUARD_S)
            assert list(commands[-1][1].reason) == ['inactive'] * 4
            # active again, then silent: nothing in its name, the drivers' own timeout
            assert change_state(lis, NODE, 'activate') is True
            n_act = len(car.taken())
            assert lis.wait_for(lambda: any(normal_but_rr(f) for f in command_frames(
                car.taken()[n_act:])), GUARD_S, procs=procs[:1])
            n_stop = drivers_time_out_while_stopped(lis, car, computer.proc, 0.3)
            assert lis.wait_for(lambda: len(car.taken()) > n_stop + 4 * 5, GUARD_S,
                                procs=procs[:1])
    finally:
        for p in procs:
            p.stop()
        car.close()
    assert computer.proc.returncode == 0, computer.output()
