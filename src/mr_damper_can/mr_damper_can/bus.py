"""
Open the CAN bus of the bridge and the simulated ECU (python-can), with a loopback-only UDP bus.

``interface`` is any python-can interface (``virtual``, ``socketcan``, ``pcan``, ...) or
``udp_loopback``: python-can's ``udp_multicast`` bus (frames as msgpack datagrams to a multicast
group, every process that joined the group receives them) restricted to the loopback device.
python-can's own ``udp_multicast`` joins the group on the interface of the default route and
sends there (a TTL of 1 still reaches the local network, and the join itself sends an IGMP
report on that interface); this machine and CI must never send anything off loopback, and
``vcan`` is not available in this kernel. :class:`LoopbackUdpBus` therefore builds the socket
itself: it joins the group on ``lo`` (127.0.0.1), sends through ``lo`` (``IP_MULTICAST_IF``)
with a TTL of 0 (Linux never puts a multicast datagram with TTL 0 on a wire) and multicast
loop on, so every process of this host on the same group and port sees every frame.
"""
import socket
import struct

import can
from can.interfaces.udp_multicast import bus as udp_bus

#: Default group and port of ``udp_loopback`` (python-can's IPv4 default group).
DEFAULT_GROUP = '239.74.163.2'
DEFAULT_PORT = 43113
#: ``interface`` value of the loopback-only bus.
UDP_LOOPBACK = 'udp_loopback'
_LOOPBACK = '127.0.0.1'


#: Receive buffer asked for [bytes]: every frame of the bus (a process also receives its own)
#: arrives as one datagram of about 1 kB kernel memory; 8 MB hold about 4 s of the DBC's full
#: traffic (about 2,000 frames/s) while a reader thread is starved on a busy machine.
RECEIVE_BUFFER_BYTES = 8 * 1024 * 1024


def _large_receive_buffer(sock):
    """Ask for :data:`RECEIVE_BUFFER_BYTES` (beyond ``rmem_max`` as root), else the most."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUFFORCE, RECEIVE_BUFFER_BYTES)
    except (OSError, AttributeError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)


class _LoopbackMulticast(udp_bus.GeneralPurposeUdpMulticastBus):
    """python-can's multicast socket helper with a socket bound to the loopback device."""

    def _create_socket(self, address_family):
        if address_family != socket.AF_INET:
            raise OSError('udp_loopback takes an IPv4 multicast group')
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, struct.pack('@I', 0))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF,
                            socket.inet_aton(_LOOPBACK))
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            _large_receive_buffer(sock)
            try:
                sock.setsockopt(socket.SOL_SOCKET, udp_bus.SO_TIMESTAMPNS, 1)
                self.timestamp_nanosecond = True
            except OSError:
                self.timestamp_nanosecond = False
            # bound to the group: only datagrams to this group and port are received
            sock.bind((self.group, self.port))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP,
                            socket.inet_aton(self.group) + socket.inet_aton(_LOOPBACK))
            return sock
        except OSError:
            sock.close()
            raise


class LoopbackUdpBus(udp_bus.UdpMulticastBus):
    """
    python-can ``udp_multicast`` bus on the loopback device only (see the module docstring).

    Parameters
    ----------
    channel : str
        IPv4 multicast group (default :data:`DEFAULT_GROUP`).
    port : int
        UDP port (default :data:`DEFAULT_PORT`); buses on other ports do not see each other.
    fd : bool
        Declare CAN FD (False: classic CAN, as the DBC's frames).

    """

    def __init__(self, channel=DEFAULT_GROUP, port=DEFAULT_PORT, fd=False, **kwargs):
        kwargs.pop('bitrate', None)   # a datagram bus has no bit rate
        can.BusABC.__init__(self, channel, **kwargs)
        self._multicast = _LoopbackMulticast(channel, int(port), 0)
        self._can_protocol = can.CanProtocol.CAN_FD if fd else can.CanProtocol.CAN_20
        self.channel_info = f'udp loopback {channel}:{port}'


def parse_channel(channel):
    """Split ``'group:port'`` (or ``'group'``) of ``udp_loopback`` into ``(group, port)``."""
    group, _, port = str(channel or DEFAULT_GROUP).partition(':')
    group = group or DEFAULT_GROUP
    try:
        first = int(socket.inet_aton(group)[0])
        port = int(port) if port else DEFAULT_PORT
    except (OSError, ValueError):
        raise ValueError(f'udp_loopback channel must be "<IPv4 multicast group>[:<port>]", '
                         f'got {channel!r}') from None
    if not 224 <= first <= 239 or not 0 < port < 65536:
        raise ValueError(f'udp_loopback channel must be "<IPv4 multicast group>[:<port>]", '
                         f'got {channel!r}')
    return group, port


def close_bus(bus):
    """Shut ``bus`` down if there is one; return None, for ``self.bus = ...`` in one line."""
    if bus is not None:
        bus.shutdown()


def make_bus(interface='virtual', channel='mr_damper', bitrate=1000000):
    """
    Open a python-can bus.

    Parameters
    ----------
    interface : str
        ``udp_loopback`` (this module, cross-process on this host) or a python-can interface
        (``virtual``: in this process only; ``socketcan`` with ``can0`` / ``vcan0``; ...).
    channel : str
        Interface channel; for ``udp_loopback`` ``'group:port'`` (e.g. ``239.74.163.2:43113``).
    bitrate : int
        Bit rate [bit/s] (ignored by virtual and datagram buses).

    Returns
    -------
    can.BusABC

    """
    if interface == UDP_LOOPBACK:
        group, port = parse_channel(channel)
        return LoopbackUdpBus(group, port)
    if interface == 'virtual':
        return can.Bus(interface='virtual', channel=channel, receive_own_messages=False)
    return can.Bus(interface=interface, channel=channel, bitrate=int(bitrate))
