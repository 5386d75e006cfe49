"""The damper DBC, rolling counters and checksums: round trips of every signal, ranges, checks."""
import math

import pytest

from mr_damper_can import codec
from mr_damper_can.codec import CORNERS, FrameCodec


@pytest.fixture(scope='module')
def db():
    return codec.load_database()


def test_crc8_sae_j1850_check_value():
    # the catalogued check value of CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF)
    assert codec.crc8_sae_j1850(b'123456789') == 0x4B
    assert codec.crc8_sae_j1850(b'') == 0x00


def test_dbc_has_every_frame_with_cycle_times(db):
    names = {m.name for m in db.messages}
    for c in CORNERS:
        assert codec.command_name(c) in names and codec.status_name(c) in names
        assert db.get_message_by_name(codec.command_name(c)).cycle_time == 1
        assert db.get_message_by_name(codec.status_name(c)).cycle_time == 2
    for name in codec.SENSOR_FRAMES:
        assert db.get_message_by_name(name).cycle_time == 2
    for m in db.messages:     # every frame: counter before the last byte, checksum last
        assert m.get_signal_by_name('CHECKSUM').start == 8 * (m.length - 1)
        assert m.get_signal_by_name('COUNTER').length == 4
    cmd = db.get_message_by_name('DAMPER_CMD_FL').get_signal_by_name('CMD_CURRENT')
    assert (cmd.minimum, cmd.maximum, cmd.scale, cmd.length) == (0, 2.55, 0.01, 8)
    # the vehicle computer's frame: the four currents at the same resolution, one id that
    # wins arbitration over every other frame, the sensor cycle it answers
    all4 = db.get_message_by_name(codec.VEHICLE_COMMAND)
    assert (all4.frame_id, all4.length, all4.cycle_time) == (0x100, 8, 2)
    assert min(m.frame_id for m in db.messages) == all4.frame_id
    for c in CORNERS:
        sig = all4.get_signal_by_name(f'CMD_CURRENT_{c.upper()}')
        assert (sig.minimum, sig.maximum, sig.scale, sig.length) == (0, 2.55, 0.01, 8)
    assert all4.get_signal_by_name('SENSOR_CYCLE').length == 8


def _grid(sig, n=7):
    """Values on the signal's raw grid from minimum to maximum (both ends included)."""
    lo, hi = float(sig.minimum), float(sig.maximum)
    steps = round((hi - lo) / sig.scale)
    return [lo + sig.scale * round(steps * k / (n - 1)) for k in range(n)]


def test_every_signal_round_trips_at_its_resolution_and_range_ends(db):
    enc, dec = FrameCodec(db), FrameCodec(db)
    for m in db.messages:
        free = [s for s in m.signals if s.name not in ('COUNTER', 'CHECKSUM')]
        for k in range(7):
            values = {s.name: _grid(s)[(k + i) % 7] for i, s in enumerate(free)}
            frame_id, data = enc.encode(m.name, values)
            assert len(data) == m.length
            got = dec.decode(frame_id, data)
            assert got.problem is None and got.counter_jump == 0, (m.name, got)
            assert got.values['COUNTER'] == k
            for s in free:
                assert got.values[s.name] == pytest.approx(values[s.name], abs=1e-9), s.name


def test_values_between_steps_are_rounded_to_the_resolution(db):
    enc, dec = FrameCodec(db), FrameCodec(db)
    frame_id, data = enc.encode('DAMPER_CMD_RR', {'CMD_CURRENT': 1.234, 'CMD_FAILSAFE': 0})
    assert dec.decode(frame_id, data).values['CMD_CURRENT'] == pytest.approx(1.23)
    frame_id, data = enc.encode('CHASSIS_SUSP_POS', {'SUSP_POS_FL': -0.01234, 'SUSP_POS_FR': 0,
                                                     'SUSP_POS_RL': 0, 'SUSP_POS_RR': 0})
    assert dec.decode(frame_id, data).values['SUSP_POS_FL'] == pytest.approx(-0.0123)


@pytest.mark.parametrize('value', [-0.01, 2.56, math.nan])
def test_encoding_outside_the_dbc_range_raises(db, value):
    with pytest.raises(Exception):
        FrameCodec(db).encode('DAMPER_CMD_FL', {'CMD_CURRENT': value, 'CMD_FAILSAFE': 0})


def test_checks_of_received_frames(db):
    enc, dec = FrameCodec(db), FrameCodec(db)
    frame_id, data = enc.encode('DAMPER_CMD_FL', {'CMD_CURRENT': 1.0, 'CMD_FAILSAFE': 0})
    assert dec.decode(frame_id, data).problem is None
    # any single bit flipped anywhere is caught by the checksum
    for bit in range(8 * len(data)):
        bad = bytearray(data)
        bad[bit // 8] ^= 1 << (bit % 8)
        assert FrameCodec(db).decode(frame_id, bytes(bad)).problem == 'bad_checksum', bit
    # the same payload under another id fails (the id is inside the CRC)
    assert FrameCodec(db).decode(frame_id + 1, data).problem == 'bad_checksum'
    assert dec.decode(0x7E5, bytes(8)).problem == 'unknown_id'
    assert dec.decode(frame_id, data[:-1]).problem == 'bad_length'
    assert dec.decode(frame_id, data, is_remote_frame=True).problem == 'remote_frame'
    assert dec.decode(0x004, bytes(8), is_error_frame=True).problem == 'error_frame'
    assert dec.decode(codec.CAN_ERR_BUSOFF, bytes(8), is_error_frame=True).problem == 'bus_off'


def test_counter_jumps_and_repeats(db):
    enc, dec = FrameCodec(db), FrameCodec(db)
    frames = [enc.encode('DAMPER_CMD_FL', {'CMD_CURRENT': 0.5, 'CMD_FAILSAFE': 0})
              for _ in range(40)]
    jumps = [dec.decode(*f).counter_jump for f in frames[:20]]   # 0..15, wraps to 0..3
    assert jumps == [0] * 20
    assert dec.decode(*frames[23]).counter_jump == 3             # frames 20, 21, 22 missed
    assert dec.decode(*frames[23]).counter_jump == -1            # the same frame again


def test_bus_load_of_the_dbc(db):
    # worst-case stuffed frame lengths: 4 bytes 95 bits, 5 bytes 105, 8 bytes 135
    assert [codec.frame_bits(n) for n in (0, 4, 5, 8)] == [55, 95, 105, 135]
    corner = codec.bus_load(db, 1_000_000, cycle_times_ms=codec.bus_layout('corner'))
    expected = (4 * 95 * 1000 + 4 * 105 * 500 + 3 * 135 * 500) / 1e6
    assert corner == pytest.approx(expected)                  # 79 %
    # the vehicle computer's bus: one 8-byte command and the three sensor frames per 2 ms
    # cycle, the four driver statuses every 10 ms: 31 % of 1 Mbit/s
    vehicle = codec.bus_load(db, 1_000_000, cycle_times_ms=codec.bus_layout('vehicle'))
    assert vehicle == pytest.approx((135 * 500 + 3 * 135 * 500 + 4 * 105 * 100) / 1e6)
    assert vehicle == pytest.approx(0.312)
    at_1khz = codec.bus_load(db, 1_000_000, cycle_times_ms=codec.bus_layout('vehicle', 0.001))
    assert at_1khz == pytest.approx(0.582)
    with pytest.raises(ValueError, match='bitrate'):
        codec.bus_load(db, 0)
    with pytest.raises(ValueError, match='layout'):
        codec.bus_layout('truck')


def test_the_vehicle_estimators_bus_resolution_and_ranges_are_the_dbcs(db):
    # the estimator (no bus of its own) and the offline chain's bus rounding keep the chassis
    # signals' resolution and range as settings: they must be the DBC's
    from semi_active_control.estimation.vehicle_estimator import EstimatorSettings
    s = EstimatorSettings()
    for frame, prefix, quantum, rng in (('CHASSIS_BODY_ACCEL', 'BODY_ACCEL', s.accel_quantum,
                                         s.accel_range),
                                        ('CHASSIS_SUSP_POS', 'SUSP_POS', s.travel_quantum,
                                         s.travel_range)):
        for c in CORNERS:
            sig = db.get_message_by_name(frame).get_signal_by_name(f'{prefix}_{c.upper()}')
            assert sig.scale == pytest.approx(quantum, rel=1e-12), sig.name
            assert (sig.minimum, sig.maximum) == pytest.approx(rng, rel=1e-12), sig.name
