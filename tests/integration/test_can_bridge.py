"""
The CAN bridge node and the simulated damper driver in two processes over the loopback UDP bus.

Real node processes (console scripts), LOCALHOST discovery and the private domain of
tests/conftest.py; the CAN bus is ``udp_loopback`` (the loopback device only) on a port of this
test's own. Assertions are on counts and the order of events; the waits are hang guards.

1. Commands at a few hundred Hz (the test paces by the bridge's reported count, so a starved
   bridge is waited for, never overrun): every command reaches the bridge, becomes one frame,
   and every frame the bridge sent reaches the driver with no counter jump and no bad checksum
   (0 lost); the last command's value is what the driver holds, and the driver's measured
   current comes back on ``mr_damper/measured_current``.
2. A driver fault injected in the driver process (``open_load``): the bridge's ``/diagnostics``
   go to ERROR with the corner in fail-safe (``driver_fault``), the next command reaches the
   driver as the bridge's safe current with the fail-safe bit; the fault cleared, the corner is
   normal again at the next command.
3. Bus faults injected in the driver process (unknown id, bad checksum, counter jump, error
   frame, bus-off): each counted by the bridge, and nothing else.
4. Both processes exit 0 on SIGINT.
"""
import os
import time

import pytest

from integration.ros_helpers import Listener, NodeProcess

pytestmark = [pytest.mark.integration, pytest.mark.slow]

GUARD_S = 60.0
SAFE_A = 0.37
N_COMMANDS = 600
CHUNK = 50
BRIDGE, SIM = 'can_bridge', 'can_driver_sim'


def _values(k):
    """Return the k-th command [A]: a ramp over the DBC range, on its 10-mA grid."""
    return round(0.01 * (k % 256), 2)


def test_bridge_and_simulated_driver_across_processes(tmp_path):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64, String
    channel = f'239.74.163.2:{43200 + int(os.environ["ROS_DOMAIN_ID"])}'
    bus = {'interface': 'udp_loopback', 'channel': channel, 'corners': 'fl',
           'diagnostics_period_s': 0.1}
    log = tmp_path / 'run.blf'
    sim = NodeProcess('can_driver_sim', params=dict(bus, tau_s=0.005, command_timeout_s=3600.0,
                                                    sensor_source='none'))
    bridge = NodeProcess('can_bridge_node', params=dict(
        bus, safe_current_a=SAFE_A, command_timeout_s=3600.0, rx_timeout_s=3600.0,
        resend_period_s=10.0, log_file=str(log)))
    procs = (sim, bridge)
    with sim, bridge, Listener('can_bridge_test') as lis:
        diag = lis.diagnostics()
        measured = lis.subscribe('mr_damper/measured_current', Float64,
                                 QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        pub = lis.publisher('mr_damper/current_command', Float64,
                            QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1000,
                                       reliability=ReliabilityPolicy.RELIABLE))
        faults = lis.publisher('can_driver_sim/inject_fault', String)

        def br():
            return diag.values(BRIDGE)

        def fl():
            return br().get('corners', {}).get('fl', {})

        def drv():
            return diag.values(SIM).get('corners', {}).get('fl', {})

        assert lis.wait_for(lambda: pub.get_subscription_count() >= 1
                            and faults.get_subscription_count() >= 1
                            and fl().get('status_frames', 0) > 0 and drv(), GUARD_S,
                            procs=procs), bridge.output() + sim.output()
        # before any command the bridge sends its safe current, flagged
        assert fl()['reason'] == 'no_command_yet'
        assert lis.wait_for(lambda: drv().get('failsafe_bit') == 1, GUARD_S, procs=procs)
        assert drv()['target_a'] == pytest.approx(SAFE_A)

        # 1. N commands, paced by the bridge's count
        for k in range(N_COMMANDS):
            pub.publish(Float64(data=_values(k)))
            if (k + 1) % CHUNK == 0:
                assert lis.wait_for(lambda: fl().get('commands', 0) >= k + 1, GUARD_S,
                                    poll=0.01, procs=procs), bridge.output()
            else:
                time.sleep(1.0 / 300.0)     # a few hundred Hz (not asserted)
        last = _values(N_COMMANDS - 1)
        # the driver has heard every frame the bridge sent: equal counts in a pair of statuses
        # taken after the last command (a keep-alive re-send comes only every 10 s)
        assert lis.wait_for(lambda: fl()['commands'] == N_COMMANDS
                            and drv().get('received') == fl().get('frames_sent')
                            and drv()['target_a'] == pytest.approx(last), GUARD_S,
                            procs=procs), (fl(), drv())
        st, d = fl(), drv()
        assert st['commands'] == N_COMMANDS
        assert st['frames_sent'] - st['resent'] == N_COMMANDS    # one frame per command
        assert br()['commands']['accepted'] == N_COMMANDS
        assert (d['counter_jumps'], d['frames_missed'], d['bad_checksum'], d['repeated']) == \
            (0, 0, 0, 0)
        assert br().get('dropped', {}) == {} and st['mode'] == 'normal'
        assert sum(br()['faults'].values()) == 0, br()['faults']
        # the measured current comes back on the ROS topic and settles on the command
        assert lis.wait_for(lambda: measured and abs(measured[-1][1].data - last) < 0.002,
                            GUARD_S, procs=procs), measured[-5:]

        # 2. a driver fault -> fail-safe in /diagnostics; the driver gets the safe current
        faults.publish(String(data='fl:open_load'))
        assert lis.wait_for(lambda: fl().get('reason') == 'driver_fault', GUARD_S, procs=procs)
        assert lis.wait_for(lambda: diag.latest(BRIDGE).level == 2, GUARD_S, procs=procs)
        assert 'open_load' in diag.latest(BRIDGE).message
        assert fl()['driver_faults'] == 'open_load' and fl()['failsafe_entries'] == 2
        pub.publish(Float64(data=2.0))
        assert lis.wait_for(lambda: drv().get('failsafe_bit') == 1
                            and drv()['target_a'] == pytest.approx(SAFE_A), GUARD_S,
                            procs=procs), drv()
        faults.publish(String(data='fl:none'))
        assert lis.wait_for(lambda: fl().get('driver_faults') == '', GUARD_S, procs=procs)
        pub.publish(Float64(data=2.0))
        assert lis.wait_for(lambda: fl().get('mode') == 'normal'
                            and drv().get('target_a') == pytest.approx(2.0), GUARD_S,
                            procs=procs), (fl(), drv())
        assert fl()['failsafe_entries'] == 2

        # 3. bus faults injected in the driver process, each counted once by the bridge
        for fault in ('unknown_id', 'bad_checksum', 'bad_counter', 'error_frame', 'bus_off'):
            faults.publish(String(data=f'fl:{fault}'))
            assert lis.wait_for(lambda: br()['faults'][fault] >= 1, GUARD_S, procs=procs), \
                (fault, br()['faults'])
        # (the frame refused for its checksum shows as one frame missed at the next one)
        expected = dict(br()['faults'], unknown_id=1, bad_checksum=1, bad_counter=2,
                        frames_missed=3, error_frame=1, bus_off=1)
        assert br()['faults'] == expected and sum(expected.values()) == 9
        assert lis.wait_for(lambda: br().get('bus_off') is False, GUARD_S, procs=procs)
    # 4. clean exits, and the frame log is readable
    assert bridge.proc.returncode == 0, bridge.output()
    assert sim.proc.returncode == 0, sim.output()
    import can
    frames = list(can.BLFReader(str(log)))
    ids = {m.arbitration_id for m in frames}
    assert {0x110, 0x120} <= ids
    assert sum(m.arbitration_id == 0x110 for m in frames) >= N_COMMANDS
