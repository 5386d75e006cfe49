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

As a socketcan socket (``CAN_RAW_RECV_OWN_MSGS`` off, its default), a process does not receive
its own frames: it sends from a socket of its own (bound to an ephemeral port of 127.0.0.1) and
its receiving socket carries a classic BPF filter that drops, in the kernel, every datagram from
that port (:func:`drop_datagrams_from`). Before, each process received every frame it sent and
threw it away in Python: on the vehicle suite's bus 3.8 of the car's 4.8 frames a sensor cycle
and 1 of the vehicle computer's (``bench/bench_can_own_frames.py``: the car's reader 3.3x
less CPU per cycle, the computer's 1.15x). Where the filter cannot be
attached (a kernel without socket filters), own frames come back as before and the bridge
skips them (``own_frames``); :attr:`LoopbackUdpBus.own_frames_filtered` says which.
"""
import ctypes
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


#: Receive buffer asked for [bytes]: every frame of the other processes on the bus arrives as
#: one datagram of about 1 kB kernel memory; 8 MB hold about 4 s of the DBC's full traffic
#: (about 2,000 frames/s) while a reader thread is starved on a busy machine.
RECEIVE_BUFFER_BYTES = 8 * 1024 * 1024

#: ``SO_ATTACH_FILTER`` of Linux (``asm-generic/socket.h``; Python's ``socket`` has no name
#: for it).
SO_ATTACH_FILTER = 26
#: Classic BPF: ``ldh [k]``, ``jeq #k, jt, jf``, ``ret #k`` (``linux/filter.h``).
_BPF_LDH_ABS, _BPF_JEQ_K, _BPF_RET_K = 0x28, 0x15, 0x06


def drop_datagrams_from(sock, port):
    """
    Attach a socket filter to UDP socket ``sock`` that drops every datagram from ``port``.

    The program (classic BPF, run by the kernel on each datagram before it is queued) reads
    the UDP source port, the first half-word a UDP socket's filter sees, and returns 0 (drop)
    when it is ``port``, else the whole datagram. Raises OSError where the kernel refuses it.
    """
    program = ((_BPF_LDH_ABS, 0, 0, 0),                # A = UDP source port
               (_BPF_JEQ_K, 0, 1, int(port)),          # A == port ? next : skip one
               (_BPF_RET_K, 0, 0, 0),                  # drop
               (_BPF_RET_K, 0, 0, 0xFFFFFFFF))         # keep all of it
    code = ctypes.create_string_buffer(b''.join(struct.pack('HBBI', *op) for op in program))
    # struct sock_fprog {unsigned short len; struct sock_filter *filter;}: the kernel copies it
    sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER,
                    struct.pack('HP', len(program), ctypes.addressof(code)))


def _loopback_multicast_options(sock):
    """Send multicast through ``lo`` only, with TTL 0, looped back to this host's sockets."""
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, struct.pack('@I', 0))
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(_LOOPBACK))


def _large_receive_buffer(sock):
    """Ask for :data:`RECEIVE_BUFFER_BYTES` (beyond ``rmem_max`` as root), else the most."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUFFORCE, RECEIVE_BUFFER_BYTES)
    except (OSError, AttributeError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)


class _LoopbackMulticast(udp_bus.GeneralPurposeUdpMulticastBus):
    """
    python-can's multicast socket helper on the loopback device, own datagrams not received.

    ``_socket`` (python-can's receive path) is bound to the group; :meth:`send` goes through a
    socket of its own whose datagrams ``_socket`` drops (module docstring).
    """

    def __init__(self, group, port, hop_limit, max_buffer=4096, receive_own=False):
        super().__init__(group, port, hop_limit, max_buffer)
        self._send_socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.own_frames_filtered = False
        try:
            _loopback_multicast_options(self._send_socket)
            self._send_socket.bind((_LOOPBACK, 0))
            try:
                if not receive_own:
                    drop_datagrams_from(self._socket, self._send_socket.getsockname()[1])
                    self.own_frames_filtered = True
            except OSError:
                pass                      # own frames come back; the bridge skips them
        except OSError as exc:
            self.shutdown()
            raise can.CanInitializationError(f'cannot open the sending socket: {exc}') from exc

    def send(self, data, timeout=None):
        """Send ``data`` to the group (python-can's semantics, from the sending socket)."""
        sock = self._send_socket
        if timeout != self._last_send_timeout:
            self._last_send_timeout = timeout
            sock.settimeout(timeout)
        try:
            if sock.sendto(data, self._send_destination) < len(data):
                raise TimeoutError()
        except TimeoutError:
            raise can.CanTimeoutError() from None
        except OSError as exc:
            raise can.CanOperationError('failed to send via socket') from exc

    def shutdown(self):
        """Close both sockets."""
        super().shutdown()
        sock = getattr(self, '_send_socket', None)
        if sock is not None:
            sock.close()

    def _create_socket(self, address_family):
        if address_family != socket.AF_INET:
            raise OSError('udp_loopback takes an IPv4 multicast group')
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            _loopback_multicast_options(sock)
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
    receive_own_messages : bool
        Receive this bus's own frames too (python-can's keyword; False, as socketcan's
        default: the kernel drops them, see the module docstring).

    """

    def __init__(self, channel=DEFAULT_GROUP, port=DEFAULT_PORT, fd=False,
                 receive_own_messages=False, **kwargs):
        kwargs.pop('bitrate', None)   # a datagram bus has no bit rate
        can.BusABC.__init__(self, channel, **kwargs)
        self._multicast = _LoopbackMulticast(channel, int(port), 0,
                                             receive_own=bool(receive_own_messages))
        self._can_protocol = can.CanProtocol.CAN_FD if fd else can.CanProtocol.CAN_20
        self.channel_info = f'udp loopback {channel}:{port}'

    @property
    def own_frames_filtered(self):
        """True when this bus does not receive its own frames (the kernel drops them)."""
        return self._multicast.own_frames_filtered


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


def make_bus(interface='virtual', channel='mr_damper', bitrate=1000000,
             receive_own_messages=False):
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
    receive_own_messages : bool
        Receive the frames this bus sends (python-can's keyword; False: as socketcan's
        default, the nodes' setting).

    Returns
    -------
    can.BusABC

    """
    own = bool(receive_own_messages)
    if interface == UDP_LOOPBACK:
        group, port = parse_channel(channel)
        return LoopbackUdpBus(group, port, receive_own_messages=own)
    if interface == 'virtual':
        return can.Bus(interface='virtual', channel=channel, receive_own_messages=own)
    return can.Bus(interface=interface, channel=channel, bitrate=int(bitrate),
                   receive_own_messages=own)
