"""The vehicle bridge core: sensor cycles assembled and numbered, one command frame, lifecycle."""
import math

import can
import numpy as np
import pytest

from fake_clock import FakeClock
from mr_damper_can import codec
from mr_damper_can.driver_sim import SimulatedEcu, synthetic_sensors
from mr_damper_can.vehicle_bridge import (MISSING_BODY_ACCEL, MISSING_WHEEL_ACCEL,
                                          VehicleBridge)

DB = codec.load_database()
CYCLE = 0.002


def _msg(frame_id, data, **kw):
    return can.Message(arbitration_id=frame_id, data=data, is_extended_id=False, **kw)


class Rig:
    """A vehicle bridge and a simulated ECU handing their frames over by hand."""

    def __init__(self, **kw):
        self.clock = FakeClock(100.0)
        self.wall = FakeClock(1.7e9)
        self.cycles = []
        self.bridge = VehicleBridge(None, cycle_s=CYCLE, db=DB, clock=self.clock,
                                    wall=self.wall, on_cycle=self.cycles.append, **kw)
        self.ecu = SimulatedEcu(None, codec.CORNERS, db=DB, clock=self.clock, tau_s=0.01,
                                safe_current_a=0.0, command_timeout_s=0.02,
                                status_period_s=0.01, sensor_period_s=CYCLE)
        self.drop = set()

    def step(self, dt=CYCLE):
        """Advance both clocks, run the ECU, deliver its frames (but those in ``drop``)."""
        self.clock.t += dt
        self.wall.t += dt
        self.ecu.step()
        up, self.ecu.sent = self.ecu.sent, []
        for msg in up:
            name = DB.get_message_by_frame_id(msg.arbitration_id).name \
                if not msg.is_error_frame else ''
            if name in self.drop:
                self.drop.discard(name)
                continue
            self.bridge.on_frame(msg)
        self.bridge.tick()
        self.deliver()

    def deliver(self):
        down, self.bridge.sent = self.bridge.sent, []
        for frame_id, data in down:
            self.ecu.on_frame(_msg(frame_id, data))
        return down


def test_sensor_cycles_are_numbered_and_lost_frames_counted():
    rig = Rig()
    for _ in range(5):
        rig.step()
    assert [c.sequence for c in rig.cycles] == [1, 2, 3, 4, 5]
    c = rig.cycles[-1]
    t = rig.clock.t - rig.ecu.t0
    want = [synthetic_sensors(t, k) for k in codec.CORNERS]
    np.testing.assert_allclose(c.susp_pos, [w['susp_pos'] for w in want], atol=5e-5)
    np.testing.assert_allclose(c.body_accel, [w['body_accel'] for w in want], atol=5e-3)
    assert c.missing == 0 and c.t_bus == rig.wall.t
    rig.drop = {'CHASSIS_BODY_ACCEL'}
    rig.step()
    assert rig.cycles[-1].missing == MISSING_BODY_ACCEL
    assert np.isnan(rig.cycles[-1].body_accel).all()
    assert not np.isnan(rig.cycles[-1].susp_pos).any()
    rig.drop = {'CHASSIS_SUSP_POS'}
    rig.step()                                 # the cycle's end lost: no cycle
    rig.step()
    assert [c.sequence for c in rig.cycles[-2:]] == [6, 8]      # cycle 7 lost on the bus
    assert rig.cycles[-1].missing == 0
    st = rig.bridge.status()
    assert st['frames_lost'] == 2 and st['cycles']['cycles_missing_frames'] == 1
    assert MISSING_WHEEL_ACCEL == 2


def test_the_readers_cpu_per_cycle_is_counted_and_a_lost_cycle_shares_it():
    cpu = FakeClock(0.0)
    rig = Rig(cpu_clock=cpu)

    def on_cycle(c):                   # the loop the cycle runs: 0.3 ms of the reader's CPU
        rig.cycles.append(c)
        cpu.t += 3e-4
    rig.bridge.on_cycle = on_cycle
    for _ in range(6):
        cpu.t += 1e-4                  # the frames' reception and decoding
        rig.step()
    st = rig.bridge.status()['reader_cpu_s']
    # the first cycle starts the count: 5 intervals of 0.4 ms
    assert st['n'] == 5
    assert st['mean_s'] == pytest.approx(4e-4)
    rig.drop = {'CHASSIS_SUSP_POS'}   # cycle 7 lost: its CPU and cycle 8's shared by two
    cpu.t += 1e-4
    rig.step()
    cpu.t += 1e-4
    rig.step()
    assert [c.sequence for c in rig.cycles[-2:]] == [6, 8]
    st = rig.bridge.status()['reader_cpu_s']
    # after cycle 6's loop (0.3 ms), 0.1 + 0.1 ms of frames: 0.5 ms over two cycles
    assert st['n'] == 6
    assert st['max_s'] == pytest.approx(4e-4)
    assert st['mean_s'] == pytest.approx((5 * 4e-4 + 2.5e-4) / 6)


def test_inactive_bridge_forwards_nothing_and_keeps_the_drivers_on_the_safe_current():
    rig = Rig(safe_current_a=0.5)
    for _ in range(10):
        rig.step()
    assert rig.bridge.command_all([1.0] * 4, [False] * 4, 3) is None
    st = rig.bridge.status()
    # 20 ms inactive: a safe frame every safe_period_s (10 ms), the first at once
    assert st['cycles']['commands_inactive'] == 1 and st['cycles']['safe_frames'] == 2
    ecu = rig.ecu.status()['corners']
    assert all(ecu[c]['target_a'] == 0.5 and ecu[c]['failsafe_bit'] == 1 for c in ecu)
    assert all(st['corners'][c]['reason'] == 'inactive' for c in codec.CORNERS)


def test_active_bridge_one_frame_per_command_with_the_cycle_and_its_latency():
    rig = Rig(safe_current_a=0.5)
    rig.step()
    rig.bridge.activate()
    for k in range(6):
        rig.step()
        cycle = rig.cycles[-1].sequence
        rig.clock.t += 0.0005 if k < 4 else 0.003            # the last two answered late
        rig.wall.t += 0.0005 if k < 4 else 0.003
        assert rig.bridge.command_all([0.1 * k, 0.5, math.nan, 5.0], [False, False, False, True],
                                      cycle) is True
        frames = rig.deliver()
        assert len(frames) == 1 and frames[0][0] == 0x100
        values = codec.FrameCodec(DB).decode(*frames[0]).values
        assert values['SENSOR_CYCLE'] == cycle
    ecu = rig.ecu.status()
    ch = ecu['corners']
    assert ch['fl']['target_a'] == pytest.approx(0.5) and ch['fl']['failsafe_bit'] == 0
    assert ch['rl']['target_a'] == 0.5 and ch['rl']['failsafe_bit'] == 1      # NaN refused
    assert ch['rr']['target_a'] == pytest.approx(2.55) and ch['rr']['failsafe_bit'] == 1
    assert ecu['last_sensor_cycle'] == rig.cycles[-1].sequence
    st = rig.bridge.status()
    assert st['cycles']['answered'] == 6 and st['cycles']['answered_in_time'] == 4
    assert st['latency']['max_s'] == pytest.approx(0.003, abs=1e-6)   # wall clock: epoch
    assert st['commands']['refused_non_finite'] == 6 and st['commands']['clamped_high'] == 6
    # an answer to a cycle already answered, or unknown, is counted apart
    rig.bridge.command_all([0.5] * 4, [False] * 4, rig.cycles[-1].sequence)
    rig.bridge.command_all([0.5] * 4, [False] * 4, 10_000)
    st = rig.bridge.status()
    assert st['cycles']['answers_old'] == 1 and st['cycles']['answers_unknown_cycle'] == 1


def test_the_answered_fraction_counts_only_cycles_received_while_active_and_stays_within_one():
    rig = Rig(safe_current_a=0.5)
    rig.step()
    before = rig.cycles[-1].sequence             # received while inactive
    rig.bridge.activate()
    # the controller answers the cycle it had before the bridge went active: counted apart
    assert rig.bridge.command_all([0.5] * 4, [False] * 4, before) is True
    for _ in range(4):
        rig.step()
        st = rig.bridge.status()
        # the newest cycle is in flight until its answer comes
        assert st['unanswered'] == 0 and st['control_cycles'] == st['cycles']['answered']
        assert st['cycles']['cycles_active'] == st['control_cycles'] + 1
        rig.bridge.command_all([0.5] * 4, [False] * 4, rig.cycles[-1].sequence)
    st = rig.bridge.status()
    c = st['cycles']
    assert c['answers_inactive_cycle'] == 1 and c['answered'] == 4 == st['control_cycles']
    # every active cycle answered, the last one too: exactly 1, never above
    assert st['answered_fraction'] == 1.0 and st['unanswered'] == 0
    rig.step()
    rig.step()                                   # one left unanswered, one in flight
    st = rig.bridge.status()
    assert st['unanswered'] == 1 and st['answered_fraction'] == pytest.approx(4 / 5)


def test_deactivate_puts_every_corner_on_the_safe_current_at_once():
    rig = Rig(safe_current_a=0.5)
    rig.bridge.activate()
    rig.step()
    rig.bridge.command_all([1.5] * 4, [False] * 4, rig.cycles[-1].sequence)
    rig.deliver()
    assert rig.bridge.deactivate() == 1
    frames = rig.deliver()
    values = codec.FrameCodec(DB).decode(*frames[0]).values
    assert [values[f'CMD_CURRENT_{c.upper()}'] for c in codec.CORNERS] == [0.5] * 4
    assert all(values[f'CMD_FAILSAFE_{c.upper()}'] == 1 for c in codec.CORNERS)
    assert all(ch['target_a'] == 0.5 for ch in rig.ecu.status()['corners'].values())


def test_a_silent_controller_gets_nothing_sent_in_its_name():
    rig = Rig(safe_current_a=0.5)
    rig.bridge.activate()
    rig.step()
    rig.bridge.command_all([1.2] * 4, [False] * 4, rig.cycles[-1].sequence)
    rig.deliver()
    for _ in range(30):                        # 60 ms without a command
        rig.step()
    st = rig.bridge.status()
    assert st['cycles']['command_frames'] == 1 and st['cycles']['safe_frames'] == 0
    assert all(st['corners'][c]['reason'] == 'command_timeout' for c in codec.CORNERS)
    # the drivers fell back on their own timeout and safe current (0 A here), once each
    ecu = rig.ecu.status()['corners']
    assert all(ecu[c]['command_timeouts'] == 1 for c in codec.CORNERS)
    assert rig.ecu.drive_targets() == [0.0] * 4
    assert st['unanswered'] == 29


def test_a_driver_fault_puts_its_corner_on_the_safe_current():
    rig = Rig(safe_current_a=0.5)
    rig.bridge.activate()
    rig.ecu.inject('fr', 'open_load')
    for _ in range(6):                         # a status frame (10 ms) reports it
        rig.step()
    rig.bridge.command_all([1.0] * 4, [False] * 4, rig.cycles[-1].sequence)
    frames = rig.deliver()
    values = codec.FrameCodec(DB).decode(*frames[-1]).values
    assert values['CMD_CURRENT_FR'] == 0.5 and values['CMD_FAILSAFE_FR'] == 1
    assert values['CMD_CURRENT_FL'] == 1.0 and values['CMD_FAILSAFE_FL'] == 0
    assert rig.bridge.status()['corners']['fr']['reason'] == 'driver_fault'
