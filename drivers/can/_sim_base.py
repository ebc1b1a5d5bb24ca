"""What both simulated CAN drives share: node, bus, plant, life cycle, URL and a mutable transmitter."""

from __future__ import annotations

import abc
import time
from typing import Any, ClassVar

from servoid.drivers.can._bus import BusAddress
from servoid.drivers.can._sim_axis import SimAxis
from servoid.ident.model import BacklashModel

__all__ = ["SimDrive"]


class SimDrive(abc.ABC):
    """Base of the simulated drives; a context manager that starts and stops it.

    Parameters
    ----------
    node : int
        Node id (validated by the subclass).
    bus : BusAddress, optional
        Where to listen; default python-can's ``virtual`` channel ``"ch0"``.
    model : BacklashModel
        The plant (rad in, rad out).
    torque_gain : float
        rad per Nm of the plant in torque mode.
    """

    protocol: ClassVar[str] = ""

    def __init__(self, *, node: int, bus: BusAddress | None, model: BacklashModel, torque_gain: float) -> None:
        self.node = node
        self.bus = bus if bus is not None else BusAddress("virtual", "ch0")
        self.axis = SimAxis(model, torque_gain=torque_gain)
        self._muted = False
        self._reply_delay = 0.0

    @abc.abstractmethod
    def start(self) -> SimDrive:
        """Connect to the bus and start answering."""

    @abc.abstractmethod
    def stop(self) -> None:
        """Leave the bus; idempotent."""

    @property
    @abc.abstractmethod
    def power_on(self) -> bool:
        """Whether the power stage is on."""

    @abc.abstractmethod
    def status(self) -> str:
        """One line for a terminal."""

    def mute(self, muted: bool = True) -> None:
        """Stop (or resume) transmitting; the drive still receives and obeys (a broken transmitter)."""
        self._muted = muted

    def delay_next_reply(self, seconds: float) -> None:
        """Answer the next cyclic exchange ``seconds`` late (a drive stalled once)."""
        self._reply_delay = seconds

    def _stall(self) -> None:
        """Called before each cyclic reply: sleep once if a delay was asked for."""
        if self._reply_delay:
            delay, self._reply_delay = self._reply_delay, 0.0
            time.sleep(delay)

    def url(self, **options: Any) -> str:
        """The ``can://`` URL that reaches this drive (extra driver options as keywords)."""
        return self.bus.url(self.protocol, self.node, **options)

    def __enter__(self) -> SimDrive:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
