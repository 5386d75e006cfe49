"""sensor_cdr: stamps and values read from serialised Imu / JointState equal rclpy's decoding."""
import math
import struct

import pytest


def _imu(frame_id, sec, nanosec, z):
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
    msg = Imu()
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.orientation_covariance[0] = -1.0
    msg.linear_acceleration.x, msg.linear_acceleration.y = 1.5, -2.5
    msg.linear_acceleration.z = z
    msg.linear_acceleration_covariance[0] = 7.0
    return serialize_message(msg)


def _joint(frame_id, names, positions, sec=3, nanosec=250_000_000):
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    msg = JointState(name=list(names), position=list(positions),
                     velocity=[9.0] * len(positions))
    msg.header.frame_id = frame_id
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    return serialize_message(msg)


@pytest.mark.parametrize('frame_id', ['', 'b', 'body', 'body_imu', 'a' * 8, 'corner_fl/imu_z'])
def test_imu_reading_of_every_header_length(frame_id):
    from semi_active_control.estimation.sensor_cdr import imu_reading
    stamp, z = imu_reading(_imu(frame_id, 12, 500_000_000, 9.80665 + 1e-3))
    assert stamp == pytest.approx(12.5, abs=1e-9) and z == 9.80665 + 1e-3


@pytest.mark.parametrize('frame_id', ['', 'abc', 'abcd'])
@pytest.mark.parametrize('names', [(), ('suspension',), ('a', 'bb', 'ccc', 'dddd', 'eeeee')])
def test_joint_reading_of_every_layout(frame_id, names):
    from semi_active_control.estimation.sensor_cdr import joint_reading
    positions = [-0.0123 + 1e-3 * k for k in range(max(len(names), 1))]
    stamp, x = joint_reading(_joint(frame_id, names, positions))
    assert stamp == pytest.approx(3.25, abs=1e-9) and x == positions[0]
    stamp, x = joint_reading(_joint(frame_id, names, []))
    assert math.isnan(x)


def test_big_endian_plain_cdr():
    """A big-endian writer: the same fields, other byte order (built by hand)."""
    from semi_active_control.estimation.sensor_cdr import imu_reading, joint_reading
    body = struct.pack('>iII', 4, 5, 5) + b'body\0' + b'\0' * 7       # header, pad to 24
    doubles = [0.0] * 4 + [0.0] * 9 + [0.0] * 3 + [0.0] * 9 + [0.1, 0.2, -9.5] + [0.0] * 9
    data = b'\x00\x00\x00\x00' + body + struct.pack('>37d', *doubles)
    assert imu_reading(data) == (pytest.approx(4.000000005), -9.5)
    body = (struct.pack('>iII', 1, 0, 1) + b'\0' + b'\0' * 3 + struct.pack('>II', 1, 2)
            + b'x\0' + b'\0' * 2 + struct.pack('>I', 1) + struct.pack('>d', 0.25))
    assert joint_reading(b'\x00\x00\x00\x00' + body) == (1.0, 0.25)


def test_other_encodings_and_short_messages():
    from semi_active_control.estimation.sensor_cdr import CdrError, imu_reading, joint_reading
    data = bytearray(_imu('body', 1, 2, 3.0))
    data[1] = 0x07                                  # XCDR2: the caller decodes it fully
    assert imu_reading(bytes(data)) is None and joint_reading(bytes(data)) is None
    for cut in (3, 10, 100, 250):
        with pytest.raises(CdrError):
            imu_reading(_imu('body', 1, 2, 3.0)[:cut])
    full = _joint('', ('suspension',), [0.5])
    for cut in (6, 20, 30, 44):
        with pytest.raises(CdrError):
            joint_reading(full[:cut])
