"""Pick a simulated CAN drive by protocol name (for ``servoid emulate can``, tests and benchmarks)."""

from __future__ import annotations

from typing import Any

from servoid.drivers.can._bus import BusAddress
from servoid.drivers.can._sim_base import SimDrive
from servoid.drivers.can.driver import DEFAULT_NODES, PROTOCOLS
from servoid.drivers.can.sim_cia402 import SimCia402Drive
from servoid.drivers.can.sim_odrive import SimOdriveAxis
from servoid.errors import ConfigError

__all__ = ["simulated_drive", "SimDrive", "DEFAULT_NODES"]


def simulated_drive(protocol: str, *, bus: BusAddress, node: int | None = None, **options: Any) -> SimDrive:
    """A simulated drive of ``protocol`` on ``bus`` (not started: use it as a context manager).

    Parameters
    ----------
    protocol : {"cia402", "odrive"}
        Which drive.
    bus : BusAddress
        Where it listens.
    node : int, optional
        Its node id (default :data:`DEFAULT_NODES`).
    **options
        Passed to the simulator (``model``, ``counts_per_rev``, ``torque_gain``, ...).
    """
    if protocol not in PROTOCOLS:
        raise ConfigError(f"unknown CAN protocol {protocol!r}; known: {', '.join(PROTOCOLS)}")
    node = DEFAULT_NODES[protocol] if node is None else node
    if protocol == "cia402":
        return SimCia402Drive(node=node, bus=bus, **options)
    return SimOdriveAxis(node=node, bus=bus, **options)
