"""
The damper system's DBC, frame encoding with rolling counter and checksum, and checks (no ROS).

Every frame of ``dbc/mr_damper.dbc`` ends with the same protection: a 4-bit rolling ``COUNTER``
(+1 per frame of that id, 15 -> 0) in the low nibble of the byte before the last, and an 8-bit
``CHECKSUM`` in the last byte: CRC-8 SAE J1850 (polynomial 0x1D, initial value 0xFF, final XOR
0xFF) over the two bytes of the frame id (low byte first, as a "data id" in the manner of
AUTOSAR E2E profiles) and every payload byte before the checksum. Signals are encoded and
decoded with cantools from the DBC (resolution, offset and range are the DBC's).
"""
from dataclasses import dataclass
import math
from pathlib import Path

import cantools

#: Corners of the car, in the order of the DBC's signals and frame ids.
CORNERS = ('fl', 'fr', 'rl', 'rr')

#: Fault bits of a ``DAMPER_STATUS_<C>`` frame, DBC signal -> status name.
FAULT_SIGNALS = {'FLT_OPEN_LOAD': 'open_load', 'FLT_SHORT': 'short',
                 'FLT_OVERCURRENT': 'overcurrent', 'FLT_OVERTEMP': 'overtemp',
                 'FLT_UNDERVOLTAGE': 'undervoltage', 'FLT_CMD_TIMEOUT': 'cmd_timeout',
                 'FLT_CMD_INVALID': 'cmd_invalid'}
#: Faults of the driver's hardware (the others, ``cmd_timeout`` and ``cmd_invalid``, report the
#: link from the bridge: the bridge counts them but they are no reason for its fail-safe).
HARDWARE_FAULTS = ('open_load', 'short', 'overcurrent', 'overtemp', 'undervoltage')
#: ``DRV_STATE`` values of the driver.
DRV_INIT, DRV_NORMAL, DRV_FAILSAFE, DRV_FAULT = 0, 1, 2, 3

#: The vehicle computer's command frame: the four corners' currents in one frame per cycle.
VEHICLE_COMMAND = 'DAMPER_CMD_ALL'

#: Sensor cluster frames: message name -> (quantity, signal prefix).
SENSOR_FRAMES = {'CHASSIS_BODY_ACCEL': ('body_accel', 'BODY_ACCEL'),
                 'CHASSIS_WHEEL_ACCEL': ('wheel_accel', 'WHEEL_ACCEL'),
                 'CHASSIS_SUSP_POS': ('susp_pos', 'SUSP_POS')}

_CRC_TABLE = []
for _byte in range(256):
    _crc = _byte
    for _ in range(8):
        _crc = ((_crc << 1) ^ 0x1D) & 0xFF if _crc & 0x80 else (_crc << 1) & 0xFF
    _CRC_TABLE.append(_crc)


def crc8_sae_j1850(data):
    """
    CRC-8 SAE J1850 of ``data`` (polynomial 0x1D, init 0xFF, final XOR 0xFF).

    Parameters
    ----------
    data : bytes-like
        Bytes to protect.

    Returns
    -------
    int
        The checksum, 0..255 (``b'123456789'`` gives 0x4B).

    """
    crc = 0xFF
    for byte in bytes(data):
        crc = _CRC_TABLE[crc ^ byte]
    return crc ^ 0xFF


def frame_checksum(frame_id, payload):
    """Return the CHECKSUM of a frame: the CRC over the id bytes and ``payload[:-1]``."""
    return crc8_sae_j1850(bytes((frame_id & 0xFF, (frame_id >> 8) & 0xFF))
                          + bytes(payload[:-1]))


def dbc_path():
    """Return the path of the packaged ``mr_damper.dbc``."""
    return str(Path(__file__).resolve().parent / 'dbc' / 'mr_damper.dbc')


def load_database(path=None):
    """Load the damper system DBC (``path`` or the packaged one) with cantools."""
    return cantools.database.load_file(path or dbc_path(), strict=True)


def parse_corners(text):
    """Return the corners of a comma-separated list; ValueError names the bad ones."""
    corners = tuple(c.strip() for c in str(text).split(',') if c.strip())
    bad = [c for c in corners if c not in CORNERS]
    if not corners or bad or len(set(corners)) != len(corners):
        raise ValueError(f'corners must be distinct names of {", ".join(CORNERS)}, got {text!r}')
    return corners


def command_name(corner):
    """Return the command message name of ``corner`` (``'fl'`` -> ``'DAMPER_CMD_FL'``)."""
    return f'DAMPER_CMD_{corner.upper()}'


def status_name(corner):
    """Return the driver status message name of ``corner``."""
    return f'DAMPER_STATUS_{corner.upper()}'


@dataclass
class Decoded:
    """
    One received frame, checked and decoded.

    Attributes
    ----------
    name : str or None
        DBC message name (None: unknown id).
    values : dict
        Physical signal values (empty unless ``problem`` is None).
    problem : str or None
        None, or the fault counted: ``unknown_id``, ``bad_length``, ``bad_checksum``,
        ``error_frame``, ``bus_off``, ``remote_frame``.
    counter_jump : int
        Frames missed before this one according to the counter (0 in order; -1 the same
        counter again: a repeated frame).

    """

    name: object
    values: dict
    problem: object = None
    counter_jump: int = 0


#: CAN error frame class bit of a bus-off (Linux ``CAN_ERR_BUSOFF`` in the frame id).
CAN_ERR_BUSOFF = 0x40


class FrameCodec:
    """
    Encode and check the frames of the DBC: counters per id, checksums, ranges.

    Parameters
    ----------
    db : cantools.database.can.Database, optional
        The DBC (default: the packaged one).

    """

    def __init__(self, db=None):
        self.db = db or load_database()
        self._by_id = {m.frame_id: m for m in self.db.messages}
        self._tx_counter = {}
        self._rx_counter = {}

    def message(self, name):
        """Return the cantools message ``name``."""
        return self.db.get_message_by_name(name)

    def signal_range(self, message_name, signal_name):
        """Return the DBC range ``(minimum, maximum)`` of a signal (physical units)."""
        sig = self.message(message_name).get_signal_by_name(signal_name)
        return float(sig.minimum), float(sig.maximum)

    def encode(self, name, values, counter=None, strict=True):
        """
        Encode message ``name`` with its next rolling counter and its checksum.

        Parameters
        ----------
        name : str
            DBC message name.
        values : dict
            Physical values of every signal but ``COUNTER`` and ``CHECKSUM``; each must lie in
            its DBC range (cantools raises otherwise: the caller clamps first).
        counter : int, optional
            Force this counter (fault injection); default the id's next one.
        strict : bool
            Check every value against its DBC range (cantools raises outside it). False: the
            caller has already clamped them (the bridge's limiter): half the encoding time.

        Returns
        -------
        frame_id : int
        data : bytes

        """
        msg = self.message(name)
        if counter is None:
            counter = self._tx_counter.get(msg.frame_id, -1) + 1 & 0x0F
            self._tx_counter[msg.frame_id] = counter
        data = bytearray(msg.encode(dict(values, COUNTER=counter, CHECKSUM=0), strict=strict))
        data[-1] = frame_checksum(msg.frame_id, data)
        return msg.frame_id, bytes(data)

    def decode(self, frame_id, data, *, is_error_frame=False, is_remote_frame=False):
        """
        Check and decode one received frame.

        The checksum is checked first, then the rolling counter of that id (a frame with a
        bad checksum leaves the counter alone); a counter jump is reported, not refused (the
        values are new).

        Returns
        -------
        Decoded

        """
        if is_error_frame:
            return Decoded(None, {}, 'bus_off' if frame_id & CAN_ERR_BUSOFF else 'error_frame')
        msg = self._by_id.get(frame_id)
        if msg is None:
            return Decoded(None, {}, 'unknown_id')
        if is_remote_frame:
            return Decoded(msg.name, {}, 'remote_frame')
        if len(data) != msg.length:
            return Decoded(msg.name, {}, 'bad_length')
        if frame_checksum(frame_id, data) != data[-1]:
            return Decoded(msg.name, {}, 'bad_checksum')
        values = msg.decode(bytes(data), decode_choices=False)
        counter = int(values['COUNTER'])
        last = self._rx_counter.get(frame_id)
        self._rx_counter[frame_id] = counter
        jump = 0 if last is None else (counter - last - 1) % 16
        return Decoded(msg.name, values, None, -1 if jump == 15 else jump)


def frame_bits(length):
    """
    Worst-case bits on the wire of a classic CAN frame, 11-bit id, ``length`` data bytes.

    44 + 8 n frame bits (SOF to EOF), the 3-bit interframe space, and the stuff bits of the
    34 + 8 n bits that are stuffed, at most one per 4 after the first.
    """
    return 47 + 8 * length + (34 + 8 * length - 1) // 4


def bus_load(db, bitrate, *, rate_scale=None, cycle_times_ms=None):
    """
    Worst-case bus load of the DBC's cyclic frames at ``bitrate``.

    Parameters
    ----------
    db : cantools.database.can.Database
        The DBC (cycle times from ``GenMsgCycleTime`` [ms]).
    bitrate : float
        Bit rate [bit/s].
    rate_scale : dict, optional
        Message name -> factor on its rate (e.g. corners not present: 0).
    cycle_times_ms : dict, optional
        Message name -> cycle time [ms] instead of the DBC's (0: not sent), e.g. a
        :func:`bus_layout`.

    Returns
    -------
    float
        Load in [0, inf): the fraction of the bit time the frames need.

    """
    bits = 0.0
    for msg in db.messages:
        cycle = msg.cycle_time if cycle_times_ms is None else cycle_times_ms.get(
            msg.name, msg.cycle_time)
        if not cycle:
            continue
        scale = 1.0 if rate_scale is None else rate_scale.get(msg.name, 1.0)
        bits += scale * frame_bits(msg.length) * 1000.0 / cycle
    if not (math.isfinite(bitrate) and bitrate > 0):
        raise ValueError(f'`bitrate` must be positive, got {bitrate}')
    return bits / float(bitrate)


#: The bus layouts of the DBC (:func:`bus_layout`).
LAYOUTS = ('corner', 'vehicle')


def bus_layout(layout, cycle_s=0.002, status_period_s=0.01):
    """
    Cycle times [ms] of the frames on one of the DBC's two buses (for :func:`bus_load`).

    Parameters
    ----------
    layout : str
        ``'corner'``: a controller's command per corner (``DAMPER_CMD_<C>``, the DBC's cycle
        times; ``can_bridge_node``); ``'vehicle'``: the vehicle computer's one command frame
        (``DAMPER_CMD_ALL``) and the sensor frames every ``cycle_s``, the driver status every
        ``status_period_s``, no per-corner commands (``vehicle_bridge_node``).
    cycle_s, status_period_s : float
        The vehicle layout's sensor / command cycle and driver status period [s].

    Returns
    -------
    dict
        Message name -> cycle time [ms] (0: not on this bus).

    """
    if layout == 'corner':
        out = {VEHICLE_COMMAND: 0}
    elif layout == 'vehicle':
        out = {command_name(c): 0 for c in CORNERS}
        out[VEHICLE_COMMAND] = 1000.0 * cycle_s
        out.update({status_name(c): 1000.0 * status_period_s for c in CORNERS})
        out.update({name: 1000.0 * cycle_s for name in SENSOR_FRAMES})
    else:
        raise ValueError(f'`layout` must be one of {", ".join(LAYOUTS)}, got {layout!r}')
    return out
