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


def test_a_bus_does_not_receive_its_own_frames_as_socketcan():
    # the kernel drops a bus's own datagrams on its receiving socket; the others get them all
    channel = f'239.74.163.2:{_port()}'
    a, b = can_bus.make_bus('udp_loopback', channel), can_bus.make_bus('udp_loopback', channel)
    try:
        assert a.own_frames_filtered and b.own_frames_filtered
        for k in range(10):
            a.send(can.Message(arbitration_id=0x110, data=bytes([k]), is_extended_id=False))
            b.send(can.Message(arbitration_id=0x120, data=bytes([k]), is_extended_id=False))
        got_b = [b.recv(30.0) for _ in range(10)]
        got_a = [a.recv(30.0) for _ in range(10)]
        # a marker sent last: once it is in, nothing of a's own can still be on its way
        b.send(can.Message(arbitration_id=0x7FF, data=b'', is_extended_id=False))
        rest = []
        while not rest or rest[-1].arbitration_id != 0x7FF:
            rest.append(a.recv(30.0))
    finally:
        a.shutdown()
        b.shutdown()
    assert [(m.arbitration_id, m.data[0]) for m in got_b] == [(0x110, k) for k in range(10)]
    assert [(m.arbitration_id, m.data[0]) for m in got_a] == [(0x120, k) for k in range(10)]
    assert [m.arbitration_id for m in rest] == [0x7FF]


def test_the_own_frame_filter_drops_one_source_port_only():
    import select
    group, port = '239.74.163.2', _port()
    b = can_bus.make_bus('udp_loopback', f'{group}:{port}')
    senders = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2)]
    try:
        sock = b._multicast._socket
        for s in senders:
            s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, struct.pack('@I', 0))
            s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton('127.0.0.1'))
            s.bind(('127.0.0.1', 0))
        can_bus.drop_datagrams_from(sock, senders[0].getsockname()[1])
        for k in range(5):
            senders[0].sendto(b'x%d' % k, (group, port))
            senders[1].sendto(b'y%d' % k, (group, port))
        got = []
        while len(got) < 5 and select.select([sock], [], [], 30.0)[0]:
            got.append(sock.recv(64))
        senders[1].sendto(b'end', (group, port))
        while got[-1] != b'end' and select.select([sock], [], [], 30.0)[0]:
            got.append(sock.recv(64))
    finally:
        b.shutdown()
        for s in senders:
            s.close()
    assert got == [b'y%d' % k for k in range(5)] + [b'end']


def test_socket_sends_only_through_loopback_with_ttl_zero():
    group, port = '239.74.163.2', _port()
    b = can_bus.make_bus('udp_loopback', f'{group}:{port}')
    try:
        sock, sender = b._multicast._socket, b._multicast._send_socket
        for s in (sock, sender):
            assert s.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL) == 0
            assert socket.inet_ntoa(s.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF,
                                                 4)) == '127.0.0.1'
        assert sock.getsockname() == (group, port)
        assert sender.getsockname()[0] == '127.0.0.1'
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
