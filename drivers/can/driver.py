"""``can://`` URLs: one driver class per protocol, chosen by ``protocol=``.

URL form::

    can://<interface>/<channel>?protocol=cia402|odrive&node=N[&mode=position|torque][&bitrate=B][&port=P][&timeout=S]

``interface`` and ``channel`` are python-can's (``virtual/ch0``,
``socketcan/can0``, ``udp_multicast/239.74.163.2``, ``pcan/PCAN_USBBUS1``,
...). :class:`CanDriver` holds what both protocols share (the bus, the node,
the mode, the reply timeout); :class:`~servoid.drivers.can.cia402.Cia402Driver`
and :class:`~servoid.drivers.can.odrive.OdriveDriver` speak the protocols.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import replace
from typing import ClassVar
from urllib.parse import unquote

from servoid import readings_side, validation
from servoid.drivers.base import Driver, DriverURL, Limits, Option, UnitConversion
from servoid.drivers.can._bus import BusAddress
from servoid.errors import ConfigError

__all__ = ["CanDriver", "PROTOCOLS", "DEFAULT_NODES", "DEFAULT_TIMEOUT_S"]

#: protocol= value -> "module:Class" of the driver that speaks it (imported on use).
PROTOCOLS: dict[str, str] = {
    "cia402": "servoid.drivers.can.cia402:Cia402Driver",
    "odrive": "servoid.drivers.can.odrive:OdriveDriver",
}

#: Node id a drive of each protocol has unless told otherwise (drivers and simulated drives).
DEFAULT_NODES = {"cia402": 1, "odrive": 0}

#: Longest wait for the reply to one cyclic exchange, s. Generous against the
#: scheduling tails of a loaded host; a real bus answers in well under 1 ms.
DEFAULT_TIMEOUT_S = 0.1

MODE_NAMES = ("position", "torque")


def _mode(text: str) -> str:
    if text not in MODE_NAMES:
        raise ValueError(f"expected one of {', '.join(MODE_NAMES)}")
    return text


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise ValueError("must be > 0")
    return value


class CanDriver(Driver):
    """A servo drive on a CAN bus, reached through python-can.

    ``CanDriver.from_url`` returns the driver of the URL's ``protocol``; the
    subclasses implement the protocols.

    Parameters
    ----------
    interface : str
        python-can interface (``virtual``, ``socketcan``, ``udp_multicast``, ...).
    channel : str
        The interface's channel (``can0``, a virtual bus name, a multicast group).
    node : int
        The drive's node id on the bus.
    mode : {"position", "torque"}
        What the command is: a target position (rad) or a torque (Nm).
    bitrate : int, optional
        Bit rate in bit/s, for interfaces that set it.
    port : int, optional
        UDP port, for ``udp_multicast``.
    bind : str, optional
        Interface address, for ``udp_multicast`` (default: loopback only).
    timeout : float
        Longest wait for a reply, s (:data:`DEFAULT_TIMEOUT_S`).
    readings : {"output", "motor"}
        Which shaft the position read is of (:attr:`~servoid.drivers.base.Driver.readings_side`);
        each protocol gives its default (a drive does not say which over the bus).
    limits : Limits, optional
        Safety limits on the command (rad, or Nm in torque mode).
    """

    scheme = "can"
    protocol: ClassVar[str] = ""
    options: ClassVar[Mapping[str, Option]] = {
        "protocol": Option(str, "cia402 (CANopen CiA 402 drive) or odrive (ODrive CAN Simple)"),
        "node": Option(int, "node id of the drive on the bus"),
        "mode": Option(_mode, "position (command in rad, default) or torque (command in Nm)"),
        "bitrate": Option(int, "bit rate in bit/s, for interfaces that set it"),
        "port": Option(int, "UDP port of the udp_multicast interface (default 43113)"),
        "bind": Option(str, "udp_multicast: IPv4 address of the interface to use (default 127.0.0.1, this host only)"),
        "timeout": Option(_positive_float, f"longest wait for a reply, s (default {DEFAULT_TIMEOUT_S})"),
        readings_side.METADATA_KEY: Option(
            str,
            "which shaft the position read is of: output (CiA 402 default) or motor (ODrive default: the axis's "
            "own encoder; a CiA 402 drive whose 0x6064 is the motor encoder, no load encoder)",
        ),
    }

    def __init__(
        self,
        *,
        interface: str,
        channel: str = "",
        node: int,
        mode: str = "position",
        bitrate: int | None = None,
        port: int | None = None,
        bind: str | None = None,
        timeout: float = DEFAULT_TIMEOUT_S,
        readings: str = readings_side.OUTPUT,
        limits: Limits | None = None,
        position_unit: UnitConversion | None = None,
        command_unit: UnitConversion | None = None,
    ) -> None:
        super().__init__(limits=limits, position_unit=position_unit, command_unit=command_unit)
        self.address = BusAddress(interface, channel, bitrate, port, bind)
        self.node = validation.integer("node", node, minimum=0)
        if mode not in MODE_NAMES:
            raise ConfigError(f"mode (={mode!r}) must be one of {', '.join(MODE_NAMES)}")
        self.mode = mode
        self.timeout = validation.positive("timeout", timeout)
        self.readings_side = readings_side.check("readings", readings)

    @classmethod
    def from_url(cls, url: DriverURL) -> Driver:
        """The driver of the URL's ``protocol=`` (see the module docstring)."""
        options = dict(url.options)
        protocol = options.pop("protocol", None)
        impl = cls if cls.protocol else protocol_class(protocol, url.raw)
        if cls.protocol and protocol not in (None, cls.protocol):
            raise ConfigError(f"{url.raw}: protocol={protocol} does not match {cls.__name__} ({cls.protocol})")
        kwargs = impl.parse_options(replace(url, options=options))
        driver = impl(interface=url.host, channel=unquote(url.path.lstrip("/")), **kwargs)
        driver.url = url.raw
        return driver

    def describe(self) -> str:
        return self.url or f"{self.protocol} node {self.node} on {self.address.describe()}"

    def _who(self) -> str:
        """The drive in messages: ``"node 1 on virtual ch0"``."""
        return f"node {self.node} on {self.address.describe()}"


def protocol_class(protocol: str | None, url: str = "") -> type[CanDriver]:
    """The driver class for ``protocol=`` (imported now).

    Raises
    ------
    ConfigError
        No or an unknown protocol (the message lists the known ones).
    """
    where = f"{url}: " if url else ""
    known = ", ".join(PROTOCOLS)
    if protocol is None:
        raise ConfigError(
            f"{where}say which protocol the drive speaks: add protocol=<{'|'.join(PROTOCOLS)}> to the URL"
        )
    if protocol not in PROTOCOLS:
        raise ConfigError(f"{where}unknown CAN protocol {protocol!r}; known: {known}")
    module_name, _, class_name = PROTOCOLS[protocol].partition(":")
    cls: type[CanDriver] = getattr(importlib.import_module(module_name), class_name)
    return cls


def parse_bool(text: str) -> bool:
    """URL flag: 1/0, yes/no, true/false, on/off."""
    lowered = text.strip().lower()
    if lowered in ("1", "yes", "true", "on"):
        return True
    if lowered in ("0", "no", "false", "off"):
        return False
    raise ValueError("expected 1 or 0 (yes/no)")
