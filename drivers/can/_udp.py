"""python-can's ``udp_multicast`` bus as servoid opens it: on loopback unless told otherwise, malformed datagrams skipped.

python-can's own bus binds its socket to every interface (``("", port)``)
and joins the group on the default one: any host on the LAN can then put a
datagram into a drive's or a driver's bus -- a stray CAN frame, or a
malformed one, which made python-can's ``recv`` raise and so ended the
driver's session and killed the emulated drive's receiver thread.

Here the socket is bound to the group's address (so no unicast datagram to
this host reaches it) and joins the group only on the interface named by
``bind`` (default ``127.0.0.1``, this host alone), with
``IP_MULTICAST_ALL`` off (only the groups this socket joined) and a TTL of 0
on loopback (nothing sent leaves the host); ``bind=0.0.0.0`` gives python-can's
behaviour, for drives on other hosts. A datagram that does not unpack into
a CAN frame is counted (:attr:`LoopbackUdpBus.malformed`) and skipped: the
bus carries on, as a CAN controller drops a frame whose CRC fails.
"""

from __future__ import annotations

import errno
import ipaddress
import logging
import socket
import struct
from typing import Any

from servoid.errors import ConfigError

__all__ = ["LOOPBACK", "open_udp_bus", "check_bind"]

log = logging.getLogger("servoid.drivers.can")

#: Where the bus listens unless the user names an interface: this host only.
LOOPBACK = "127.0.0.1"

_IP_MULTICAST_ALL = getattr(socket, "IP_MULTICAST_ALL", 49)  # Linux; absent from Python's socket module
_SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)


def check_bind(bind: str) -> str:
    """``bind`` as an IPv4 address of a local interface (``127.0.0.1``, ``0.0.0.0`` or a card's), else ConfigError.

    Parameters
    ----------
    bind : str
        The address.
    """
    try:
        address = ipaddress.ip_address(bind)
    except ValueError:
        raise ConfigError(f"bind (={bind!r}) must be the IPv4 address of a local interface, e.g. 127.0.0.1") from None
    if address.version != 4:
        raise ConfigError(f"bind (={bind!r}) must be an IPv4 address (IPv6 groups listen on the loopback interface)")
    return str(address)


def open_udp_bus(can: Any, channel: str, port: int, *, bind: str | None = None, can_filters: Any = None) -> Any:
    """A python-can ``udp_multicast`` bus on ``channel`` (the group) and ``port``, listening where ``bind`` says.

    Parameters
    ----------
    can : module
        python-can, imported (with msgpack) by the caller, which reports a missing one.
    channel : str
        The multicast group (IPv4 or IPv6).
    port : int
        The UDP port.
    bind : str, optional
        IPv4 address of the interface to use; default :data:`LOOPBACK`.
    can_filters : list, optional
        python-can receive filters.
    """
    from can.interfaces.udp_multicast import bus as udp
    from can.interfaces.udp_multicast.utils import is_msgpack_installed

    where = check_bind(bind) if bind is not None else LOOPBACK

    class _Multicast(udp.GeneralPurposeUdpMulticastBus):
        def _create_socket(self, address_family: socket.AddressFamily) -> socket.socket:
            return _socket(can, self, address_family, where)

    class LoopbackUdpBus(udp.UdpMulticastBus):
        """python-can's udp_multicast bus with servoid's socket, skipping malformed datagrams."""

        def __init__(self) -> None:
            is_msgpack_installed()
            # UdpMulticastBus.__init__ would open python-can's own socket (bound to every interface) first
            can.BusABC.__init__(self, channel, can_filters=can_filters)
            self._multicast = _Multicast(channel, port, 0 if where == LOOPBACK else 1)
            self._can_protocol = can.CanProtocol.CAN_FD
            #: Datagrams that did not unpack into a CAN frame, skipped.
            self.malformed = 0

        def _recv_internal(self, timeout: float | None) -> tuple[Any, bool]:
            try:
                return super()._recv_internal(timeout)
            except can.CanOperationError as exc:
                if "could not unpack" not in str(exc):
                    raise  # the socket itself failed (the interface went down): not a datagram to skip
                self.malformed += 1
                log.warning("%s:%s: skipped a malformed datagram (%d so far): %s", channel, port, self.malformed,
                            exc.__cause__)  # fmt: skip
                return None, False

    return LoopbackUdpBus()


def _socket(can: Any, bus: Any, family: socket.AddressFamily, where: str) -> socket.socket:
    """The socket of python-can's GeneralPurposeUdpMulticastBus, bound to the group and joined on ``where`` only."""
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if hasattr(socket, "SO_REUSEPORT"):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        try:
            sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
        except OSError as error:
            if error.errno not in (errno.ENOPROTOOPT, errno.EINVAL):
                raise
            bus.timestamp_nanosecond = False
        else:
            bus.timestamp_nanosecond = True
        hops = struct.pack("@I", bus.hop_limit)
        group = socket.inet_pton(family, bus.group)
        if family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, hops)
            # bound to the group: a unicast datagram to one of this host's addresses never reaches it
            sock.bind((bus.group, bus.port))
            interface = socket.inet_aton(where)
            if where != "0.0.0.0":
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, interface)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, group + interface)
            try:  # only the groups this socket joined, on the interface it joined them on
                sock.setsockopt(socket.IPPROTO_IP, _IP_MULTICAST_ALL, 0)
            except OSError:
                pass  # not Linux: the membership above is all there is
        else:
            index = 0 if where == "0.0.0.0" else socket.if_nametoindex("lo")
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_HOPS, hops)
            sock.bind((bus.group, bus.port, 0, index))
            if index:
                sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_IF, struct.pack("@I", index))
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_LOOP, 1)
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_JOIN_GROUP, group + struct.pack("@I", index))
        return sock
    except OSError as error:
        sock.close()
        raise can.CanInitializationError(f"could not create or configure the multicast socket on {where}") from error
