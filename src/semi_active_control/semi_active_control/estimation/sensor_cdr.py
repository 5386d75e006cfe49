"""
The readings of serialised ``sensor_msgs/Imu`` and ``sensor_msgs/JointState`` messages, no ROS.

A reader of 1 kHz sensor topics in Python spends most of its time building message objects it
reads one number from: rclpy's conversion of an ``Imu`` (header, quaternion, three vectors, three
covariance arrays) cost 42 us, a ``JointState`` 19 us, against about 2 us here
(``bench/bench_estimator_rate.py``). :func:`imu_reading` and :func:`joint_reading` read the
stamp and the one value the state estimator uses straight from the serialised message (what an
rclpy subscription created with ``raw=True`` hands its callback).

Encoding: the 4-byte encapsulation header, then the body in plain CDR (XCDR1, what Fast DDS and
Cyclone DDS send for ROS 2 messages), big or little endian, every primitive aligned to its
size from the start of the body. Any other encapsulation (XCDR2, a parameter list) returns None:
the caller then decodes the message fully (rclpy's deserialisation), so every writer is read.
A message too short for its own lengths raises :class:`CdrError`.
"""
import struct

#: encapsulation identifiers of plain CDR (XCDR1): big endian, little endian
_CDR_BE, _CDR_LE = b'\x00\x00', b'\x00\x01'
#: offset of ``linear_acceleration.z`` in an Imu after the header (8-aligned): orientation (4),
#: its covariance (9), angular_velocity (3), its covariance (9), linear_acceleration x, y
_IMU_ACCEL_Z = 8 * (4 + 9 + 3 + 9 + 2)
_NAN = float('nan')


class CdrError(ValueError):
    """A serialised message shorter than its own field lengths say."""


def _endian(data):
    head = bytes(data[0:2])
    if head == _CDR_LE:
        return '<'
    if head == _CDR_BE:
        return '>'
    return None


def _header(data, order):
    """Return (stamp [s], offset after the header in the body) of a std_msgs/Header."""
    sec, nanosec, n = struct.unpack_from(order + 'iII', data, 4)
    return sec + 1e-9 * nanosec, 12 + n


def _check(data, end):
    if 4 + end > len(data):
        raise CdrError(f'serialised message of {len(data)} bytes, its fields need {4 + end}')


def imu_reading(data):
    """
    Return ``(stamp [s], linear_acceleration.z)`` of a serialised ``sensor_msgs/Imu``.

    Parameters
    ----------
    data : bytes-like
        The serialised message (encapsulation header included).

    Returns
    -------
    tuple of float, or None
        None when the message is not in plain CDR (decode it fully instead).

    Raises
    ------
    CdrError
        The message is shorter than its fields.

    """
    order = _endian(data)
    if order is None:
        return None
    try:
        stamp, p = _header(data, order)
        p = (p + 7) & ~7
        _check(data, p + _IMU_ACCEL_Z + 8)
        (z,) = struct.unpack_from(order + 'd', data, 4 + p + _IMU_ACCEL_Z)
    except struct.error as exc:
        raise CdrError(f'serialised Imu of {len(data)} bytes: {exc}') from None
    return stamp, z


def joint_reading(data):
    """
    Return ``(stamp [s], position[0])`` of a serialised ``sensor_msgs/JointState``.

    As :func:`imu_reading` (None when not plain CDR, :class:`CdrError` when cut short);
    ``position[0]`` is NaN when the message has no position.
    """
    order = _endian(data)
    if order is None:
        return None
    u32 = order + 'I'
    try:
        stamp, p = _header(data, order)
        p = (p + 3) & ~3
        (names,) = struct.unpack_from(u32, data, 4 + p)
        p += 4
        for _ in range(names):
            p = (p + 3) & ~3
            (n,) = struct.unpack_from(u32, data, 4 + p)
            p += 4 + n
            _check(data, p)
        p = (p + 3) & ~3
        (count,) = struct.unpack_from(u32, data, 4 + p)
        p += 4
        if count == 0:
            return stamp, _NAN
        p = (p + 7) & ~7
        _check(data, p + 8)
        (x,) = struct.unpack_from(order + 'd', data, 4 + p)
    except struct.error as exc:
        raise CdrError(f'serialised JointState of {len(data)} bytes: {exc}') from None
    return stamp, x
