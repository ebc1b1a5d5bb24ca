"""What a simulated servo offers beyond a driver: its clock, its true parameters, its reference input.

The app asks for these with ``isinstance(driver, SimulatedServo)`` rather than
reaching for attributes a real driver does not have. :class:`~servoid.drivers.sim.SimDriver`
satisfies it; so must any other simulated servo (a physical twin behind the
driver interface).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from servoid.drivers.clock import Clock
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["SimulatedServo"]


@runtime_checkable
class SimulatedServo(Protocol):
    """A driver whose servo is simulated (checked at run time by member names)."""

    #: The time source of the simulation; the sampling session shares it (a virtual clock: runs repeat exactly).
    clock: Clock

    #: Standard deviation of the measurement noise, position unit.
    noise_std: float

    @property
    def truth(self) -> BacklashModel:
        """The simulated plant's true parameters (as new)."""
        ...

    def truth_at(self, sample: int) -> BacklashModel:
        """The true parameters at the plant's sample ``sample`` (wear included)."""
        ...

    @property
    def reference_amplitude(self) -> float:
        """Half-width of the uniform input the plant is meant to be excited with, command unit."""
        ...
