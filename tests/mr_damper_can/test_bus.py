"""The loopback-only UDP bus: frames cross sockets on this host, the socket never leaves lo."""
import socket
import struct
import time

import can
import pytest

from mr_damper_can import bus as can_bus


def _port():
    return 46000 + time.monotonic_ns() % 1000


def test_frames_cross_between_two_buses_on_the_same_group_and_port():
    channel = f'239.74.163.2:{_port()}'
    a, b = can_bus.make_bus('udp_loopback', channel), can_bus.make_bus('udp_loopback', channel)
    try:
        for k in range(20):
            a.send(can.Message(arbitration_id=0x110, data=bytes([k, 0, 0, 0]),
                               is_extended_id=False))
        got = [b.recv(30.0) for _ in range(20)]
    finally:
        a.shutdown()
        b.shutdown()
    assert [m.data[0] for m in got] == list(range(20))
    assert all(m.arbitration_id == 0x110 and not m.is_fd for m in got)


def test_socket_sends_only_through_loopback_with_ttl_zero():
    group, port = '239.74.163.2', _port()
    b = can_bus.make_bus('udp_loopback', f'{group}:{port}')
    try:
        sock = b._multicast._socket
        assert sock.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL) == 0
        assert socket.inet_ntoa(sock.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF,
                                                4)) == '127.0.0.1'
        assert sock.getsockname() == (group, port)
        # the group is joined on lo only (the kernel's table of memberships per device)
        hex_group = '%08X' % struct.unpack('<I', socket.inet_aton(group))[0]
        devices, device = [], None
        for line in open('/proc/net/igmp').read().splitlines()[1:]:
            if not line.startswith('\t'):
                device = line.split()[1]
            elif line.split()[0] == hex_group:
                devices.append(device)
        assert devices and set(devices) == {'lo'}, devices
    finally:
        b.shutdown()


def test_other_interfaces_go_to_python_can():
    a = can_bus.make_bus('virtual', 'bus_test_virtual')
    try:
        assert isinstance(a, can.BusABC)
    finally:
        a.shutdown()
    assert can_bus.parse_channel('') == (can_bus.DEFAULT_GROUP, can_bus.DEFAULT_PORT)
    assert can_bus.parse_channel('239.1.2.3:5000') == ('239.1.2.3', 5000)
    for bad in ('ff15::1:5000', '10.0.0.1:5000', '239.1.2.3:x', '239.1.2.3:70000'):
        with pytest.raises(ValueError, match='IPv4 multicast group'):
            can_bus.make_bus('udp_loopback', bad)
