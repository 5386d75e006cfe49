"""The simulated damper driver: first-order coil, its own command timeout, injected faults."""
import math

import can
import pytest

from fake_clock import FakeClock
from mr_damper_can import codec
from mr_damper_can.codec import FrameCodec
from mr_damper_can.driver_sim import SimulatedEcu

DB = codec.load_database()


def _command(enc, ecu, corner, value, failsafe=0):
    frame_id, data = enc.encode(codec.command_name(corner),
                                {'CMD_CURRENT': value, 'CMD_FAILSAFE': failsafe})
    ecu.on_frame(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False))


def _statuses(ecu, corner='fl'):
    dec = FrameCodec(DB)
    frame_id = DB.get_message_by_name(codec.status_name(corner)).frame_id
    return [dec.decode(m.arbitration_id, m.data).values for m in ecu.sent
            if m.arbitration_id == frame_id]


def _send_commands(bus, currents_a, corner='fl'):
    """Send one command frame of ``corner`` per current [A] on ``bus``, in order."""
    enc = FrameCodec(DB)
    for current in currents_a:
        frame_id, data = enc.encode(codec.command_name(corner),
                                    {'CMD_CURRENT': current, 'CMD_FAILSAFE': 0})
        bus.send(can.Message(arbitration_id=frame_id, data=data, is_extended_id=False))


def test_coil_follows_a_step_with_a_first_order_lag():
    clock = FakeClock(50.0)
    tau = 0.02
    ecu = SimulatedEcu(None, ('fl',), db=DB, clock=clock, tau_s=tau, command_timeout_s=1.0,
                       sensors=False)
    enc = FrameCodec(DB)
    ecu.step()
    for _ in range(50):                       # 100 ms at the 2-ms status period
        _command(enc, ecu, 'fl', 2.0)
        clock.t += 0.002
        ecu.step()
    got = [v['MEAS_CURRENT'] for v in _statuses(ecu)]
    truth = [2.0 * (1.0 - math.exp(-0.002 * k / tau)) for k in range(51)]
    assert got == pytest.approx(truth, abs=0.0005 + 1e-9)    # the 1-mA resolution
    assert _statuses(ecu)[-1]['DRV_STATE'] == codec.DRV_NORMAL


def test_driver_timeout_falls_back_to_its_safe_current():
    clock = FakeClock(50.0)
    ecu = SimulatedEcu(None, ('fl',), db=DB, clock=clock, tau_s=0.001, safe_current_a=0.4,
                       command_timeout_s=0.05, sensors=False)
    enc = FrameCodec(DB)
    _command(enc, ecu, 'fl', 1.5)
    clock.t += 0.02
    ecu.step()
    assert _statuses(ecu)[-1]['MEAS_CURRENT'] == pytest.approx(1.5, abs=0.001)
    clock.t += 0.05
    ecu.step()
    last = _statuses(ecu)[-1]
    assert last['MEAS_CURRENT'] == pytest.approx(0.4, abs=0.001)
    assert (last['FLT_CMD_TIMEOUT'], last['DRV_STATE']) == (1, codec.DRV_FAILSAFE)


def test_bad_command_frames_are_refused_and_counted():
    clock = FakeClock(50.0)
    ecu = SimulatedEcu(None, ('fl',), db=DB, clock=clock, sensors=False)
    enc = FrameCodec(DB)
    _command(enc, ecu, 'fl', 1.0)
    frame_id, data = enc.encode('DAMPER_CMD_FL', {'CMD_CURRENT': 2.0, 'CMD_FAILSAFE': 0})
    ecu.on_frame(can.Message(arbitration_id=frame_id, data=data[:-1] + b'\x00',
                             is_extended_id=False))
    enc.encode('DAMPER_CMD_FL', {'CMD_CURRENT': 0.0, 'CMD_FAILSAFE': 0})   # never sent
    _command(enc, ecu, 'fl', 0.7)
    st = ecu.status()['corners']['fl']
    assert (st['received'], st['bad_checksum'], st['counter_jumps'], st['frames_missed']) == \
        (2, 1, 1, 2)
    assert st['target_a'] == pytest.approx(0.7)
    ecu.step()
    assert _statuses(ecu)[-1]['FLT_CMD_INVALID'] == 1
    clock.t += 0.002
    ecu.step()
    assert _statuses(ecu)[-1]['FLT_CMD_INVALID'] == 0


@pytest.mark.parametrize('fault', ['open_load', 'short', 'overcurrent', 'overtemp',
                                   'undervoltage'])
def test_driver_faults_switch_the_channel_off_and_are_reported(fault):
    clock = FakeClock(50.0)
    ecu = SimulatedEcu(None, ('fl', 'fr'), db=DB, clock=clock, tau_s=0.001, sensors=False)
    enc = FrameCodec(DB)
    _command(enc, ecu, 'fl', 2.0)
    ecu.inject('fl', fault)
    clock.t += 0.02
    ecu.step()
    last = _statuses(ecu)[-1]
    assert last[f'FLT_{fault.upper()}'] == 1 and last['DRV_STATE'] == codec.DRV_FAULT
    assert last['MEAS_CURRENT'] == pytest.approx(0.0, abs=0.001)
    assert sum(last[s] for s in codec.FAULT_SIGNALS) == 1
    assert _statuses(ecu, 'fr')[-1]['DRV_STATE'] != codec.DRV_FAULT
    with pytest.raises(ValueError, match='unknown fault'):
        ecu.inject('fl', 'gremlins')
    with pytest.raises(ValueError, match='unknown corner'):
        ecu.inject('rr', 'none')


def test_stop_with_drain_takes_the_frames_still_queued():
    # frames sent before the stop but not yet read (no reader running) are counted by the stop
    channel = 'driver_sim_drain_test'
    with can.Bus(interface='virtual', channel=channel) as ecu_bus, \
            can.Bus(interface='virtual', channel=channel) as bridge_bus:
        ecu = SimulatedEcu(ecu_bus, ('fl',), db=DB, clock=FakeClock(50.0), sensors=False)
        _send_commands(bridge_bus, [0.01 * k for k in range(25)])
        ecu.stop()                                   # no drain: nothing taken
        assert ecu.status()['corners']['fl']['received'] == 0
        ecu.stop(drain=True)
        st = ecu.status()['corners']['fl']
        assert (st['received'], st['counter_jumps'], st['bad_checksum']) == (25, 0, 0)
        assert st['target_a'] == pytest.approx(0.24)


def test_the_reader_thread_runs_at_the_priority_asked_for_and_a_refusal_is_kept():
    """The reader's policy is set in its own thread on its first frame; every frame taken."""
    import os
    import threading
    channel = 'driver_sim_priority_test'
    with can.Bus(interface='virtual', channel=channel) as ecu_bus, \
            can.Bus(interface='virtual', channel=channel) as bridge_bus:
        ecu = SimulatedEcu(ecu_bus, ('fl',), db=DB, clock=FakeClock(50.0), sensors=False)
        seen = []
        done = threading.Event()
        take = ecu.on_frame

        def on_frame(msg):                  # what the reader thread runs, and under what
            seen.append((threading.get_native_id(),
                         (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)))
            take(msg)
            if len(seen) == 3:
                done.set()
        ecu.on_frame = on_frame
        ecu.start(cycle=False, reader_priority=7)
        _send_commands(bridge_bus, [0.1 * k for k in range(3)])
        assert done.wait(30.0), seen               # a hang guard only
        ecu.stop()
    tids = {tid for tid, _ in seen}
    assert len(tids) == 1 and threading.get_native_id() not in tids
    assert ecu.status()['corners']['fl']['received'] == 3
    err = ecu.status()['reader_priority_error']
    if err is None:                              # allowed (root): FIFO, at the priority
        assert {policy for _, policy in seen} == {(os.SCHED_FIFO, 7)}
        assert os.sched_getscheduler(0) != os.SCHED_FIFO     # the test's thread untouched
    else:                                        # not allowed: said, normal scheduling
        assert {policy for _, policy in seen} == {(os.SCHED_OTHER, 0)}
