"""The bridge core: commands encoded and clamped, frames checked, faults counted, fail-safe."""
import math
import time

import can
import pytest

from fake_clock import FakeClock
from mr_damper_can import codec
from mr_damper_can.bridge import BridgeHealth, CanBridge
from mr_damper_can.codec import FrameCodec
from mr_damper_can.driver_sim import SimulatedEcu
from mr_damper_common.health import ERROR, OK, WARN

DB = codec.load_database()


def _msg(frame_id, data, **kw):
    return can.Message(arbitration_id=frame_id, data=data, is_extended_id=False, **kw)


def _pair(clock, corners=('fl',), **kw):
    """Return a bridge and a simulated ECU without a bus (frames handed over by `_pump`)."""
    bridge = CanBridge(None, corners, db=DB, clock=clock, **kw)
    ecu = SimulatedEcu(None, corners, db=DB, clock=clock, tau_s=0.01)
    return bridge, ecu


def _pump(bridge, ecu):
    """Deliver the frames each side sent to the other; return how many went each way."""
    down, bridge.sent = bridge.sent, []
    for frame_id, data in down:
        ecu.on_frame(_msg(frame_id, data))
    up, ecu.sent = ecu.sent, []
    for msg in up:
        bridge.on_frame(msg)
    return len(down), len(up)


def _sent_values(frames):
    dec = FrameCodec(DB)
    return [dec.decode(f, d).values for f, d in frames]


def test_each_command_is_one_frame_with_counter_and_checksum():
    clock = FakeClock()
    bridge = CanBridge(None, ('fl', 'rr'), db=DB, clock=clock)
    currents = [0.0, 0.01, 1.234, 2.55, 0.5] * 5
    for k, i in enumerate(currents):
        clock.t += 0.001
        assert bridge.command('fl' if k % 2 else 'rr', i) == 'accepted'
    assert len(bridge.sent) == len(currents)
    ids = [f for f, _ in bridge.sent]
    assert ids.count(0x110) == 12 and ids.count(0x113) == 13
    values = _sent_values(bridge.sent)       # a fresh decoder: no counter jump, no bad CRC
    assert [v['CMD_CURRENT'] for v in values] == pytest.approx([round(i, 2) for i in currents])
    assert all(v['CMD_FAILSAFE'] == 0 for v in values)
    assert [v['COUNTER'] for v, f in zip(values, ids) if f == 0x110] == list(range(12))
    st = bridge.status()
    assert st['corners']['fl']['commands'] == 12 and st['corners']['fl']['frames_sent'] == 12
    assert st['commands'] == {'accepted': 25, 'clamped_low': 0, 'clamped_high': 0,
                              'refused_non_finite': 0}


def test_commands_outside_the_dbc_range_never_leave_the_bridge():
    clock = FakeClock()
    bridge = CanBridge(None, ('fl',), db=DB, clock=clock)
    outcomes = [bridge.command('fl', i) for i in (3.7, -0.4, 1e9, -math.inf, math.nan, 1.0)]
    assert outcomes == ['clamped_high', 'clamped_low', 'clamped_high', 'refused_non_finite',
                        'refused_non_finite', 'accepted']
    assert [v['CMD_CURRENT'] for v in _sent_values(bridge.sent)] == pytest.approx(
        [2.55, 0.0, 2.55, 1.0])             # inf, NaN: no frame, the previous command stays
    assert bridge.status()['commands'] == {'accepted': 1, 'clamped_low': 1, 'clamped_high': 2,
                                           'refused_non_finite': 2}
    health = BridgeHealth()(bridge.status())
    assert health.level == WARN and 'commands outside the DBC range' in health.message


@pytest.mark.parametrize('safe', [0.0, 2.55])
def test_fail_safe_polarity_is_a_parameter_and_checked(safe):
    clock = FakeClock()
    bridge = CanBridge(None, ('fl',), db=DB, clock=clock, safe_current_a=safe)
    assert bridge.tick() == 1                # no command yet: the safe current, flagged
    (v,) = _sent_values(bridge.sent)
    assert v['CMD_CURRENT'] == pytest.approx(safe) and v['CMD_FAILSAFE'] == 1
    assert bridge.status()['corners']['fl']['reason'] == 'no_command_yet'
    with pytest.raises(ValueError, match='safe_current_a'):
        CanBridge(None, ('fl',), db=DB, safe_current_a=2.6)
    assert 'DBC range' in bridge.reconfigure(safe_current_a=-0.1)
    assert bridge.safe_current_a == safe


def test_command_timeout_puts_the_corner_in_fail_safe_and_back():
    clock = FakeClock()
    bridge, ecu = _pair(clock, safe_current_a=0.3, command_timeout_s=0.05,
                        rx_timeout_s=10.0, resend_period_s=0.01)
    for _ in range(10):
        clock.t += 0.001
        bridge.command('fl', 1.5)
        ecu.step()
        _pump(bridge, ecu)
    st = bridge.status()['corners']['fl']
    assert st['mode'] == 'normal' and st['failsafe_entries'] == 1     # the start
    clock.t += 0.06                          # the controller stops
    bridge.tick()
    st = bridge.status()['corners']['fl']
    assert (st['mode'], st['reason'], st['sent_a']) == ('failsafe', 'command_timeout', 0.3)
    assert st['failsafe_entries'] == 2 and st['resent'] == 1
    assert _sent_values(bridge.sent)[-1]['CMD_FAILSAFE'] == 1
    _pump(bridge, ecu)
    assert ecu.status()['corners']['fl']['target_a'] == pytest.approx(0.3)
    clock.t += 0.004
    bridge.tick()                            # re-sent only after resend_period_s
    assert bridge.status()['corners']['fl']['resent'] == 1
    clock.t += 0.006
    bridge.tick()
    assert bridge.status()['corners']['fl']['resent'] == 2
    bridge.command('fl', 1.0)                # the controller is back
    st = bridge.status()['corners']['fl']
    assert (st['mode'], st['sent_a'], st['failsafe_entries']) == ('normal', 1.0, 2)
    assert st['failsafe_s'] == pytest.approx(0.001 + 0.01)   # start, then from the tick on


def test_driver_fault_puts_the_corner_in_fail_safe_until_cleared():
    clock = FakeClock()
    bridge, ecu = _pair(clock, ('fl', 'fr'), safe_current_a=0.2, rx_timeout_s=10.0)
    driver_seen = []
    bridge.on_driver = driver_seen.append
    for corner in ('fl', 'fr'):
        bridge.command(corner, 2.0)
    ecu.step()
    _pump(bridge, ecu)
    ecu.inject('fr', 'overtemp')
    clock.t += 0.002
    ecu.step()
    _pump(bridge, ecu)
    st = bridge.status()
    assert st['corners']['fl']['mode'] == 'normal'
    fr = st['corners']['fr']
    assert (fr['mode'], fr['reason'], fr['driver_faults']) == ('failsafe', 'driver_fault',
                                                               'overtemp')
    assert fr['driver_state'] == codec.DRV_FAULT and fr['driver_fault_edges'] == {'overtemp': 1}
    assert driver_seen[-1].corner == 'fr' and driver_seen[-1].faults == ('overtemp',)
    bridge.command('fr', 2.0)                # the controller's command is replaced
    last = _sent_values(bridge.sent)[-1]
    assert (last['CMD_CURRENT'], last['CMD_FAILSAFE']) == (pytest.approx(0.2), 1)
    health = BridgeHealth()(st)
    assert health.level == ERROR and 'fr: driver fault (overtemp)' in health.message
    ecu.inject('fr', 'none')
    clock.t += 0.002
    ecu.step()
    _pump(bridge, ecu)
    bridge.command('fr', 2.0)
    assert bridge.status()['corners']['fr']['mode'] == 'normal'
    assert _sent_values(bridge.sent)[-1]['CMD_CURRENT'] == pytest.approx(2.0)


def test_link_flags_of_the_driver_are_counted_but_no_fail_safe():
    clock = FakeClock()
    bridge = CanBridge(None, ('fl',), db=DB, clock=clock, rx_timeout_s=10.0,
                       command_timeout_s=10.0)
    ecu = SimulatedEcu(None, ('fl',), db=DB, clock=clock, command_timeout_s=0.02)
    bridge.command('fl', 1.0)
    _pump(bridge, ecu)
    clock.t += 0.03                          # the driver's own timeout, not the bridge's
    ecu.step()
    _pump(bridge, ecu)
    st = bridge.status()['corners']['fl']
    assert st['driver_faults'] == 'cmd_timeout' and st['driver_fault_edges'] == {'cmd_timeout': 1}
    assert st['mode'] == 'normal'


@pytest.mark.parametrize('fault, counter', [('bad_checksum', 'bad_checksum'),
                                            ('bad_counter', 'bad_counter'),
                                            ('unknown_id', 'unknown_id'),
                                            ('error_frame', 'error_frame'),
                                            ('bus_off', 'bus_off')])
def test_every_bus_fault_injected_is_counted(fault, counter):
    clock = FakeClock()
    bridge, ecu = _pair(clock, rx_timeout_s=10.0)
    bridge.command('fl', 1.0)
    for k in range(5):
        clock.t += 0.002
        if k == 2:
            ecu.inject('fl', fault)
        ecu.step()
        _pump(bridge, ecu)
    st = bridge.status()
    expected = dict.fromkeys(st['faults'], 0)
    expected[counter] = 1
    if fault == 'bad_counter':
        expected['frames_missed'] = 2
    if fault == 'bad_checksum':              # the refused frame is missing at the next one
        expected.update(bad_counter=1, frames_missed=1)
    assert st['faults'] == expected
    health = BridgeHealth()(st)
    assert health.level == WARN and counter in health.message
    if fault == 'bus_off':                   # the next valid frame: the bus is back
        assert st['bus_off'] is False and st['corners']['fl']['failsafe_entries'] == 2
    # the next status sees nothing new
    rules = BridgeHealth()
    rules(st)
    assert rules(bridge.status()).level == OK


def test_bus_off_is_fail_safe_while_it_lasts():
    clock = FakeClock()
    bridge = CanBridge(None, ('fl',), db=DB, clock=clock, rx_timeout_s=10.0)
    bridge.command('fl', 1.0)
    bridge.on_frame(_msg(codec.CAN_ERR_BUSOFF, bytes(8), is_error_frame=True))
    st = bridge.status()
    assert st['bus_off'] and st['corners']['fl']['reason'] == 'bus_off'
    assert BridgeHealth()(st).level == ERROR


def test_missing_cyclic_frames_are_timeouts_once_per_outage():
    clock = FakeClock()
    bridge, ecu = _pair(clock, rx_timeout_s=0.02, command_timeout_s=10.0)
    bridge.command('fl', 1.0)
    for _ in range(5):
        clock.t += 0.002
        ecu.step()
        _pump(bridge, ecu)
        bridge.tick()
    assert bridge.status()['faults']['timeout'] == 0
    ecu.inject('fl', 'silent', silence_s=0.05)       # the driver's status stops for 50 ms
    for _ in range(40):
        clock.t += 0.002
        ecu.step()
        _pump(bridge, ecu)
        bridge.tick()
        if bridge.status()['corners']['fl']['reason'] == 'driver_timeout':
            break
    st = bridge.status()
    assert st['faults']['timeout'] == 1 and st['timeouts'] == {'DAMPER_STATUS_FL': 1}
    assert st['corners']['fl']['mode'] == 'failsafe'
    for _ in range(40):                      # the status comes back: normal again
        clock.t += 0.002
        ecu.step()
        _pump(bridge, ecu)
        bridge.tick()
    bridge.command('fl', 1.0)
    st = bridge.status()
    assert st['faults']['timeout'] == 1 and st['corners']['fl']['mode'] == 'normal'
    # the sensor cluster never sent anything (sensor frames went to the bridge, every one):
    assert 'CHASSIS_BODY_ACCEL' not in st['timeouts']


def test_sensor_frames_decode_to_the_known_synthetic_values():
    clock = FakeClock()
    bridge, ecu = _pair(clock, ('fl', 'fr', 'rl', 'rr'), rx_timeout_s=10.0)
    got = []
    bridge.on_sensors = lambda quantity, values, t: got.append((quantity, values))
    ecu.step()
    _pump(bridge, ecu)
    assert [q for q, _ in got] == ['body_accel', 'wheel_accel', 'susp_pos']
    from mr_damper_can.driver_sim import synthetic_sensors
    for quantity, values in got:
        step = {'body_accel': 0.01, 'wheel_accel': 0.1, 'susp_pos': 0.0001}[quantity]
        for corner, value in values.items():
            truth = synthetic_sensors(0.0, corner)[quantity]
            assert value == pytest.approx(truth, abs=step / 2 + 1e-12), (quantity, corner)
    ecu.set_sensors('rl', 25.0, -3.0, 0.5)     # out of the DBC range: clamped by the sensor
    ecu.step(clock.t + 0.002)
    _pump(bridge, ecu)
    last = {q: v for q, v in got[-3:]}
    assert last['body_accel']['rl'] == pytest.approx(20.47)
    assert last['wheel_accel']['rl'] == pytest.approx(-3.0)
    assert last['susp_pos']['rl'] == pytest.approx(0.2047)


def test_bridge_and_driver_over_a_virtual_bus_lose_nothing():
    # threads and python-can's virtual bus: every command reaches the driver, in order
    channel = f'test_bridge_{time.monotonic_ns()}'
    bus_a = can.Bus(interface='virtual', channel=channel)
    bus_b = can.Bus(interface='virtual', channel=channel)
    seen = []
    ecu = SimulatedEcu(bus_b, ('fl', 'fr'), command_timeout_s=10.0,
                       on_command=lambda *a: seen.append(a[:3]))
    measured = []
    bridge = CanBridge(bus_a, ('fl', 'fr'), rx_timeout_s=10.0, command_timeout_s=10.0,
                       resend_period_s=10.0, on_driver=measured.append)
    try:
        ecu.start()
        bridge.start()
        values = [round(0.01 * (k % 200), 2) for k in range(500)]
        for value in values:
            bridge.command('fl', value)
        bridge.command('fr', 1.7)
        end = time.monotonic() + 30.0
        while time.monotonic() < end and (len(seen) < 501 or not any(
                m.corner == 'fr' and abs(m.current_a - 1.7) < 0.002 for m in measured)):
            time.sleep(0.01)
    finally:
        bridge.stop()
        ecu.stop()
        bus_a.shutdown()
        bus_b.shutdown()
    fl = [s for s in seen if s[0] == 'fl']
    assert [s[1] for s in fl] == pytest.approx(values)
    assert [s[2] for s in fl] == [k % 16 for k in range(500)]
    st = ecu.status()['corners']['fl']
    assert (st['received'], st['counter_jumps'], st['bad_checksum']) == (500, 0, 0)
    assert bridge.status()['faults']['bad_checksum'] == 0
    assert any(m.corner == 'fr' and abs(m.current_a - 1.7) < 0.002 for m in measured)


def _logged_exchange(log, commands, statuses):
    """Bridge and driver on a virtual bus, the bridge logging to ``log``; return the bridge."""
    channel = f'test_bridge_log_{time.monotonic_ns()}'
    with can.Bus(interface='virtual', channel=channel) as bus_a, \
            can.Bus(interface='virtual', channel=channel) as bus_b:
        got = []
        bridge = CanBridge(bus_a, ('fl',), rx_timeout_s=10.0, command_timeout_s=10.0,
                           resend_period_s=10.0, on_driver=got.append)
        ecu = SimulatedEcu(bus_b, ('fl',), sensors=False)
        try:
            bridge.start(log_file=str(log))
            for value in commands:
                bridge.command('fl', value)
            for k in range(statuses):
                ecu.step(0.01 * k)                # one driver status frame each
            end = time.monotonic() + 30.0       # a hang guard only
            while len(got) < statuses and time.monotonic() < end:
                time.sleep(0.01)
        finally:
            bridge.stop()
    assert len(got) == statuses
    return bridge


def test_the_frame_log_holds_both_directions_on_a_bus_without_own_frames(tmp_path):
    # python-can's virtual bus, like socketcan, gives a bus none of its own frames: the log
    # has the commands because the bridge writes what it sends, not what comes back
    log = tmp_path / 'frames.asc'
    values = [0.05 * k for k in range(20)]
    bridge = _logged_exchange(log, values, 5)
    frames = list(can.ASCReader(str(log)))
    cmd_id = DB.get_message_by_name(codec.command_name('fl')).frame_id
    status_id = DB.get_message_by_name(codec.status_name('fl')).frame_id
    sent = [m for m in frames if m.arbitration_id == cmd_id]
    received = [m for m in frames if m.arbitration_id == status_id]
    assert bridge.own_frames == 0 and bridge.log_errors == 0
    assert len(sent) == 20 and not any(m.is_rx for m in sent)
    assert len(received) == 5 and all(m.is_rx for m in received)
    # a sent frame carries its time (the log's writer: relative to its first frame)
    stamps = [m.timestamp for m in sent]
    assert stamps == sorted(stamps) and stamps[-1] > stamps[0]
    dec = FrameCodec(DB)
    assert [dec.decode(m.arbitration_id, m.data).values['CMD_CURRENT'] for m in sent] == \
        pytest.approx(values)


def test_a_frame_log_that_fails_is_counted_and_the_bus_goes_on(tmp_path):
    # the BLF writer cannot write the virtual bus's text channel: every status frame still
    # reaches the bridge (the helper asserts it), each refusal of the log is counted
    st = _logged_exchange(tmp_path / 'frames.blf', [], 3).status()
    assert st['log_errors'] == 3 and 'ushort format' in st['log_error']
    h = BridgeHealth()(st)
    assert h.level == WARN and '3 frames the frame log refused' in h.message


def test_a_frame_whose_handling_raises_is_counted_and_the_reader_goes_on():
    # the driver callback raises on the second status frame: the reader takes the third and
    # fourth (python-can's Notifier would end its thread), the health names the error
    channel = f'test_bridge_raise_{time.monotonic_ns()}'
    with can.Bus(interface='virtual', channel=channel) as bus_a, \
            can.Bus(interface='virtual', channel=channel) as bus_b:
        got = []

        def on_driver(status):
            got.append(status)
            if len(got) == 2:
                raise ZeroDivisionError('a bug in a callback')
        bridge = CanBridge(bus_a, ('fl',), rx_timeout_s=10.0, command_timeout_s=10.0,
                           resend_period_s=10.0, on_driver=on_driver)
        ecu = SimulatedEcu(bus_b, ('fl',), sensors=False)
        health = BridgeHealth()
        try:
            bridge.start()
            for k in range(4):
                ecu.step(0.01 * k)
            end = time.monotonic() + 30.0       # a hang guard only
            while len(got) < 4 and time.monotonic() < end:
                time.sleep(0.01)
        finally:
            bridge.stop()
    st = bridge.status()
    assert len(got) == 4
    assert st['frame_errors'] == 1
    assert st['frame_error'] == 'ZeroDivisionError: a bug in a callback'
    h = health(st)
    assert h.level == ERROR and '1 frames whose handling raised' in h.message
    assert 'frames whose handling raised' not in health(bridge.status()).message    # once


def test_the_bridges_reader_runs_at_the_priority_asked_for():
    """The frames are taken in the reader thread, under SCHED_FIFO there (or a refusal said)."""
    import os
    import threading
    channel = f'test_bridge_prio_{time.monotonic_ns()}'
    with can.Bus(interface='virtual', channel=channel) as bus_a, \
            can.Bus(interface='virtual', channel=channel) as bus_b:
        bridge = CanBridge(bus_a, ('fl',), rx_timeout_s=10.0, command_timeout_s=10.0)
        ecu = SimulatedEcu(bus_b, ('fl',), sensors=False)
        taken = []
        done = threading.Event()
        on_frame = bridge.on_frame

        def take(msg):
            taken.append((os.sched_getscheduler(0), os.sched_getparam(0).sched_priority))
            on_frame(msg)
            done.set()
        bridge.on_frame = take
        try:
            bridge.start(reader_priority=9)
            ecu.step(0.0)                         # the driver's status frame on the bus
            assert done.wait(30.0)                # a hang guard only
        finally:
            bridge.stop()
        err = bridge.status()['reader_priority_error']
    assert taken[0] == ((os.SCHED_FIFO, 9) if err is None else (os.SCHED_OTHER, 0))
    assert bridge.frames_received >= 1
