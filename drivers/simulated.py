"""What a simulated servo offers beyond a driver: its clock, its ground truth, its reference input.

The app asks for these with ``isinstance(driver, SimulatedServo)`` rather than
reaching for attributes a real driver does not have. :class:`~servoid.drivers.sim.SimDriver`
satisfies it; so must any other simulated servo.

Ground truth comes in two kinds, one of them None: a pseudo-Wiener plant
(``sim://model``, ``paper``, ``gear``) *is* a :class:`BacklashModel`, whose
parameters an identification can be scored against (:attr:`SimulatedServo.truth`);
a physical twin (``sim://xm430``, ...) is not any such model, and what is
true of it is physical: its play, its gear ratio, which encoder the drive's
loop closes on and which one the host reads, its loop structure
(:attr:`SimulatedServo.twin_truth`, a :class:`~servoid.drivers.twin.TwinTruth`).
Both have an ``_at(sample)`` form that includes the wear.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from servoid.drivers.clock import Clock
from servoid.drivers.twin.servo import TwinTruth
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
    def truth(self) -> BacklashModel | None:
        """The pseudo-Wiener model the servo is (as new); None for a physical twin."""
        ...

    def truth_at(self, sample: int) -> BacklashModel | None:
        """The pseudo-Wiener model at the servo's sample ``sample`` (wear included); None for a twin."""
        ...

    @property
    def twin_truth(self) -> TwinTruth | None:
        """A physical twin's ground truth as new (play, ratio, encoders, loop structure); None for a model plant."""
        ...

    def twin_truth_at(self, sample: int) -> TwinTruth | None:
        """A twin's ground truth at the servo's sample ``sample``: its play as worn by then; None for a model plant."""
        ...

    @property
    def reference_amplitude(self) -> float:
        """Half-width of the uniform input the servo is meant to be excited with, command unit."""
        ...
