"""Where a CAN driver or simulated drive meets python-can: opening a bus, and its address.

python-can (and canopen, for CiA 402) are imported here and in the protocol
modules only when a bus is opened, so that ``import servoid.drivers.can``
stays cheap and a missing package is reported by name
(:class:`~servoid.errors.MissingDependency`), not as a traceback.
"""

from __future__ import annotations

import importlib
import socket
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any
from urllib.parse import urlencode

from servoid import validation
from servoid.drivers.can._udp import LOOPBACK, check_bind, open_udp_bus
from servoid.errors import ConfigError, DriverError, MissingDependency

__all__ = [
    "BusAddress",
    "UDP_GROUP",
    "UDP_PORT",
    "import_vendor",
    "kernel_has_can",
    "NO_KERNEL_CAN",
]

#: python-can's default IPv4 group for its ``udp_multicast`` interface (an
#: administratively scoped address: it stays on this host's network).
UDP_GROUP = "239.74.163.2"

#: python-can's default port for ``udp_multicast``.
UDP_PORT = 43113

#: Why socketcan tests skip on machines like the ones servoid is built on.
NO_KERNEL_CAN = "no CAN support in this kernel"

_PACKAGES = {"can": "python-can", "canopen": "canopen", "msgpack": "msgpack"}


def import_vendor(name: str) -> ModuleType:
    """Import python-can or canopen now; a missing one raises :class:`MissingDependency` naming it."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        missing = (exc.name or name).split(".")[0]
        package = _PACKAGES.get(missing, missing)
        raise MissingDependency(f"the can:// driver needs the package {package!r}: pip install {package}") from exc


def kernel_has_can() -> bool:
    """Whether this kernel offers PF_CAN sockets (socketcan, vcan)."""
    family = getattr(socket, "PF_CAN", None)
    if family is None:
        return False
    try:
        socket.socket(family, socket.SOCK_RAW, socket.CAN_RAW).close()
    except OSError:
        return False
    return True


@dataclass(frozen=True)
class BusAddress:
    """Which CAN bus to open: a python-can interface and channel.

    Parameters
    ----------
    interface : str
        python-can interface name (``virtual``, ``socketcan``, ``udp_multicast``,
        ``pcan``, ``kvaser``, ...).
    channel : str
        The interface's channel: ``can0`` for socketcan, any name for
        ``virtual`` (buses of one process with the same name see each other),
        a multicast group for ``udp_multicast`` (default :data:`UDP_GROUP`).
    bitrate : int, optional
        Bit rate in bit/s, for interfaces that set it (ignored by ``virtual``
        and ``udp_multicast``; socketcan takes it from ``ip link``).
    port : int, optional
        UDP port of ``udp_multicast`` (default :data:`UDP_PORT`); processes
        talk to each other only on the same group and port.
    bind : str, optional
        ``udp_multicast``: IPv4 address of the interface the bus uses (default
        127.0.0.1: this host only; ``0.0.0.0`` for every interface, to reach
        drives on other hosts). See :mod:`servoid.drivers.can._udp`.
    """

    interface: str
    channel: str = ""
    bitrate: int | None = None
    port: int | None = None
    bind: str | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.interface, str) or not self.interface:
            raise ConfigError(
                f"CAN interface (={self.interface!r}) must be a python-can interface name such as "
                "'virtual', 'socketcan' or 'udp_multicast': can://<interface>/<channel>?..."
            )
        channel = self.channel or (UDP_GROUP if self.interface == "udp_multicast" else "")
        if not channel:
            raise ConfigError(
                f"CAN channel is missing for interface {self.interface!r}: "
                f"can://{self.interface}/<channel>?... (e.g. can0 for socketcan, any name for virtual)"
            )
        object.__setattr__(self, "channel", channel)
        if self.bitrate is not None:
            object.__setattr__(self, "bitrate", validation.integer("bitrate", self.bitrate, minimum=1))
        if self.port is not None:
            port = validation.integer("port", self.port, minimum=1)
            if port > 65535:
                raise ConfigError(f"port (={port}) must be <= 65535")
            if self.interface != "udp_multicast":
                raise ConfigError(f"port (={port}) applies to the udp_multicast interface only, not {self.interface!r}")
            object.__setattr__(self, "port", port)
        if self.bind is not None:
            if self.interface != "udp_multicast":
                raise ConfigError(
                    f"bind (={self.bind}) applies to the udp_multicast interface only, not {self.interface!r}"
                )
            object.__setattr__(self, "bind", check_bind(self.bind))

    def url(self, protocol: str, node: int, **options: Any) -> str:
        """The ``can://`` URL a driver uses to reach a node on this bus."""
        query: dict[str, Any] = {"protocol": protocol, "node": node}
        if self.bitrate is not None:
            query["bitrate"] = self.bitrate
        if self.interface == "udp_multicast":
            query["port"] = self.port if self.port is not None else UDP_PORT
            if self.bind is not None:
                query["bind"] = self.bind
        query.update(options)
        return f"can://{self.interface}/{self.channel}?{urlencode(query)}"

    def describe(self) -> str:
        if self.interface == "udp_multicast":
            where = f"{self.channel}:{self.port or UDP_PORT} on {self.bind or LOOPBACK}"
        else:
            where = self.channel
        return f"{self.interface} {where}"

    def open(self, *, can_filters: Sequence[Mapping[str, Any]] | None = None) -> Any:
        """Open the bus (a ``can.BusABC``).

        Raises
        ------
        MissingDependency
            python-can (or msgpack, for ``udp_multicast``) is not installed.
        ConfigError
            Unknown interface (the message lists python-can's).
        DriverError
            The interface exists but the bus cannot be opened; for socketcan
            on a kernel without CAN the message says so.
        """
        can = import_vendor("can")
        valid = sorted(can.interfaces.VALID_INTERFACES)
        if self.interface not in valid:
            raise ConfigError(f"unknown CAN interface {self.interface!r}; python-can offers {', '.join(valid)}")
        kwargs: dict[str, Any] = {"interface": self.interface, "channel": self.channel}
        if self.bitrate is not None:
            kwargs["bitrate"] = self.bitrate
        if self.port is not None:
            kwargs["port"] = self.port
        if can_filters is not None:
            kwargs["can_filters"] = list(can_filters)
        try:
            if self.interface == "udp_multicast":
                import_vendor("msgpack")
                return open_udp_bus(can, self.channel, self.port or UDP_PORT, bind=self.bind, can_filters=can_filters)
            return can.Bus(**kwargs)
        except (OSError, can.CanError) as exc:
            hint = f" ({NO_KERNEL_CAN})" if self.interface == "socketcan" and not kernel_has_can() else ""
            raise DriverError(f"cannot open CAN bus {self.describe()}{hint}: {exc}") from exc
