"""What both simulated CAN drives share: node, bus, plant, life cycle, URL, and injected faults."""

from __future__ import annotations

import abc
import time
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from servoid import validation
from servoid.drivers.can._bus import BusAddress
from servoid.drivers.can._sim_axis import SimAxis
from servoid.drivers.servos import Servo

__all__ = ["SimDrive"]


class SimDrive(abc.ABC):
    """Base of the simulated drives; a context manager that starts and stops it.

    Parameters
    ----------
    node : int
        Node id (validated by the subclass).
    bus : BusAddress, optional
        Where to listen; default python-can's ``virtual`` channel ``"ch0"``.
    servo : Servo
        The servo behind the drive (:mod:`servoid.drivers.servos`).
    torque_gain : float
        rad per Nm of the plant in torque mode.
    period_s : float, optional
        The drive's own sample period (see :class:`~servoid.drivers.can._sim_axis.SimAxis`).
    mute_after : int, optional
        Fault: after this many cyclic replies the drive stops transmitting
        (it still receives and obeys: a broken transmitter, or a cut CAN_H
        seen from the host).
    drop : float
        Fault: probability that a cyclic reply is lost.
    restart_after : int, optional
        Fault: the drive restarts at the cyclic request after this many
        (where the protocol has a restart the host can see).
    seed : int
        Seed of the dropped replies.

    Attributes
    ----------
    on_event : callable or None
        Called with one line (``"node 1: power stage off ..."``) when the
        drive switches its power stage off or its watchdog fires, from the
        drive's thread.
    """

    protocol: ClassVar[str] = ""

    def __init__(
        self,
        *,
        node: int,
        bus: BusAddress | None,
        servo: Servo,
        torque_gain: float,
        period_s: float | None = None,
        mute_after: int | None = None,
        drop: float = 0.0,
        restart_after: int | None = None,
        seed: int = 0,
    ) -> None:
        self.node = node
        self.bus = bus if bus is not None else BusAddress("virtual", "ch0")
        self.axis = SimAxis(servo, torque_gain=torque_gain, period_s=period_s)
        self.mute_after = None if mute_after is None else validation.integer("mute_after", mute_after, minimum=0)
        self.drop = validation.in_unit_interval("drop", drop, open_low=False, open_high=False)
        self.restart_after = (
            None if restart_after is None else validation.integer("restart_after", restart_after, minimum=0)
        )
        self._rng = np.random.default_rng(seed)
        #: Cyclic requests served (SYNCs in Operation Enabled, inputs in closed-loop control).
        self.requests = 0
        #: Cyclic replies sent or lost.
        self.replies = 0
        self._muted = False
        self._reply_delay = 0.0
        self.on_event: Callable[[str], None] | None = None

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

    def _event(self, what: str) -> None:
        if self.on_event is not None:
            self.on_event(f"node {self.node}: {what}")

    def mute(self, muted: bool = True) -> None:
        """Stop (or resume) transmitting; the drive still receives and obeys (a broken transmitter)."""
        self._muted = muted

    def delay_next_reply(self, seconds: float) -> None:
        """Answer the next cyclic exchange ``seconds`` late (a drive stalled once)."""
        self._reply_delay = seconds

    def _restart_due(self) -> bool:
        """Count one cyclic request; whether the injected restart happens at it."""
        self.requests += 1
        return self.restart_after is not None and self.requests == self.restart_after + 1

    def _reply_lost(self) -> bool:
        """Called before each cyclic reply: stall once if asked to; whether the reply is lost."""
        if self._reply_delay:
            delay, self._reply_delay = self._reply_delay, 0.0
            time.sleep(delay)
        self.replies += 1
        if self.mute_after is not None and self.replies > self.mute_after:
            self._muted = True
        return self._muted or (self.drop > 0 and self._rng.random() < self.drop)

    def url(self, **options: Any) -> str:
        """The ``can://`` URL that reaches this drive (extra driver options as keywords)."""
        return self.bus.url(self.protocol, self.node, **options)

    def __enter__(self) -> SimDrive:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
